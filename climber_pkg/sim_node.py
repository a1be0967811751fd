"""climber_sim: PyBullet climbing parallel robot on a trunk (hardware stand-in, owns /clock).

World (frame ``map``, z up): the structure from ``trunk_file`` as static collision geometry
(overlapping cylinders following its centreline and radius); the robot as a dynamic closed
chain under gravity: two ring bodies (polygonal annuli with the configured bore) and six legs,
each a two-body prismatic actuator (cylinder + rod) in position control, attached to ring 1 and
ring 2 by ``JOINT_POINT2POINT`` constraints stiffened as NOTES.md prescribes (max force 1e7,
ERP 0.9, 100 solver iterations, 1 kHz). A clamp is a ``JOINT_FIXED`` constraint between a ring
and the world, made ``clamp_close_time`` after a close command (then reported closed) and
removed at once on a release command (reported open at once: the grip is gone).

Hardware interlock (defence in depth, ``interlock`` parameter): a release command is ignored,
with an error log and a count in the status, while the other clamp is not closed.

Subscribes: ``/climber/leg_command`` (trajectory_msgs/JointTrajectory, legs leg1..leg6, last
point's positions = lengths, reached linearly over its time_from_start),
``/climber/ring{1,2}/clamp_command`` (std_msgs/Bool, true = close).
Publishes: ``/climber/joint_states`` (sensor_msgs/JointState, encoder lengths m, rates m/s),
``/climber/ring{1,2}/clamp_closed`` (std_msgs/Bool), ``/climber/ground_truth``
(geometry_msgs/PoseArray [ring 1, ring 2], ``map``), ``/climber/sim_status``
(diagnostic_msgs/DiagnosticStatus: ring-trunk contacts, interlock trips), ``/clock``.
"""
import math

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import Pose, PoseArray
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool
from trajectory_msgs.msg import JointTrajectory

from climber_pkg.evaluation import ring_clearance
from climber_pkg.kinematic_model import initial_pose_on_trunk
from climber_pkg.robot import load_robot_config
from climber_pkg.trunk import Trunk
from paramotion.errors import ParameterError, UserError
from paramotion.node import Param, run_node
from paramotion.qos import SENSOR_QOS, STATE_QOS
from paramotion.rotations import matrix_from_quat, quat_from_matrix
from paramotion.sim import SimulationNode

LEG_NAMES = tuple(f'leg{i}' for i in range(1, 7))
RING_SEGMENTS = 24
TRUNK_SEGMENT = 0.1


