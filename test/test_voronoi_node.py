"""voronoi_planner node: GetPlan served and called in one process (lead's Graph runner)."""
import math

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from nav_msgs.srv import GetPlan
from test_voronoi_planner import independent_check
from visualization_msgs.msg import MarkerArray

from paramotion.errors import ParameterError
from paramotion.graph import Graph
from paramotion.qos import LATCHED_QOS
from voronoi_pkg.planar import PAPER_GOAL, PAPER_START
from voronoi_pkg.planner_node import VoronoiPlannerNode


def _pose(x, y, yaw, frame='map'):
    p = PoseStamped()
    p.header.frame_id = frame
    p.pose.position.x, p.pose.position.y = float(x), float(y)
    p.pose.orientation.z, p.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return p


class _Client:
    """A plain rclpy node in the same graph: service client and latched subscribers."""

    def __init__(self, graph):
        self.graph = graph
        self.node = rclpy.create_node('voronoi_test_client', context=graph.context)
        graph.nodes.append(self.node)
        graph.executor.add_node(self.node)
        self.client = self.node.create_client(GetPlan, '/voronoi/get_plan')
        self.paths, self.markers, self.status = [], [], []
        from diagnostic_msgs.msg import DiagnosticArray
        self.node.create_subscription(Path, '/voronoi/path', self.paths.append, LATCHED_QOS)
        self.node.create_subscription(MarkerArray, '/voronoi/diagram', self.markers.append,
                                      LATCHED_QOS)
        self.node.create_subscription(DiagnosticArray, '/voronoi/status', self.status.append,
                                      LATCHED_QOS)

    def call(self, start, goal):
        assert self.graph.spin_wall(5.0, until=lambda: self.client.service_is_ready())
        req = GetPlan.Request(start=start, goal=goal, tolerance=0.0)
        future = self.client.call_async(req)
        assert self.graph.spin_wall(60.0, until=future.done)
        return future.result()

    def last_status(self):
        self.graph.spin_wall(2.0, until=lambda: bool(self.status))
        return self.status[-1].status[0]


@pytest.fixture
def graph():
    with Graph() as g:
        yield g


@pytest.mark.slow            # the paper query through the node (the planner test solves it too)
def test_get_plan_returns_a_verified_path_and_latches_outputs(graph):
    node = graph.add(VoronoiPlannerNode, grid_spacing=1.0, slice_step_deg=2.5)
    client = _Client(graph)
    resp = client.call(_pose(*PAPER_START), _pose(*PAPER_GOAL))
    poses = resp.plan.poses
    assert len(poses) > 100 and resp.plan.header.frame_id == 'map'
    q = np.array([[p.pose.position.x, p.pose.position.y,
                   2 * math.atan2(p.pose.orientation.z, p.pose.orientation.w)]
                  for p in poses])
    q[:, 2] = np.unwrap(q[:, 2])
    np.testing.assert_allclose(q[0], PAPER_START, atol=1e-9)
    np.testing.assert_allclose(q[-1, :2], PAPER_GOAL[:2], atol=1e-9)
    assert independent_check(q) is None
    # Latched outputs reach the subscriber: path, markers with scene, diagram and path.
    graph.spin_wall(5.0, until=lambda: bool(client.paths and client.markers
                                            and len(client.markers[-1].markers) == 4))
    assert client.paths, 'no path message'
    assert client.markers, 'no markers'
    assert len(client.paths[-1].poses) == len(poses)
    namespaces = {m.ns: m for m in client.markers[-1].markers}
    assert set(namespaces) == {'scene', 'diagram', 'path', 'diagram_used'}
    assert len(namespaces['diagram'].points) > 20
    # The used diagram edges are the path's own pieces: every end point lies on the path.
    used = np.array([[p.x, p.y] for p in namespaces['diagram_used'].points])
    assert len(used) >= 2 and len(used) % 2 == 0
    gap = np.min(np.hypot(used[:, None, 0] - q[None, :, 0], used[:, None, 1] - q[None, :, 1]),
                 axis=1)
    assert gap.max() < 1e-6
    status = client.last_status()
    assert status.message == 'path found'
    assert node.requests == 1


def test_no_path_and_bad_requests_return_an_empty_plan_with_a_reason(graph):
    graph.add(VoronoiPlannerNode, grid_spacing=2.0, slice_step_deg=5.0)
    client = _Client(graph)
    resp = client.call(_pose(*PAPER_START), _pose(-10.0, 15.0, 0.0))   # across y = 0
    assert len(resp.plan.poses) == 0
    status = client.last_status()
    assert status.message.startswith('no path') and '[p1 p2 p3]' in status.message
    client.status.clear()
    resp = client.call(_pose(52.0, 0.5, 0.0), _pose(*PAPER_GOAL))        # through the wall
    assert len(resp.plan.poses) == 0
    status = client.last_status()
    assert 'refused' in status.message and 'boundary edge P7P8' in status.message
    client.status.clear()
    resp = client.call(_pose(*PAPER_START, frame='odom'), _pose(*PAPER_GOAL))
    assert len(resp.plan.poses) == 0
    assert "frame 'odom'" in client.last_status().message
    client.status.clear()
    zero = _pose(*PAPER_GOAL)
    zero.pose.orientation.z = zero.pose.orientation.w = 0.0
    resp = client.call(_pose(*PAPER_START), zero)
    assert len(resp.plan.poses) == 0
    assert 'goal: orientation' in client.last_status().message


def test_bad_parameters_are_refused():
    with Graph() as graph:
        with pytest.raises(ParameterError, match='grid_spacing'):
            graph.add(VoronoiPlannerNode, grid_spacing=-1.0)
    with Graph() as graph:
        with pytest.raises(ParameterError, match='scene_file'):
            graph.add(VoronoiPlannerNode, scene_file='/nonexistent/scene.json')
    with Graph() as graph:
        with pytest.raises(ParameterError, match="parameter 'without'.*'walls'"):
            graph.add(VoronoiPlannerNode, without='walls')
    with Graph() as graph:
        node = graph.add(VoronoiPlannerNode, grid_spacing=3.0, slice_step_deg=15.0,
                         without='collision')
        assert 'collision' not in node.model.programs
    with Graph() as graph:
        with pytest.raises(ParameterError, match='exceeds'):
            graph.add(VoronoiPlannerNode, grid_spacing=0.1, slice_step_deg=0.5)
    with Graph() as graph:
        node = graph.add(VoronoiPlannerNode, grid_spacing=3.0, slice_step_deg=10.0)
        result = node.set_parameters([rclpy.parameter.Parameter('slice_step_deg',
                                                                value=90.0)])
        assert not result[0].successful and 'slice_step_deg' in result[0].reason
        # In range on its own, but 901 x 901 x 38 vertices: refused as a whole.
        result = node.set_parameters([rclpy.parameter.Parameter('grid_spacing', value=0.1)])
        assert not result[0].successful and 'exceeds' in result[0].reason
        assert node.params.grid_spacing == 3.0
