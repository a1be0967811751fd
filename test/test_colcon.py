"""``colcon build --symlink-install`` of the repository as a user with ROS 2 would do it;
executables start, refuse bad parameters and stop cleanly."""
import os
import signal
import subprocess
import sys
import time

import pytest
import rclpy
from launch_helpers import colcon_workspace, in_workspace

from paramotion.launch import wait_until
from paramotion.start import NODES

pytestmark = pytest.mark.slow


@pytest.fixture(scope='module')
def workspace(tmp_path_factory):
    return colcon_workspace(tmp_path_factory)


def _run_in_ws(ws, command, **kwargs):
    return subprocess.Popen(in_workspace(ws, command), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True, **kwargs)


def test_executables_installed_where_ros2_run_looks(workspace):
    lib = workspace / 'install' / 'paramotion' / 'lib' / 'paramotion'
    names = list(NODES)
    assert 'smoke_sim' in names and 'bag_recorder' in names
    for name in names:
        assert (lib / name).is_file() and os.access(lib / name, os.X_OK), name
    share = workspace / 'install' / 'paramotion' / 'share'
    assert (share / 'paramotion' / 'package.xml').is_file()
    assert (share / 'ament_index' / 'resource_index' / 'packages' / 'paramotion').is_file()
    # With the workspace sourced, the package is the workspace's (symlinked to its sources).
    proc = _run_in_ws(workspace, f"{sys.executable} -c "
                      "'import paramotion; print(paramotion.__file__)'")
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and out.strip().startswith(str(workspace)), (out, err)


def test_built_node_validates_parameters(workspace):
    lib = workspace / 'install' / 'paramotion' / 'lib' / 'paramotion'
    proc = _run_in_ws(workspace, f'{lib}/smoke_sim --ros-args -p publish_period:=-1.0')
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and "'publish_period'" in err


def test_built_node_starts_and_stops_on_sigint(workspace):
    lib = workspace / 'install' / 'paramotion' / 'lib' / 'paramotion'
    proc = _run_in_ws(workspace, f'{lib}/smoke_controller')
    try:
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
        assert up and proc.poll() is None, (up, proc.poll())
        time.sleep(0.5)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=30)
        assert proc.returncode == 0 and 'Traceback' not in err, err
    finally:
        if proc.poll() is None:  # a failed check must not leave the node running
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)
