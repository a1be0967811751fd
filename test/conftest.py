"""Test isolation: every test run gets its own DDS domain and localhost-only discovery.

Set before any rclpy Context is created, so two test runs on one machine (or a test run beside
a scenario) never hear each other. Each test creates its own Context/Graph and shuts it down.
"""
import os
import random
import signal
import sys
from pathlib import Path

_REPO = Path(__file__).resolve().parents[1]
if str(_REPO) not in sys.path:
    sys.path.insert(0, str(_REPO))



def _domain_id():
    """Domain ids 1..100 leave room for Fast DDS port arithmetic: one per run, at random
    (seeded by pid and urandom so parallel runs differ). Under pytest-xdist (``-n N``) the
    workers of one run share a random base (``PYTEST_XDIST_TESTRUNUID``) and add their index,
    so no two workers of a run share a domain."""
    run_uid = os.environ.get('PYTEST_XDIST_TESTRUNUID')
    worker = os.environ.get('PYTEST_XDIST_WORKER', '')
    if run_uid and worker.startswith('gw') and worker[2:].isdigit():
        base = random.Random(run_uid).randrange(100)
        return (base + int(worker[2:])) % 100 + 1
    rng = random.Random(os.getpid() ^ int.from_bytes(os.urandom(4), 'little'))
    return rng.randint(1, 100)


os.environ['ROS_DOMAIN_ID'] = str(_domain_id())
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)
os.environ.setdefault('MPLBACKEND', 'Agg')

# A terminal's Ctrl-C reaches processes whose SIGINT is at its default. Started in the
# background by a non-interactive shell (as a CI runner may start it), this process has SIGINT
# ignored, every node it starts would inherit that and rightly keep ignoring it
# (paramotion/shutdown.py), and the tests that press Ctrl-C would test nothing. Installing
# Python's handler here gives the started processes a default SIGINT again, as a terminal does.
signal.signal(signal.SIGINT, signal.default_int_handler)

REPO = _REPO
BAGS = _REPO / 'bags'
