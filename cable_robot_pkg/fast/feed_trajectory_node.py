"""fast_trajectory: the feed's target pose along a track on the spherical focal surface.

Publishes ``/fast/feed_target`` (geometry_msgs/PoseStamped, ``map``) at ``rate`` Hz of sim
time: a point of the focal surface with the feed axis (the pose's z axis) toward the sphere's
centre, following the config's track (:class:`cable_robot_pkg.fast.focal_surface.Track`:
circle, meridian or hold) at the field model's scale. ``track_speed`` >= 0 overrides the
config's feed speed along the surface.
"""
import math

from geometry_msgs.msg import PoseStamped

from cable_robot_pkg.fast.focal_surface import Track
from cable_robot_pkg.fast.ros_messages import (
    TOPICS,
    check_config_param,
    config_from_param,
    pose_msg,
)
from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import STATE_QOS


class FeedTrajectoryNode(ParamotionNode):
    """Feed target generator."""

    PARAMS = (
        Param('config', '', 'FAST config YAML (empty: the packaged fast.yaml).',
              read_only=True),
        Param('rate', 100.0, 'Publication rate (Hz, sim time).', min=1.0, max=1000.0,
              read_only=True),
        Param('track_speed', -1.0, "Feed speed along the surface (m/s); < 0: the config's "
              'track.speed.', min=-1.0, max=1.0, read_only=True),
    )

    def __init__(self, node_name='fast_trajectory', **kwargs):
        super().__init__(node_name, **kwargs)
        cfg = config_from_param(self.params.config)
        t = cfg.track
        speed = t.speed if self.params.track_speed < 0 else self.params.track_speed
        self.track = Track(t.surface, t.kind, t.zenith, t.azimuth, speed)
        self.pub = self.create_publisher(PoseStamped, TOPICS['feed_target'], STATE_QOS)
        self.create_timer(1.0 / self.params.rate, self._tick)

    def check_params(self, values):
        return check_config_param(values['config'])

    def _tick(self):
        now = self.get_clock().now()
        t = now.nanoseconds * 1e-9
        position, rotation = self.track.pose(t)
        if math.isfinite(position[0]):
            self.pub.publish(pose_msg(now.to_msg(), 'map', position, rotation))


def main(args=None):
    run_node(FeedTrajectoryNode, args)


if __name__ == '__main__':
    main()
