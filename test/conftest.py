"""Test isolation: every test run gets its own DDS domain and localhost-only discovery.

Set before any rclpy Context is created, so two test runs on one machine (or a test run beside
a scenario) never hear each other. Each test creates its own Context/Graph and shuts it down.
"""
import os
import random
import sys
from pathlib import Path

_REPO = Path(__file__).resolve().parents[1]
if str(_REPO) not in sys.path:
    sys.path.insert(0, str(_REPO))

# Domain ids 1..100 leave room for Fast DDS port arithmetic; pick one per run at random
# (seeded by pid and time so parallel runs differ).
_rng = random.Random(os.getpid() ^ int.from_bytes(os.urandom(4), 'little'))
os.environ['ROS_DOMAIN_ID'] = str(_rng.randint(1, 100))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)
os.environ.setdefault('MPLBACKEND', 'Agg')

REPO = _REPO
BAGS = _REPO / 'bags'
