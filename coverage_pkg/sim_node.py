"""coverage_sim: PyBullet stand-in for a Nomad-style holonomic disk robot in a planar world.

Loads the world file (:mod:`coverage_pkg.world`) as static collision geometry (every wall and
obstacle edge is a thin box), and a cylinder of radius ``radius`` as the robot. The robot is
driven by ``cmd_vel`` (geometry_msgs/Twist in the body frame: linear.x, linear.y, angular.z;
holonomic like a synchro-drive base with an independent turret). Every publish period it
publishes ``odom`` (nav_msgs/Odometry, frame ``odom`` -> ``base_link``; the odom frame
coincides with the start pose), ``/coverage/ground_truth`` (nav_msgs/Odometry in ``map``) and
``/clock``. A ``cmd_vel`` older than ``cmd_timeout`` s of sim time is treated as zero.
"""
import math

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry

from coverage_pkg.world import load_world_param
from paramotion.node import Param, run_node
from paramotion.qos import SENSOR_QOS, STATE_QOS
from paramotion.rotations import quat_from_yaw
from paramotion.sim import SimulationNode

WALL_HEIGHT = 0.5
WALL_THICKNESS = 0.02


class CoverageSimNode(SimulationNode):
    """Planar world + holonomic disk robot in PyBullet (no gravity: the robot glides)."""

    PARAMS = tuple(p for p in SimulationNode.PARAMS
                   if p.name not in ('gravity', 'physics_dt', 'publish_period')) + (
        Param('physics_dt', 0.01, 'PyBullet time step in seconds.', min=1e-4, max=0.05,
              read_only=True),
        Param('publish_period', 0.05, 'Simulated seconds per step; /clock, odom and ground '
              'truth are published once per step.', min=1e-3, max=0.5, read_only=True),
        Param('gravity', 0.0, 'Gravity along z (m/s^2). 0: the planar robot glides on its '
              'velocity command.', min=-20.0, max=0.0, read_only=True),
        Param('world', '', 'World JSON file (format in shared/worlds/README.md).',
              read_only=True),
        Param('radius', 0.25, 'Robot radius r (m).', min=0.01, max=5.0, read_only=True),
        Param('start_yaw', 0.0, 'Initial heading (rad).', min=-math.pi, max=math.pi,
              read_only=True),
        Param('max_speed', 2.0, 'Speed limit applied to cmd_vel (m/s).', min=0.0, max=10.0),
        Param('max_yaw_rate', 3.0, 'Yaw-rate limit applied to cmd_vel (rad/s).', min=0.0,
              max=20.0),
        Param('cmd_timeout', 0.5, 'A command older than this (s, sim time) counts as zero.',
              min=0.01, max=10.0),
    )

    def __init__(self, node_name='coverage_sim', **kwargs):
        super().__init__(node_name, **kwargs)
        p = self.params
        self.world = load_world_param(self, p.world, radius=p.radius)
        b = self.bullet
        for x1, y1, x2, y2 in self.world.segments:
            length = math.hypot(x2 - x1, y2 - y1)
            if length < 1e-9:
                continue
            shape = b.createCollisionShape(
                b.GEOM_BOX, halfExtents=[length / 2.0, WALL_THICKNESS / 2.0, WALL_HEIGHT / 2.0])
            ang = math.atan2(y2 - y1, x2 - x1)
            b.createMultiBody(0.0, shape, basePosition=[(x1 + x2) / 2, (y1 + y2) / 2,
                                                        WALL_HEIGHT / 2],
                              baseOrientation=quat_from_yaw(ang))
        body = b.createCollisionShape(b.GEOM_CYLINDER, radius=p.radius, height=0.3)
        sx, sy = map(float, self.world.start)
        self.robot = b.createMultiBody(10.0, body, basePosition=[sx, sy, WALL_HEIGHT / 2],
                                       baseOrientation=quat_from_yaw(p.start_yaw))
        b.changeDynamics(self.robot, -1, lateralFriction=0.0, linearDamping=0.0,
                         angularDamping=0.0)
        self.start = (sx, sy, float(p.start_yaw))
        self.command = (0.0, 0.0, 0.0)
        self.command_time = None
        self.path_length = 0.0
        self._last_xy = (sx, sy)
        # The per-step PyBullet calls, bound once.
        self._get_pose = self.bullet_function('getBasePositionAndOrientation', self.robot)
        self._get_velocity = self.bullet_function('getBaseVelocity', self.robot)
        self._euler = self.bullet_function('getEulerFromQuaternion')
        self._set_velocity = self.bullet_function('resetBaseVelocity', self.robot)
        self._set_pose = self.bullet_function('resetBasePositionAndOrientation', self.robot)
        self._step = self.bullet_function('stepSimulation')
        self.create_subscription(Twist, 'cmd_vel', self._on_cmd, STATE_QOS)
        self.odom_pub = self.create_publisher(Odometry, 'odom', SENSOR_QOS)
        self.truth_pub = self.create_publisher(Odometry, '/coverage/ground_truth', SENSOR_QOS)
        # One message object per topic, refilled every period (publishing serialises it).
        self._truth_msg = self._new_odometry('map', 'base_link')
        self._odom_msg = self._new_odometry('odom', 'base_link')

    def _on_cmd(self, msg):
        vals = (msg.linear.x, msg.linear.y, msg.angular.z)
        if not all(math.isfinite(v) for v in vals):
            self.get_logger().warning('cmd_vel with a non-finite value ignored')
            return
        p = self.params
        speed = math.hypot(vals[0], vals[1])
        k = min(1.0, p.max_speed / speed) if speed > 0 else 1.0
        wz = max(-p.max_yaw_rate, min(p.max_yaw_rate, vals[2]))
        self.command = (vals[0] * k, vals[1] * k, wz)
        self.command_time = self.sim_time

    def pose(self):
        """True (x, y, yaw) of the robot in the map frame."""
        pos, orn = self._get_pose()
        return float(pos[0]), float(pos[1]), float(self._euler(orn)[2])

    def step_physics(self, dt):
        x, y, yaw = self.pose()
        vx, vy, wz = self.command
        if self.command_time is None or self.sim_time - self.command_time > \
                self.params.cmd_timeout:
            vx = vy = wz = 0.0
        c, s = math.cos(yaw), math.sin(yaw)
        self._set_velocity([c * vx - s * vy, s * vx + c * vy, 0.0], [0.0, 0.0, wz])
        self._step()
        # Keep the robot planar (contacts may tilt or lift it slightly).
        x, y, yaw = self.pose()
        self._set_pose([x, y, WALL_HEIGHT / 2], quat_from_yaw(yaw))
        self.path_length += math.hypot(x - self._last_xy[0], y - self._last_xy[1])
        self._last_xy = (x, y)

    @staticmethod
    def _new_odometry(frame, child):
        msg = Odometry()
        msg.header.frame_id = frame
        msg.child_frame_id = child
        return msg

    @staticmethod
    def _fill_odometry(msg, stamp, x, y, yaw, lin, ang):
        """Header stamp, planar pose and body-frame velocity of ``msg`` (the only fields that
        change; the frames are set once)."""
        msg.header.stamp = stamp
        position = msg.pose.pose.position
        position.x = x
        position.y = y
        o = msg.pose.pose.orientation
        o.x, o.y, o.z, o.w = quat_from_yaw(yaw)
        c, s = math.cos(yaw), math.sin(yaw)
        twist = msg.twist.twist
        twist.linear.x = c * lin[0] + s * lin[1]
        twist.linear.y = -s * lin[0] + c * lin[1]
        twist.angular.z = ang[2]
        return msg

    def publish_state(self):
        x, y, yaw = self.pose()
        stamp = self.stamp()
        lin, ang = self._get_velocity()
        self.truth_pub.publish(self._fill_odometry(self._truth_msg, stamp, x, y, yaw, lin, ang))
        # Odometry in the odom frame = start pose; perfect wheel odometry of the glide model.
        sx, sy, syaw = self.start
        c, s = math.cos(-syaw), math.sin(-syaw)
        ox, oy = c * (x - sx) - s * (y - sy), s * (x - sx) + c * (y - sy)
        self.odom_pub.publish(self._fill_odometry(
            self._odom_msg, stamp, ox, oy, math.remainder(yaw - syaw, 2 * math.pi), lin, ang))


def main(args=None):
    run_node(CoverageSimNode, args)


if __name__ == '__main__':
    main()
