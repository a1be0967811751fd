"""The FAST feed support as a PyBullet model: what is simulated how (no rclpy).

Split between PyBullet and analytic models (chosen so that a 60 s run stays fast):

- **Rigid bodies in PyBullet** (real dynamics, 1 kHz by default): the trolley as a free-floating
  box; the 2-DOF orienting mechanism (ring on a hinge about the trolley x axis, upper platform on
  a hinge about the ring's y axis); six legs, each a cylinder on a spherical joint under the
  upper platform plus a rod on a prismatic joint; and the lower (feed) platform as a separate
  body tied to the six rod tips by ``JOINT_POINT2POINT`` constraints -- a closed kinematic chain,
  stiffened (``maxForce``, ``erp``, solver iterations) as NOTES.md found necessary. Leg and hinge
  reaction forces shake the trolley: the dynamic coupling of Cheng et al.
- **Actuators**: hinge servos are PyBullet's implicit position/velocity motors with a torque
  limit. Leg drives are either the same near-ideal implicit servo (``gough_stewart.actuator:
  servo``) or a *force* drive (``actuator: force``): an explicit PD on the leg's length and
  rate errors (``actuator_stiffness`` N/m, ``actuator_damping`` N s/m) plus the static leg
  force that carries the feed at the nominal pose, through a first-order force lag
  (``actuator_bandwidth_hz``) and clipped at ``drive_force_max`` -- a drive with finite
  stiffness, bandwidth and force. Commands are position + velocity, held first-order between
  updates.
- **Cables analytically** (:mod:`cable_robot_pkg.fast.cables`): ten tension-only elastic cables
  whose wrench is applied to the trolley every step; cable mass/sag and pulley friction are
  neglected. Winches set the unstretched length, rate-limited to ``winch_speed_max``.
- **Wind analytically** (:mod:`cable_robot_pkg.fast.wind`): force and torque on the trolley.
- Collisions are off (nothing touches anything); towers are static visual bodies.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pybullet
from numpy.typing import ArrayLike

from cable_robot_pkg.fast.cables import compiled_kernel
from cable_robot_pkg.fast.focal_surface import hinge_rotation
from paramotion.gough_stewart import inverse_kinematics, jacobian
from paramotion.rotations import quat_from_matrix

if TYPE_CHECKING:
    from pybullet_utils.bullet_client import BulletClient

    from cable_robot_pkg.fast.configuration import FastConfig
    from cable_robot_pkg.fast.wind import WindModel

_EYE_Q = [0.0, 0.0, 0.0, 1.0]


def _matrix(q):
    return np.array(pybullet.getMatrixFromQuaternion(q)).reshape(3, 3)


class FeedSupportPlant:
    """Trolley + orienting mechanism + Gough-Stewart platform + cables + wind in one client."""

    def __init__(self, cfg: FastConfig, bullet: BulletClient, wind: WindModel | None = None,
                 start_time: float = 0.0, dt: float | None = None,
                 solver_iterations: int | None = None):
        self.cfg = cfg
        self.b = bullet
        self.wind = wind
        self.t = start_time
        raw = cfg.raw
        self.dt = raw['sim']['physics_dt'] if dt is None else float(dt)
        b = bullet
        b.setTimeStep(self.dt)
        iterations = raw['sim']['solver_iterations'] if solver_iterations is None \
            else solver_iterations
        b.setPhysicsEngineParameter(numSolverIterations=int(iterations))
        self.geom = cfg.geometry
        self.chain = cfg.chain
        self.cables = cfg.cables
        self.winch_speed = raw['cables']['winch_speed_max']
        self.t_max = raw['cables']['tension_max']
        feed_p, feed_R, trolley_p, alpha, beta, lengths = self._start_at_track(start_time)
        # PyBullet model, in this order (body and shape ids, hence results, depend on it).
        self._build_towers(raw)
        self._build_bodies(raw, trolley_p, feed_p, feed_R)
        self._pose_chain(alpha, beta)
        self._close_legs()
        self._init_drives(raw, start_time, lengths, bullet._client)
        # Settle the closed chain (constraints at rest) before time starts.
        self.apply_commands(0.0)
        for _ in range(5):
            b.stepSimulation()

    def _start_at_track(self, start_time):
        """Start at the first track target, cables at their planned tensions: sets the winch
        state and returns ``(feed_p, feed_R, trolley_p, alpha, beta, cable lengths)``."""
        feed_p, feed_R = self.cfg.track.pose(start_time)
        trolley_p, (alpha, beta), _, _ = self.chain.coarse_targets(feed_p, feed_R)
        t_plan = self.cfg.tension_targets(trolley_p, feed_R)
        lengths = self.cables.lengths(trolley_p, np.eye(3))
        self.unstretched = self.cables.unstretched_for(lengths, t_plan)
        self.winch_cmd = self.unstretched.copy()
        self.winch_rate_cmd = np.zeros(self.cables.n)
        self.winch_cmd_time = start_time
        return feed_p, feed_R, trolley_p, alpha, beta, lengths

    def _build_bodies(self, raw, trolley_p, feed_p, feed_R):
        """The trolley multibody (base) with the orienting ring, the upper platform and six
        two-body prismatic legs as links, and the feed platform as a free body. Legs start at
        their nominal lengths (``self.nominal_lengths``); nothing collides."""
        b = self.b
        gs = raw['gough_stewart']
        up_off = self.chain.upper_offset
        hinge = np.asarray(self.chain.hinge_offset, float)
        tsize = np.asarray(raw['trolley']['size'], float)
        trolley_shape = b.createCollisionShape(b.GEOM_BOX, halfExtents=list(tsize / 2))
        ring_shape = b.createCollisionShape(b.GEOM_BOX, halfExtents=[0.3, 0.3, 0.05])
        upper_shape = b.createCollisionShape(
            b.GEOM_CYLINDER, radius=gs['base_radius'], height=0.06)
        leg_shape = b.createCollisionShape(b.GEOM_CYLINDER, radius=0.03, height=0.4)

        base_local = self.geom.base_anchors - np.array([0.0, 0.0, up_off])   # upper link frame
        rel_p, rel_R = self.chain.nominal_relative_pose()
        plat_in_upper = rel_p + self.geom.platform_anchors @ rel_R.T          # upper plat frame
        self.nominal_lengths = inverse_kinematics(self.geom, rel_p, rel_R)
        leg_m = gs['leg_mass'] / 2.0

        masses, shapes, positions, orients, inertial_pos = [], [], [], [], []
        parents, jtypes, axes = [], [], []
        # link 0: ring on hinge about trolley x
        masses.append(raw['orienting']['ring_mass'])
        shapes.append(ring_shape)
        positions.append(list(hinge))
        orients.append(_EYE_Q)
        inertial_pos.append([0, 0, 0])
        parents.append(0)
        jtypes.append(b.JOINT_REVOLUTE)
        axes.append([1, 0, 0])
        # link 1: upper platform on hinge about ring y; its link frame is at the hinge centre
        masses.append(gs['upper_mass'])
        shapes.append(upper_shape)
        positions.append([0, 0, 0])
        orients.append(_EYE_Q)
        inertial_pos.append([0, 0, -up_off])
        parents.append(1)
        jtypes.append(b.JOINT_REVOLUTE)
        axes.append([0, 1, 0])
        self.leg_dirs = []
        # Links in depth-first order (PyBullet's own order): cylinder i, then its rod.
        for i in range(6):
            d = plat_in_upper[i] - self.geom.base_anchors[i]
            u = d / np.linalg.norm(d)
            self.leg_dirs.append(u)
            # Leg frame: z along the nominal leg (downward), built from u.
            x = np.cross([0.0, 1.0, 0.0], u)
            x = x / np.linalg.norm(x)
            R_leg = np.column_stack([x, np.cross(u, x), u])
            masses += [leg_m, leg_m]
            shapes += [leg_shape, leg_shape]
            positions += [list(base_local[i]), [0, 0, float(self.nominal_lengths[i])]]
            orients += [list(quat_from_matrix(R_leg)), _EYE_Q]
            inertial_pos += [[0, 0, 0.2], [0, 0, -0.2]]
            cyl_index = 2 + 2 * i
            parents += [2, cyl_index + 1]
            jtypes += [b.JOINT_SPHERICAL, b.JOINT_PRISMATIC]
            axes += [[0, 0, 1], [0, 0, 1]]
        n_links = len(masses)
        self.body = b.createMultiBody(
            baseMass=raw['trolley']['mass'], baseCollisionShapeIndex=trolley_shape,
            basePosition=list(trolley_p), baseOrientation=_EYE_Q,
            linkMasses=masses, linkCollisionShapeIndices=shapes,
            linkVisualShapeIndices=[-1] * n_links, linkPositions=positions,
            linkOrientations=orients, linkInertialFramePositions=inertial_pos,
            linkInertialFrameOrientations=[_EYE_Q] * n_links, linkParentIndices=parents,
            linkJointTypes=jtypes, linkJointAxis=axes)
        self.RING, self.UPPER = 0, 1
        self.CYL = list(range(2, 14, 2))
        self.ROD = list(range(3, 14, 2))
        self.feed = b.createMultiBody(
            baseMass=gs['feed_mass'],
            baseCollisionShapeIndex=b.createCollisionShape(
                b.GEOM_CYLINDER, radius=gs['platform_radius'], height=0.06),
            basePosition=list(feed_p), baseOrientation=list(quat_from_matrix(feed_R)))
        for body in (self.body, self.feed):
            for link in range(-1, b.getNumJoints(body)):
                b.setCollisionFilterGroupMask(body, link, 0, 0)
                b.changeDynamics(body, link, linearDamping=0.0, angularDamping=0.0)

    def _pose_chain(self, alpha, beta):
        """Hinges at the start target; the legs' spherical joints free (motors off)."""
        b = self.b
        b.resetJointState(self.body, self.RING, alpha)
        b.resetJointState(self.body, self.UPPER, beta)
        self.hinge_cmd = np.array([alpha, beta])
        for i in range(6):
            b.resetJointStateMultiDof(self.body, self.CYL[i], _EYE_Q)
            b.setJointMotorControlMultiDof(self.body, self.CYL[i], b.POSITION_CONTROL,
                                           targetPosition=_EYE_Q, positionGain=0.0,
                                           velocityGain=0.0, force=[0.0, 0.0, 0.0])

    def _close_legs(self):
        """Close the six loops: each rod tip to its feed anchor, a stiffened point-to-point
        constraint (``maxForce=1e7, erp=0.9``; PyBullet's defaults leave 20-50 mm of play)."""
        b = self.b
        self.constraints = []
        for i in range(6):
            # Constraint pivots are given relative to the link's centre of mass: the rod tip
            # (rod link frame origin) is 0.2 m above the rod's CoM.
            c = b.createConstraint(self.body, self.ROD[i], self.feed, -1, b.JOINT_POINT2POINT,
                                   [0, 0, 0], [0, 0, 0.2],
                                   list(self.geom.platform_anchors[i]))
            b.changeConstraint(c, maxForce=1e7, erp=0.9)
            self.constraints.append(c)

    def _init_drives(self, raw, start_time, lengths, client_id):
        """Leg and hinge servo set-points and gains, and the state the step reports."""
        gs = raw['gough_stewart']
        orient = raw['orienting']
        self.leg_cmd = self.nominal_lengths.copy()
        self.leg_rate_cmd = np.zeros(6)
        self.leg_cmd_time = start_time
        self.hinge_gains = (orient['servo_position_gain'], orient['servo_velocity_gain'],
                            orient['torque_max'])
        self.leg_gains = (gs['servo_position_gain'], gs['servo_velocity_gain'],
                          gs['drive_force_max'])
        self._cid = client_id
        self._leg_kp = [float(self.leg_gains[0])] * 6
        self._leg_kv = [float(self.leg_gains[1])] * 6
        self._leg_fmax = [float(self.leg_gains[2])] * 6
        self.force_drive = gs.get('actuator', 'servo') == 'force'
        self.leg_force = np.zeros(6)
        if self.force_drive:
            self._init_force_drive(gs)
        self._hinge_sent = None
        self.last_tensions = np.zeros(self.cables.n)
        self.last_lengths = lengths
        self.slack = np.zeros(self.cables.n, bool)
        self.slack_count = 0                     # slack cables at the last step
        self.tension_range = (0.0, 0.0)          # smallest and largest tension, last step
        # The compiled step (None: numpy), chosen when the plant is built.
        self._kernel = compiled_kernel('plant_step')
        self.winch_rates = np.zeros(self.cables.n)
        self.wind_force = np.zeros(3)
        self.wind_torque = np.zeros(3)
        # The compiled step's wind constants (and placeholders when there is no wind).
        self._wind_params = self.wind.kernel_parameters() if self.wind is not None \
            else np.zeros(8)
        self._no_block = np.zeros((6, 1))

    def _init_force_drive(self, gs):
        """Force drives: free the prismatic joints' default motors and compute the static
        leg forces that hold the feed's weight at the nominal pose (``J^T f = -w``)."""
        self.drive_kp = float(gs['actuator_stiffness'])
        self.drive_kd = float(gs['actuator_damping'])
        self.drive_tau = 1.0 / (2.0 * math.pi * float(gs['actuator_bandwidth_hz']))
        pybullet.setJointMotorControlArray(self.body, self.ROD, pybullet.VELOCITY_CONTROL,
                                           forces=[0.0] * 6, physicsClientId=self._cid)
        rel_p, rel_R = self.chain.nominal_relative_pose()
        _, _, _, up_R = self.chain.coarse_targets(*self.cfg.track.pose(self.t))
        J = jacobian(self.geom, rel_p, rel_R)
        weight = up_R.T @ np.array([0.0, 0.0, -9.81 * gs['feed_mass']])
        self.static_leg_force = np.linalg.solve(J.T, -np.concatenate([weight, np.zeros(3)]))
        self.leg_force = self.static_leg_force.copy()

    def _apply_force_drive(self, target, rates):
        """Explicit PD force of each leg drive, lagged by its bandwidth, clipped."""
        cid = self._cid
        states = pybullet.getJointStates(self.body, self.ROD, physicsClientId=cid)
        q = np.array([st[0] for st in states]) + self.nominal_lengths
        qd = np.array([st[1] for st in states])
        demand = self.drive_kp * (target - q) + self.drive_kd * (rates - qd) \
            + self.static_leg_force
        self.leg_force += self.dt / (self.drive_tau + self.dt) * (demand - self.leg_force)
        fmax = self._leg_fmax[0]
        self.leg_force = np.clip(self.leg_force, -fmax, fmax)
        pybullet.setJointMotorControlArray(self.body, self.ROD, pybullet.TORQUE_CONTROL,
                                           forces=self.leg_force.tolist(), physicsClientId=cid)

    def _build_towers(self, raw):
        b = self.b
        for name, top in raw['towers'].items():
            top = np.asarray(top, float)
            shape = b.createCollisionShape(b.GEOM_BOX, halfExtents=[0.3, 0.3, top[2] / 2])
            tower = b.createMultiBody(0.0, shape, basePosition=[top[0], top[1], top[2] / 2])
            b.setCollisionFilterGroupMask(tower, -1, 0, 0)

    # ------------------------------------------------------------------ commands
    def set_winch_command(self, unstretched: ArrayLike, rates: ArrayLike | None = None,
                          stamp: float | None = None) -> None:
        """Winch set-point: unstretched lengths valid at ``stamp`` (default now) moving at
        ``rates`` (a time-stamped trajectory point, held first-order)."""
        self.winch_cmd = np.asarray(unstretched, float).copy()
        self.winch_rate_cmd = np.zeros(self.cables.n) if rates is None else np.asarray(rates)
        self.winch_cmd_time = self.t if stamp is None else min(float(stamp), self.t)

    def set_leg_command(self, lengths: ArrayLike, rates: ArrayLike | None = None,
                        stamp: float | None = None) -> None:
        """Leg set-point: lengths valid at ``stamp`` (default now) moving at ``rates``."""
        self.leg_cmd = np.asarray(lengths, float).copy()
        self.leg_rate_cmd = np.zeros(6) if rates is None else np.asarray(rates, float)
        self.leg_cmd_time = self.t if stamp is None else min(float(stamp), self.t)

    def set_hinge_command(self, alpha: float, beta: float) -> None:
        self.hinge_cmd = np.array([alpha, beta], float)

    def apply_commands(self, since: float) -> None:
        """Servo targets (first-order hold of position + velocity commands).

        The six leg servos are set in one ``setJointMotorControlArray`` call; the hinge servos
        only when their command changed (PyBullet keeps a motor's set-point until it is set
        again, so re-sending an unchanged one every step did nothing but cost time).
        """
        target = np.clip(self.leg_cmd + self.leg_rate_cmd * since, self.geom.leg_min,
                         self.geom.leg_max)
        self._send_commands(target, target - self.nominal_lengths)

    def _send_commands(self, target: np.ndarray, joint_target: np.ndarray) -> None:
        """Leg drives toward ``target`` (lengths; ``joint_target`` the same minus the
        nominal lengths, the prismatic joints' positions) and the hinge servos when their
        command changed."""
        cid = self._cid
        if self.force_drive:
            self._apply_force_drive(target, self.leg_rate_cmd)
        else:
            pybullet.setJointMotorControlArray(
                self.body, self.ROD, pybullet.POSITION_CONTROL,
                targetPositions=joint_target.tolist(),
                targetVelocities=self.leg_rate_cmd.tolist(), positionGains=self._leg_kp,
                velocityGains=self._leg_kv, forces=self._leg_fmax, physicsClientId=cid)
        hinge = (float(self.hinge_cmd[0]), float(self.hinge_cmd[1]))
        if hinge != self._hinge_sent:
            kp, kv, tmax = self.hinge_gains
            for j, link in enumerate((self.RING, self.UPPER)):
                pybullet.setJointMotorControl2(self.body, link, pybullet.POSITION_CONTROL,
                                               targetPosition=hinge[j], positionGain=kp,
                                               velocityGain=kv, force=tmax,
                                               physicsClientId=cid)
            self._hinge_sent = hinge

    # ------------------------------------------------------------------ stepping
    def step(self) -> None:
        """Advance one physics step: winches, cable and wind wrenches, servos, PyBullet.

        This runs 1000 times per simulated second, so it calls the PyBullet module directly
        (with the client id) instead of through ``BulletClient`` attribute look-ups and reads
        the trolley state once. With numba the winches, cables, wind and leg targets are one
        compiled call (:func:`cable_robot_pkg.fast.cable_kernel.plant_step`, the same
        arithmetic in the same order as :meth:`_step_numpy`, which is the path without
        numba and with ``PARAMOTION_BACKEND=numpy`` when the plant is built). Also sets
        ``tension_range`` and ``slack_count`` for the simulator's bookkeeping.
        """
        kernel = self._kernel
        if kernel is None:
            self._step_numpy()
            return
        cid = self._cid
        body = self.body
        args, pos = self._kernel_arguments()
        kernel(*args)
        out, slack = args[-2], args[-1]
        n = self.cables.n
        wind = self.wind
        self.last_tensions = out[12:12 + n]
        self.last_lengths = out[12 + n:12 + 2 * n]
        self.unstretched = out[12 + 2 * n:12 + 3 * n]
        self.winch_rates = out[12 + 3 * n:12 + 4 * n]
        self.slack = slack
        self.tension_range = (float(out[24 + 4 * n]), float(out[25 + 4 * n]))
        self.slack_count = int(out[26 + 4 * n])
        if wind is not None:
            self.wind_force, self.wind_torque = out[6:9], out[9:12]
        pybullet.applyExternalForce(body, -1, out[0:3].tolist(), pos, pybullet.WORLD_FRAME,
                                    physicsClientId=cid)
        pybullet.applyExternalTorque(body, -1, out[3:6].tolist(), pybullet.WORLD_FRAME,
                                     physicsClientId=cid)
        legs = 12 + 4 * n
        self._send_commands(out[legs:legs + 6], out[legs + 6:legs + 12])
        pybullet.stepSimulation(physicsClientId=cid)
        self.t += self.dt

    def _kernel_arguments(self, with_wind: bool = True) -> tuple[tuple, tuple]:
        """The compiled step's arguments at the current state (its two outputs, ``out`` and
        ``slack``, last and new), and the trolley position read from PyBullet.
        ``with_wind=False`` leaves the wind model alone (it draws gusts and turbulence
        blocks from its generator as time goes on) and passes its placeholders, of the same
        types."""
        cid = self._cid
        t = self.t
        pos, q = pybullet.getBasePositionAndOrientation(self.body, physicsClientId=cid)
        lin, ang = pybullet.getBaseVelocity(self.body, physicsClientId=cid)
        R = np.array(pybullet.getMatrixFromQuaternion(q)).reshape(3, 3)
        cables = self.cables
        n = cables.n
        wind = self.wind
        wind_on = with_wind and wind is not None and wind.U > 0.0
        if wind_on:
            block, j, block2, j2, frac = wind.turbulence_columns(t)
            params = self._wind_params
            params[6] = frac
            params[7] = wind._gust(t)
            r_cp = R @ wind.r_cp
        else:
            block = block2 = self._no_block
            j = j2 = 0
            params = r_cp = self._wind_params
        return (self.winch_cmd, self.winch_rate_cmd, t - self.winch_cmd_time,
                self.winch_speed * self.dt, self.dt, self.unstretched, cables.attach @ R.T,
                cables.anchors, cables.anchor_mask, np.array(pos), np.array(lin),
                np.array(ang), cables.EA, cables.damping, wind_on, params, block, j, block2,
                j2, r_cp, self.leg_cmd, self.leg_rate_cmd, t - self.leg_cmd_time,
                self.geom.leg_min, self.geom.leg_max, self.nominal_lengths,
                np.empty(27 + 4 * n), np.empty(n, bool)), pos

    def compile_step(self) -> None:
        """Compile the step's numba kernels now (or load them from numba's disk cache), by
        calls whose results are thrown away: the plant's state does not change.

        A process compiles them at the first call, or loads them from the cache; from an
        empty cache that takes some seconds. A simulator node calls this while it starts,
        before its controllers wait on it, so that no physics step of a run stalls for the
        compiler. The wind model is
        not asked (its generator's draws stay in the order of a run without this call).
        """
        if self._kernel is not None:
            self._kernel(*self._kernel_arguments(with_wind=False)[0])
        trolley = self.trolley_pose()
        self.cables.length_rates(*trolley, *self.trolley_velocity())

    def _step_numpy(self) -> None:
        """:meth:`step` in numpy (cables through ``CableSystem.wrench``, wind through
        ``WindModel.wrench``): the path without numba and the compiled step's reference."""
        cid = self._cid
        dt = self.dt
        # Winches: unstretched length follows the command at most at the speed limit.
        goal = self.winch_cmd + self.winch_rate_cmd * (self.t - self.winch_cmd_time)
        # np.clip's result, without its call overhead (1000 calls per sim s).
        step = np.minimum(np.maximum(goal - self.unstretched, -self.winch_speed * dt),
                          self.winch_speed * dt)
        self.unstretched = self.unstretched + step
        rates = step / dt
        pos, q = pybullet.getBasePositionAndOrientation(self.body, physicsClientId=cid)
        lin, ang = pybullet.getBaseVelocity(self.body, physicsClientId=cid)
        R = np.array(pybullet.getMatrixFromQuaternion(q)).reshape(3, 3)
        f, tq, tens, lengths, slack = self.cables.wrench(np.array(pos), R, np.array(lin),
                                                         np.array(ang), self.unstretched, rates)
        self.last_tensions, self.last_lengths, self.slack = tens, lengths, slack
        self.tension_range = (float(tens.min()), float(tens.max()))
        self.slack_count = int(np.count_nonzero(slack))
        self.winch_rates = rates
        if self.wind is not None:
            wf, wt = self.wind.wrench(self.t, R)
            self.wind_force, self.wind_torque = wf, wt
            f = f + wf
            tq = tq + wt
        pybullet.applyExternalForce(self.body, -1, f.tolist(), pos, pybullet.WORLD_FRAME,
                                    physicsClientId=cid)
        pybullet.applyExternalTorque(self.body, -1, tq.tolist(), pybullet.WORLD_FRAME,
                                     physicsClientId=cid)
        self.apply_commands(self.t - self.leg_cmd_time)
        pybullet.stepSimulation(physicsClientId=cid)
        self.t += dt

    # ------------------------------------------------------------------ state
    # The state reads below run once per publish period each: PyBullet's functions with the
    # client id, not through ``BulletClient`` (which builds a partial at every attribute read).
    def trolley_pose(self) -> tuple[np.ndarray, np.ndarray]:
        pos, q = pybullet.getBasePositionAndOrientation(self.body, physicsClientId=self._cid)
        return np.array(pos), _matrix(q)

    def trolley_velocity(self) -> tuple[np.ndarray, np.ndarray]:
        lin, ang = pybullet.getBaseVelocity(self.body, physicsClientId=self._cid)
        return np.array(lin), np.array(ang)

    def upper_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Upper platform centre and orientation (world)."""
        st = pybullet.getLinkState(self.body, self.UPPER, computeForwardKinematics=True,
                                   physicsClientId=self._cid)
        R = _matrix(st[5])
        return np.array(st[4]) - self.chain.upper_offset * R[:, 2], R

    def feed_pose(self) -> tuple[np.ndarray, np.ndarray]:
        pos, q = pybullet.getBasePositionAndOrientation(self.feed, physicsClientId=self._cid)
        return np.array(pos), _matrix(q)

    def hinge_angles(self) -> np.ndarray:
        return np.array([s[0] for s in pybullet.getJointStates(
            self.body, [self.RING, self.UPPER], physicsClientId=self._cid)])

    def leg_lengths(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Leg lengths from the prismatic joints (the actuators' encoders), rates and forces."""
        states = pybullet.getJointStates(self.body, self.ROD, physicsClientId=self._cid)
        q = np.array([s[0] for s in states]) + self.nominal_lengths
        v = np.array([s[1] for s in states])
        f = self.leg_force.copy() if self.force_drive else np.array([s[3] for s in states])
        return q, v, f

    def leg_lengths_geometric(self) -> np.ndarray:
        """Leg lengths between the joint centres of the two platforms (for checking)."""
        up, Ru = self.upper_pose()
        fp, Rf = self.feed_pose()
        rel_p = Ru.T @ (fp - up)
        return inverse_kinematics(self.geom, rel_p, Ru.T @ Rf)

    def nominal_upper(self, alpha: float, beta: float) -> np.ndarray:
        """Upper platform rotation relative to a level trolley for hinge angles."""
        return hinge_rotation(alpha, beta)


def make_client() -> BulletClient:
    """A headless PyBullet client (DIRECT) with z-up gravity."""
    from pybullet_utils.bullet_client import BulletClient
    client = BulletClient(connection_mode=pybullet.DIRECT)
    client.setGravity(0.0, 0.0, -9.81)
    return client


def angle_deg(R_a: ArrayLike, R_b: ArrayLike) -> float:
    """Angle (deg) of the rotation between two orientations."""
    c = (np.trace(np.asarray(R_a).T @ np.asarray(R_b)) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))
