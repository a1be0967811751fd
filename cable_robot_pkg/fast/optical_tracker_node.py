"""fast_tracker: optical trackers of the trolley, upper platform and feed (terminal feedback).

The FAST field model closes its loops on optical measurements of the trolley and of the feed
(Lu, Zhu, Ren: "direct terminal feedback from the optical sensors"). This simulated sensor
reads the simulator's ground truth (it is a sensor model, so truth is its input) and, at
``rate`` Hz of sim time, captures each body's pose, adds Gaussian noise (``noise_position`` m
per axis, ``noise_orientation_deg`` per axis as a small rotation) and publishes it
``latency`` seconds later on ``/fast/tracker/{trolley,upper_platform,feed}``
(geometry_msgs/PoseStamped, ``map``). ``header.stamp`` is the *capture* time, as a real
tracker's timestamp, so a consumer can measure and compensate the delay.

Faults: ``dropout_probability`` drops single frames; ``dropout_start``/``dropout_duration``
(sim seconds) blank every body for a window (line of sight lost); ``nan_probability`` sends a
frame of NaNs (a failed fit). The sensor is clocked by the ground-truth stream (capture on the
first truth sample at or after each ``1/rate`` tick), so latency resolution is the simulator's
publish period, and the sensor captures at most once per period: the nodes' defaults are
200 Hz and 5 ms (lock-step, ``paramotion fast``); ``launch/fast.launch.xml`` across processes
publishes every 10 ms and sets ``rate`` to 100 Hz (``tracker_rate``).
"""
import math
from collections import deque

import numpy as np
from geometry_msgs.msg import PoseStamped

from cable_robot_pkg.fast.ros_messages import TOPICS, pose_from_msg, pose_msg, stamp_seconds
from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import SENSOR_QOS, STATE_QOS
from paramotion.rotations import matrix_from_rotvec

BODIES = (('trolley', 'truth_trolley', 'tracker_trolley'),
          ('upper_platform', 'truth_upper', 'tracker_upper'),
          ('feed', 'truth_feed', 'tracker_feed'))


class OpticalTrackerNode(ParamotionNode):
    """Noisy, delayed, sometimes missing pose measurements of the three bodies."""

    PARAMS = (
        Param('rate', 200.0, 'Capture rate (Hz, sim time).', min=1.0, max=2000.0,
              read_only=True),
        Param('latency', 0.02, 'Delay from capture to publication (s).', min=0.0, max=0.2),
        Param('noise_position', 0.001, 'Position noise, 1 sigma per axis (m).', min=0.0,
              max=0.1),
        Param('noise_orientation_deg', 0.01, 'Orientation noise, 1 sigma per axis (deg).',
              min=0.0, max=5.0),
        Param('dropout_probability', 0.0, 'Probability that a frame is lost.', min=0.0,
              max=1.0),
        Param('dropout_start', -1.0, 'Start of a total dropout window (sim s; < 0: none).',
              min=-1.0, max=1e6),
        Param('dropout_duration', 0.0, 'Length of the dropout window (s).', min=0.0,
              max=1e6),
        Param('nan_probability', 0.0, 'Probability that a frame is all NaN.', min=0.0,
              max=1.0),
        Param('seed', 1, 'Seed of the noise generator.', min=0, max=2 ** 31 - 1,
              read_only=True),
        Param('offset', [0.0, 0.0, 0.0], 'Calibration offset added to every measured '
              'position, map frame (m): an injected tracker error.', read_only=True),
    )

    def __init__(self, node_name='fast_tracker', **kwargs):
        super().__init__(node_name, **kwargs)
        self.rng = np.random.default_rng(self.params.seed)
        self.offset = np.asarray(self.params.offset, float)
        self.truth = {}
        self.last_capture = {}
        self.queue = deque()
        self.published = 0
        self.dropped = 0
        self.pubs = {}
        for body, truth_key, out_key in BODIES:
            self.create_subscription(PoseStamped, TOPICS[truth_key],
                                     lambda m, b=body: self._on_truth(b, m), STATE_QOS)
            self.pubs[body] = self.create_publisher(PoseStamped, TOPICS[out_key], SENSOR_QOS)
        self.out = {body: PoseStamped() for body, _, _ in BODIES}   # refilled (publish copies)
        self.next_capture = 0.0

    def check_params(self, values):
        offset = values['offset']
        if len(offset) != 3 or not all(math.isfinite(x) for x in offset):
            return f"parameter 'offset' = {list(offset)} must be 3 finite numbers (m)"
        return None

    def _on_truth(self, body, msg):
        """Event-driven sensor: the camera frame clock is the truth stream's sim time, so
        capture and release happen exactly when due (a timer callback could lag a period)."""
        self.truth[body] = msg
        if body != BODIES[-1][0]:
            return
        t = stamp_seconds(msg.header.stamp)
        if t + 1e-9 >= self.next_capture:
            self.next_capture = t + 1.0 / self.params.rate - 1e-9
            self._tick(t)
        else:
            self._release(t)

    def _in_window(self, t):
        p = self.params
        return p.dropout_start >= 0.0 and p.dropout_start <= t < p.dropout_start + \
            p.dropout_duration

    def _tick(self, now):
        p = self.params
        sig_r = math.radians(p.noise_orientation_deg)
        # The generator's stream and arithmetic of ``normal(0, sigma, 3)`` twice and
        # ``random()`` twice per body (``loc + scale * standard normal``), in two calls.
        sig_p = p.noise_position
        scale = np.array([sig_p, sig_p, sig_p, sig_r, sig_r, sig_r])
        for body, _, _ in BODIES:
            msg = self.truth.get(body)
            if msg is None:
                continue
            t_cap = stamp_seconds(msg.header.stamp)
            # Draw every random number every time: the noise does not depend on the faults.
            d = 0.0 + scale * self.rng.standard_normal(6)
            dn, dr = d[:3], d[3:]
            u = self.rng.random(2)
            drop = u[0] < p.dropout_probability
            nan = u[1] < p.nan_probability
            if self.last_capture.get(body) == t_cap:
                continue   # this truth sample was already captured
            self.last_capture[body] = t_cap
            position, rotation = pose_from_msg(msg)
            if drop or self._in_window(t_cap):
                self.dropped += 1
                continue
            if nan:
                position = np.full(3, np.nan)
                rotation = np.full((3, 3), np.nan)
            else:
                position = position + dn + self.offset
                rotation = matrix_from_rotvec(dr) @ rotation
            self.queue.append((t_cap + p.latency, body, msg.header.stamp, position, rotation))
        self._release(now)

    def _release(self, now):
        while self.queue and self.queue[0][0] <= now + 1e-9:
            _, body, stamp, position, rotation = self.queue.popleft()
            if np.isfinite(rotation).all():
                out = pose_msg(stamp, 'map', position, rotation, msg=self.out[body])
            else:
                out = PoseStamped()
                out.header.stamp = stamp
                out.header.frame_id = 'map'
                out.pose.position.x = out.pose.position.y = out.pose.position.z = math.nan
                o = out.pose.orientation
                o.x = o.y = o.z = o.w = math.nan
            self.pubs[body].publish(out)
            self.published += 1


def main(args=None):
    run_node(OpticalTrackerNode, args)


if __name__ == '__main__':
    main()
