"""``colcon build`` of the repository as a user with ROS 2 would do it; executables start."""
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import rclpy

from paramotion.launch import wait_until

REPO = Path(__file__).resolve().parents[1]


def _tracked_files():
    try:
        out = subprocess.run(['git', 'ls-files'], cwd=REPO, capture_output=True, text=True,
                             check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        out = []
    return [f for f in out if (REPO / f).is_file()]


@pytest.fixture(scope='module')
def workspace(tmp_path_factory):
    colcon = shutil.which('colcon', path=os.path.dirname(sys.executable)) or \
        shutil.which('colcon')
    assert colcon, 'colcon is in requirements.txt and must be installed'
    ws = tmp_path_factory.mktemp('ws')
    src = ws / 'src' / 'paramotion'
    files = _tracked_files()
    assert 'package.xml' in files
    for rel in files:
        dst = src / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / rel, dst)
    env = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep
               + os.environ.get('PATH', ''))
    proc = subprocess.run([colcon, 'build', '--event-handlers', 'console_direct-'], cwd=ws,
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return ws


def _run_in_ws(ws, command, **kwargs):
    script = f'. {ws}/install/setup.bash && cd {ws} && exec {command}'
    return subprocess.Popen(['bash', '-c', script], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True, **kwargs)


def test_executables_installed_where_ros2_run_looks(workspace):
    lib = workspace / 'install' / 'paramotion' / 'lib' / 'paramotion'
    setup_py = (REPO / 'setup.py').read_text()
    names = [line.split('=')[0].strip().strip("'") for line in setup_py.splitlines()
             if line.strip().startswith("'") and ' = ' in line and ':main' in line]
    assert 'smoke_sim' in names and 'bag_recorder' in names
    for name in names:
        assert (lib / name).is_file() and os.access(lib / name, os.X_OK), name
    share = workspace / 'install' / 'paramotion' / 'share'
    assert (share / 'paramotion' / 'package.xml').is_file()
    assert (share / 'ament_index' / 'resource_index' / 'packages' / 'paramotion').is_file()


def test_built_node_validates_parameters(workspace):
    lib = workspace / 'install' / 'paramotion' / 'lib' / 'paramotion'
    proc = _run_in_ws(workspace, f'{lib}/smoke_sim --ros-args -p publish_period:=-1.0')
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and "'publish_period'" in err


def test_built_node_starts_and_stops_on_sigint(workspace):
    lib = workspace / 'install' / 'paramotion' / 'lib' / 'paramotion'
    proc = _run_in_ws(workspace, f'{lib}/smoke_controller')
    # Interrupt only once the node is up (seen on the graph), not during its imports.
    context = rclpy.Context()
    rclpy.init(context=context)
    probe = rclpy.create_node('colcon_probe', context=context)
    try:
        up = wait_until(lambda: proc.poll() is not None
                        or 'smoke_controller' in probe.get_node_names(), timeout=60.0)
    finally:
        probe.destroy_node()
        rclpy.try_shutdown(context=context)
    assert up and proc.poll() is None, proc.communicate()[1]
    time.sleep(0.5)
    os.killpg(proc.pid, signal.SIGINT)
    proc.communicate(timeout=30)
    assert proc.returncode == 0
