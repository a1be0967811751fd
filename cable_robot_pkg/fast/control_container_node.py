"""fast_control_container: the FAST control nodes composed in one process on one executor.

The optical tracker, the feed trajectory, the cable controller and the isolation controller
exchange about 2,000 messages per simulated second among themselves; as four processes each
message crosses DDS between processes and each process runs an executor of its own. This
container runs them in one process (:class:`paramotion.container.ComponentContainer`), as a
ROS 2 user would load them into a component container: each keeps its node name
(``fast_tracker``, ``fast_trajectory``, ``fast_cable_controller``,
``fast_isolation_controller``), its parameters (given to the container as
``<node>.<parameter>``) and the process's remappings. ``launch/fast.launch.xml`` starts it
instead of the four processes with ``composed:=true``.
"""
from cable_robot_pkg.fast.cable_pid_node import CablePidNode
from cable_robot_pkg.fast.feed_trajectory_node import FeedTrajectoryNode
from cable_robot_pkg.fast.isolation_node import IsolationNode
from cable_robot_pkg.fast.optical_tracker_node import OpticalTrackerNode
from paramotion.container import ComponentContainer, component_params
from paramotion.node import run_node

COMPONENTS = {
    'fast_tracker': OpticalTrackerNode,
    'fast_trajectory': FeedTrajectoryNode,
    'fast_cable_controller': CablePidNode,
    'fast_isolation_controller': IsolationNode,
}


class FastControlContainer(ComponentContainer):
    """The four FAST control nodes in one process."""

    COMPONENTS = COMPONENTS
    PARAMS = component_params(COMPONENTS)

    def __init__(self, node_name='fast_control_container', **kwargs):
        super().__init__(node_name, **kwargs)


def main(args=None):
    run_node(FastControlContainer, args)


if __name__ == '__main__':
    main()
