"""coverage_monitor: evaluation only. What has the detector seen, and how much of CVS is that?

Reads the world file and the true pose (``/coverage/ground_truth``), accumulates the union of
the visible detector disks ``B^V_delta(p(t))`` along the true path
(:class:`coverage_pkg.cvs.CoverageAccumulator`) and every ``publish_period`` s of sim time
publishes

* ``/coverage/seen`` (nav_msgs/OccupancyGrid in ``map``, latched): 100 = seen by the detector,
  0 = in the coverable set CVS but not seen yet, -1 = not coverable by any planner;
* ``/coverage/covered_fraction`` (std_msgs/Float64, latched): |seen and CVS| / |CVS|.

The planner never subscribes to these topics.
"""
import array
import math

import numpy as np
from nav_msgs.msg import OccupancyGrid, Odometry
from std_msgs.msg import Float64

from coverage_pkg.cvs import CoverableSet, CoverageAccumulator
from coverage_pkg.world import load_world_param
from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import LATCHED_QOS, SENSOR_QOS


class CoverageMonitorNode(ParamotionNode):
    """Ground-truth coverage accounting against the coverable set of Section VI."""

    PARAMS = (
        Param('world', '', 'World JSON file.', read_only=True),
        Param('radius', 0.25, 'Robot radius r (m).', min=0.01, max=10.0, read_only=True),
        Param('delta', 2.0, 'Detector range (m): delta, or r for the robot-size detector.',
              min=0.01, max=100.0, read_only=True),
        Param('resolution', 0.05, 'Grid cell of the accounting (m).', min=0.01, max=1.0,
              read_only=True),
        Param('publish_period', 2.0, 'Publication period (s, sim time).', min=0.05,
              max=600.0),
        Param('pose_step', 0.1, 'Add a detector disk every this many metres of motion.',
              min=0.005, max=1.0),
    )

    def __init__(self, node_name='coverage_monitor', **kwargs):
        super().__init__(node_name, **kwargs)
        p = self.params
        self.world = load_world_param(self, p.world, radius=p.radius)
        self.cvs = CoverableSet(self.world, p.radius, p.delta, p.resolution)
        self.acc = CoverageAccumulator(self.cvs)
        self.path = []
        # The grid's cells outside the seen set: -1 outside CVS, 0 in it (the mask is fixed).
        self._unseen = np.where(self.cvs.mask, 0, -1).astype(np.int8)
        self.create_subscription(Odometry, '/coverage/ground_truth', self._on_truth, SENSOR_QOS)
        self.grid_pub = self.create_publisher(OccupancyGrid, '/coverage/seen', LATCHED_QOS)
        self.fraction_pub = self.create_publisher(Float64, '/coverage/covered_fraction',
                                                  LATCHED_QOS)
        self.create_timer(p.publish_period, self.publish)

    def _on_truth(self, msg):
        x, y = msg.pose.pose.position.x, msg.pose.pose.position.y
        if not (math.isfinite(x) and math.isfinite(y)):
            return
        self.acc.add_pose(x, y, min_step=self.params.pose_step)
        if not self.path or math.hypot(x - self.path[-1][0], y - self.path[-1][1]) >= 0.02:
            self.path.append((x, y))

    @property
    def fraction(self):
        return self.acc.fraction()

    def publish(self):
        self.fraction_pub.publish(Float64(data=self.fraction))
        grid = OccupancyGrid()
        grid.header.stamp = self.get_clock().now().to_msg()
        grid.header.frame_id = 'map'
        cvs = self.cvs
        grid.info.resolution = float(cvs.res)
        grid.info.height, grid.info.width = cvs.mask.shape
        grid.info.origin.position.x = float(cvs.origin[0])
        grid.info.origin.position.y = float(cvs.origin[1])
        grid.info.origin.orientation.w = 1.0
        data = self._unseen.copy()
        data[self.acc.seen] = 100
        grid.data = array.array('b', data.tobytes())
        self.grid_pub.publish(grid)


def main(args=None):
    run_node(CoverageMonitorNode, args)


if __name__ == '__main__':
    main()