def frame_from_z(z_axis):
    """A rotation whose z column is ``z_axis`` (x chosen perpendicular to it)."""
    z = np.asarray(z_axis, dtype=float)
    z = z / np.linalg.norm(z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


class ClimberSimNode(SimulationNode):
    """The 6-UPS climbing robot and its trunk in PyBullet."""

    PARAMS = SimulationNode.PARAMS + (
        Param('trunk_file', '', 'Structure JSON (shared/trunks format) to climb.',
              read_only=True),
        Param('robot_config', '', 'Robot geometry YAML; empty = climber_pkg/config/climber.yaml.',
              read_only=True),
        Param('start_s', 0.4, 'Arc length of ring 1 centre on the structure at start (m).',
              min=0.0, max=100.0, read_only=True),
        Param('start_offset', 0.0, 'Start off the structure axis by this distance, in ring 1 '
              "'s plane (m); direction drawn from start_seed.", min=0.0, max=0.2,
              read_only=True),
        Param('start_tilt_deg', 0.0, 'Start tilted from the structure axis by this angle about '
              'an axis through mid-height (deg); axis drawn from start_seed.', min=0.0,
              max=30.0, read_only=True),
        Param('start_seed', 1, 'Seed of the start offset direction and tilt axis.', min=0,
              max=2 ** 31 - 1, read_only=True),
        Param('start_length', 0.5, 'Initial length of every leg (m).', min=0.1, max=10.0,
              read_only=True),
        Param('leg_force', 5000.0, 'Force limit of each actuator (N).', min=1.0, max=1e6),
        Param('solver_iterations', 100, 'PyBullet constraint solver iterations.', min=10,
              max=1000, read_only=True),
        Param('interlock', True, 'Ignore a clamp release while the other clamp is not closed.'),
        Param('start_clamped', True, 'Both clamps closed at start (else ring 1 only).',
              read_only=True),
    )

    def __init__(self, node_name='climber_sim', **kwargs):
        super().__init__(node_name, **kwargs)
        p = self.params
        if not p.trunk_file:
            raise ParameterError(f"{node_name}: parameter 'trunk_file' is required")
        self.trunk = Trunk.from_file(p.trunk_file)
        self.robot = load_robot_config(p.robot_config or None)
        geom = self.robot.geometry
        if not geom.leg_min <= p.start_length <= geom.leg_max:
            raise ParameterError(f"{node_name}: parameter 'start_length' = {p.start_length} "
                                 f'outside the stroke [{geom.leg_min}, {geom.leg_max}] m')
        if self.trunk.max_radius >= self.robot.ring_inner_radius:
            raise UserError(f'{p.trunk_file}: radius {self.trunk.max_radius:.3f} m does not '
                            f'pass through the {self.robot.ring_inner_radius:.3f} m ring bore')
        b = self.bullet
        b.setPhysicsEngineParameter(numSolverIterations=p.solver_iterations)
        self._build_trunk()
        lengths = np.full(6, p.start_length)
        (p1, r1), (p2, r2) = initial_pose_on_trunk(
            self.trunk, self.robot, p.start_s, lengths, p.start_offset,
            math.radians(p.start_tilt_deg), p.start_seed)
        for ring, (pos, rot) in enumerate(((p1, r1), (p2, r2))):
            gap = ring_clearance(self.trunk, self.robot, pos, rot)
            if not gap > 0.005:
                raise ParameterError(
                    f"{node_name}: parameters 'start_offset' = {p.start_offset} m and "
                    f"'start_tilt_deg' = {p.start_tilt_deg} put ring {ring + 1}'s bore "
                    f'{1000 * gap:.0f} mm from the structure (need > 5 mm)')
        self.rings = [self._make_ring(p1, r1), self._make_ring(p2, r2)]
        self.legs = [self._make_leg(i, (p1, r1), (p2, r2)) for i in range(6)]
        self._filter_collisions()
        self.clamp_constraint = [None, None]
        self.clamp_closed = [False, False]
        self._closing_at = [None, None]
        for ring in (0, 1) if p.start_clamped else (0,):
            self._make_clamp(ring)
        self.interlock_trips = 0
        self.contacts = 0
        self.max_contact_depth = 0.0
        # Command trajectory: linear from (t0, start) to (t1, target).
        self._cmd = (0.0, lengths.copy(), 0.0, lengths.copy())
        self._last_lengths = lengths.copy()
        self.create_subscription(JointTrajectory, '/climber/leg_command', self._on_legs,
                                 STATE_QOS)
        for ring in (0, 1):
            self.create_subscription(Bool, f'/climber/ring{ring + 1}/clamp_command',
                                     lambda msg, r=ring: self._on_clamp(r, msg), STATE_QOS)
        self.joint_pub = self.create_publisher(JointState, '/climber/joint_states', SENSOR_QOS)
        self.clamp_pubs = [self.create_publisher(Bool, f'/climber/ring{r}/clamp_closed',
                                                 STATE_QOS) for r in (1, 2)]
        self.truth_pub = self.create_publisher(PoseArray, '/climber/ground_truth', SENSOR_QOS)
        self.status_pub = self.create_publisher(DiagnosticStatus, '/climber/sim_status',
                                                STATE_QOS)
        # Per-step PyBullet calls bound once, and the motor targets last set (a leg's motor is
        # set again only when its target or force changed: setting the same values again
        # leaves the simulation as it is).
        self._step = self.bullet_function('stepSimulation')
        self._motors = [self.bullet_function('setJointMotorControl2', leg, 0,
                                             b.POSITION_CONTROL) for leg in self.legs]
        self._joint_state = [self.bullet_function('getJointState', leg, 0)
                             for leg in self.legs]
        self._ring_pose = [self.bullet_function('getBasePositionAndOrientation', ring)
                           for ring in self.rings]
        self._motor_set = None
        # One message object per topic, refilled every period (publishing serialises it).
        self._joints_msg = JointState(name=list(LEG_NAMES))
        self._truth_msg = PoseArray(poses=[Pose(), Pose()])
        self._truth_msg.header.frame_id = 'map'

    # ------------------------------------------------------------------ world building
    def _build_trunk(self):
        b, tr = self.bullet, self.trunk
        n = max(1, int(math.ceil(tr.length / TRUNK_SEGMENT)))
        edges = np.linspace(0.0, tr.length, n + 1)
        self.trunk_bodies = []
        for s0, s1 in zip(edges[:-1], edges[1:]):
            a, c = tr.point_at(s0), tr.point_at(s1)
            mid = 0.5 * (a + c)
            radius = float(tr.radius_at(0.5 * (s0 + s1)))
            height = float(np.linalg.norm(c - a)) + 0.01      # overlap the neighbours
            shape = b.createCollisionShape(b.GEOM_CYLINDER, radius=radius, height=height)
            body = b.createMultiBody(0.0, shape, basePosition=mid.tolist(),
                                     baseOrientation=quat_from_matrix(frame_from_z(c - a)))
            self.trunk_bodies.append(body)

    def _make_ring(self, position, rotation):
        b, rb = self.bullet, self.robot
        r_in, r_out = rb.ring_inner_radius, rb.ring_outer_radius
        width = r_out - r_in
        r_mid = 0.5 * (r_in + r_out)
        chord = 2 * r_mid * math.tan(math.pi / RING_SEGMENTS) + 0.005
        types, half, pos, orn = [], [], [], []
        for k in range(RING_SEGMENTS):
            ang = 2 * math.pi * k / RING_SEGMENTS
            # Box centred so its inner face is tangent to the bore circle.
            centre = (r_in + width / 2) * np.array([math.cos(ang), math.sin(ang)])
            types.append(b.GEOM_BOX)
            half.append([width / 2, chord / 2, rb.ring_thickness / 2])
            pos.append([float(centre[0]), float(centre[1]), 0.0])
            orn.append([0.0, 0.0, math.sin(ang / 2), math.cos(ang / 2)])
        shape = b.createCollisionShapeArray(shapeTypes=types, halfExtents=half,
                                            collisionFramePositions=pos,
                                            collisionFrameOrientations=orn)
        body = b.createMultiBody(rb.ring_mass, shape, basePosition=np.asarray(position).tolist(),
                                 baseOrientation=quat_from_matrix(rotation))
        b.changeDynamics(body, -1, linearDamping=0.0, angularDamping=0.0)
        return body

    def _make_leg(self, i, pose1, pose2):
        b, rb = self.bullet, self.robot
        geom = rb.geometry
        (p1, r1), (p2, r2) = pose1, pose2
        a = p1 + r1 @ geom.base_anchors[i]
        tip = p2 + r2 @ geom.platform_anchors[i]
        rot = frame_from_z(tip - a)
        ball = b.createCollisionShape(b.GEOM_SPHERE, radius=rb.leg_radius)
        half_mass = rb.leg_mass / 2
        leg = b.createMultiBody(
            baseMass=half_mass, baseCollisionShapeIndex=ball, basePosition=a.tolist(),
            baseOrientation=quat_from_matrix(rot),
            linkMasses=[half_mass], linkCollisionShapeIndices=[ball],
            linkVisualShapeIndices=[-1], linkPositions=[[0.0, 0.0, 0.0]],
            linkOrientations=[[0, 0, 0, 1]], linkInertialFramePositions=[[0, 0, 0]],
            linkInertialFrameOrientations=[[0, 0, 0, 1]], linkParentIndices=[0],
            linkJointTypes=[b.JOINT_PRISMATIC], linkJointAxis=[[0.0, 0.0, 1.0]])
        b.resetJointState(leg, 0, float(np.linalg.norm(tip - a)))
        b.changeDynamics(leg, -1, angularDamping=0.5)
        b.changeDynamics(leg, 0, angularDamping=0.5, jointLowerLimit=geom.leg_min,
                         jointUpperLimit=geom.leg_max)
        c1 = b.createConstraint(self.rings[0], -1, leg, -1, b.JOINT_POINT2POINT, [0, 0, 0],
                                geom.base_anchors[i].tolist(), [0, 0, 0])
        c2 = b.createConstraint(self.rings[1], -1, leg, 0, b.JOINT_POINT2POINT, [0, 0, 0],
                                geom.platform_anchors[i].tolist(), [0, 0, 0])
        for c in (c1, c2):
            b.changeConstraint(c, maxForce=1e7, erp=0.9)
        return leg

    def _filter_collisions(self):
        b = self.bullet
        for leg in self.legs:
            for link in (-1, 0):
                b.setCollisionFilterGroupMask(leg, link, 0, 0)   # legs touch nothing
        b.setCollisionFilterPair(self.rings[0], self.rings[1], -1, -1, 0)

    def _make_clamp(self, ring):
        b = self.bullet
        pos, orn = b.getBasePositionAndOrientation(self.rings[ring])
        c = b.createConstraint(self.rings[ring], -1, -1, -1, b.JOINT_FIXED, [0, 0, 0],
                               [0, 0, 0], pos, childFrameOrientation=orn)
        b.changeConstraint(c, maxForce=1e8, erp=0.9)
        self.clamp_constraint[ring] = c
        self.clamp_closed[ring] = True

    # ------------------------------------------------------------------ commands
    def _on_legs(self, msg):
        if not msg.points:
            return
        try:
            index = [list(msg.joint_names).index(n) for n in LEG_NAMES]
        except ValueError:
            self.get_logger().error(f'leg command must name {LEG_NAMES}, got {msg.joint_names}')
            return
        target = np.array([msg.points[-1].positions[k] for k in index], dtype=float)
        if not np.all(np.isfinite(target)):
            self.get_logger().error(f'leg command not finite: {target}')
            return
        geom = self.robot.geometry
        target = np.clip(target, geom.leg_min, geom.leg_max)     # mechanical end stops
        dur = msg.points[-1].time_from_start
        duration = dur.sec + dur.nanosec * 1e-9
        now = self.sim_time
        self._cmd = (now, self._commanded(now), now + duration, target)

    def _commanded(self, t):
        t0, start, t1, target = self._cmd
        if t >= t1 or t1 <= t0:
            return target.copy()
        return start + (target - start) * (t - t0) / (t1 - t0)

    def _on_clamp(self, ring, msg):
        if msg.data:
            if not self.clamp_closed[ring] and self._closing_at[ring] is None:
                self._closing_at[ring] = self.sim_time + self.robot.clamp_close_time
            return
        self._closing_at[ring] = None
        if not self.clamp_closed[ring]:
            return
        if self.params.interlock and not self.clamp_closed[1 - ring]:
            self.interlock_trips += 1
            self.get_logger().error(f'interlock: release of ring {ring + 1} refused, ring '
                                    f'{2 - ring} is not clamped')
            return
        self.bullet.removeConstraint(self.clamp_constraint[ring])
        self.clamp_constraint[ring] = None
        self.clamp_closed[ring] = False

    # ------------------------------------------------------------------ simulation
    def step_physics(self, dt):
        for ring in (0, 1):
            due = self._closing_at[ring]
            if due is not None and self.sim_time >= due - 1e-9:
                self._closing_at[ring] = None
                self._make_clamp(ring)
        target = self._commanded(self.sim_time).tolist()
        force = self.params.leg_force
        if self._motor_set != (target, force):
            self._motor_set = (target, force)
            for motor, q in zip(self._motors, target):
                motor(targetPosition=q, force=force, positionGain=0.3, velocityGain=1.0,
                      maxVelocity=1.0)
        self._step()

    def leg_lengths(self):
        return np.array([state()[0] for state in self._joint_state])

    def ring_poses(self):
        """True ring poses [(position, rotation)] in map."""
        out = []
        for pose in self._ring_pose:
            pos, orn = pose()
            out.append((np.array(pos), matrix_from_quat(orn)))
        return out

    def publish_state(self):
        b = self.bullet
        stamp = self.stamp()
        states = [state() for state in self._joint_state]
        js = self._joints_msg
        js.header.stamp = stamp
        js.position = [s[0] for s in states]
        js.velocity = [s[1] for s in states]
        js.effort = [s[3] for s in states]
        self.joint_pub.publish(js)
        for ring in (0, 1):
            self.clamp_pubs[ring].publish(Bool(data=bool(self.clamp_closed[ring])))
        pa = self._truth_msg
        pa.header.stamp = stamp
        for pose, (pos, rot) in zip(pa.poses, self.ring_poses()):
            p, o = pose.position, pose.orientation
            p.x, p.y, p.z = pos.tolist()
            o.x, o.y, o.z, o.w = quat_from_matrix(rot)
        self.truth_pub.publish(pa)
        contacts = 0
        for ring in self.rings:
            for pt in b.getContactPoints(bodyA=ring):
                if pt[2] in self.trunk_bodies:
                    contacts += 1
                    self.max_contact_depth = max(self.max_contact_depth, -pt[8])
        self.contacts += contacts
        st = DiagnosticStatus(name='climber_sim', hardware_id='pybullet',
                              level=DiagnosticStatus.OK if contacts == 0 else
                              DiagnosticStatus.WARN,
                              message='ring-trunk contact' if contacts else 'ok')
        st.values = [KeyValue(key='contacts_now', value=str(contacts)),
                     KeyValue(key='contacts_total', value=str(self.contacts)),
                     KeyValue(key='interlock_trips', value=str(self.interlock_trips))]
        self.status_pub.publish(st)


def main(args=None):
    run_node(ClimberSimNode, args)


if __name__ == '__main__':
    main()
