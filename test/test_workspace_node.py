"""workspace_monitor node: a commanded pose in, cable lengths and a diagnosis out."""
import math

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import JointState
from visualization_msgs.msg import MarkerArray

from cable_robot_pkg.cdrpm.description import CONFIG_DIR, load_description
from cable_robot_pkg.cdrpm.kinematics import inverse_kinematics
from cable_robot_pkg.cdrpm.workspace_monitor_node import WorkspaceMonitorNode
from paramotion.errors import ParameterError
from paramotion.graph import Graph
from paramotion.qos import LATCHED_QOS, STATE_QOS


class Probe:
    """A plain node in the graph that publishes poses and collects the monitor's outputs."""

    def __init__(self, graph):
        self.node = rclpy.create_node('workspace_probe', context=graph.context)
        graph.executor.add_node(self.node)
        graph.nodes.append(self.node)
        self.pub = self.node.create_publisher(PoseStamped, '/cdrpm/pose_cmd', STATE_QOS)
        self.lengths, self.status, self.markers = [], [], []
        self.node.create_subscription(JointState, '/cdrpm/cable_lengths',
                                      self.lengths.append, STATE_QOS)
        self.node.create_subscription(DiagnosticArray, '/cdrpm/workspace_status',
                                      self.status.append, LATCHED_QOS)
        self.node.create_subscription(MarkerArray, '/cdrpm/cable_markers',
                                      self.markers.append, STATE_QOS)

    def send(self, graph, position, quat=(0.0, 0.0, 0.0, 1.0)):
        before = len(self.status)
        msg = PoseStamped()
        msg.header.frame_id = 'map'
        msg.header.stamp.sec = 7
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = position
        (msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z,
         msg.pose.orientation.w) = quat
        self.pub.publish(msg)
        assert graph.spin_wall(5.0, until=lambda: len(self.status) > before)
        graph.spin_wall(0.1)
        return self.status[-1].status[0]


@pytest.fixture
def graph():
    with Graph() as g:
        yield g


def _wait_matched(graph, probe):
    assert graph.spin_wall(5.0, until=lambda: probe.pub.get_subscription_count() > 0)


def test_pose_in_lengths_and_diagnosis_out(graph):
    graph.add(WorkspaceMonitorNode)
    probe = Probe(graph)
    _wait_matched(graph, probe)
    desc = load_description()

    status = probe.send(graph, (0.2, -0.3, 0.1))
    assert status.level == DiagnosticStatus.OK and status.message == 'collision-free'
    assert len(probe.lengths) == 1
    js = probe.lengths[-1]
    assert js.name == [f'cable_{i}' for i in range(1, 9)]
    expected = inverse_kinematics(desc, [[0.2, -0.3, 0.1]], np.eye(3)).lengths[0]
    np.testing.assert_allclose(js.position, expected, atol=1e-12)
    assert js.header.stamp.sec == 7
    assert probe.markers and len(probe.markers[-1].markers[0].points) == 16

    # Outside the frame: reported as such, no lengths published.
    status = probe.send(graph, (0.0, 2.5, 0.0))
    assert status.level == DiagnosticStatus.ERROR and 'outside frame' in status.message
    assert len(probe.lengths) == 1
    # Invalid input: zero quaternion and NaN position.
    status = probe.send(graph, (0.0, 0.0, 0.0), quat=(0.0, 0.0, 0.0, 0.0))
    assert status.level == DiagnosticStatus.ERROR and 'invalid pose' in status.message
    status = probe.send(graph, (math.nan, 0.0, 0.0))
    assert status.level == DiagnosticStatus.ERROR and 'invalid pose' in status.message
    assert len(probe.lengths) == 1


def test_collision_names_the_pair(graph):
    # The pinwheel's cables 1 and 2 cross right next to the +y end wall (docs/workspace.md).
    graph.add(WorkspaceMonitorNode,
              robot_description=str(CONFIG_DIR / 'kntu_pinwheel.yaml'))
    probe = Probe(graph)
    _wait_matched(graph, probe)
    status = probe.send(graph, (-0.875, 1.875, 0.875))
    assert status.level == DiagnosticStatus.ERROR
    assert 'cable-cable collision: cables 1 and 2' in status.message
    values = {kv.key: kv.value for kv in status.values}
    assert values['state'] == 'collision' and '1-2' in values['colliding_pairs']
    colours = probe.markers[-1].markers[0].colors
    assert colours[0].r > 0.8 and colours[0].g < 0.2        # cable 1 drawn red
    # 0.1 m further from the wall the cables clear each other by about 5 mm: a warning.
    status = probe.send(graph, (-0.875, 1.775, 0.875))
    assert status.level == DiagnosticStatus.WARN and 'mm apart' in status.message
    values = {kv.key: kv.value for kv in status.values}
    assert 0.0 < float(values['min_cable_gap_m']) < 0.02
    # Far from the walls: OK again.
    assert probe.send(graph, (-0.875, 1.5, 0.875)).level == DiagnosticStatus.OK


def test_without_cable_cable_lets_the_crossing_pass(graph):
    """With the cable-cable check switched off the crossing pose is no longer an error."""
    graph.add(WorkspaceMonitorNode, robot_description=str(CONFIG_DIR / 'kntu_pinwheel.yaml'),
              without='cable_cable')
    probe = Probe(graph)
    _wait_matched(graph, probe)
    status = probe.send(graph, (-0.875, 1.875, 0.875))
    assert status.level != DiagnosticStatus.ERROR
    assert {kv.key: kv.value for kv in status.values}['colliding_pairs'] == ''


def test_bad_description_parameter_is_refused(graph, tmp_path):
    with pytest.raises(ParameterError, match='robot_description'):
        graph.add(WorkspaceMonitorNode, robot_description=str(tmp_path / 'missing.yaml'))
    with pytest.raises(ParameterError, match='clearance_warning'):
        graph.add(WorkspaceMonitorNode, clearance_warning=-1.0)
    with pytest.raises(ParameterError, match="'without': without: unknown construct"):
        graph.add(WorkspaceMonitorNode, without='cable_cable,cables')
