"""Gough-Stewart vibration isolation of the feed on the vibrating trolley (the fine loop).

Three controllers, selected by ``mode`` (``configuration.ISOLATION_MODES``):

``lu`` -- Lu, Zhu, Ren (Abstract): "standard proportional-integral-derivative controllers with
direct terminal feedback from the optical sensors". PID on the latest tracked feed error, in
velocity form on the commanded relative pose, as if the delayed measurement were current (no
capture stamps, no base model). A loop gain ``lu_ki`` with a delay ``tau`` loses stability
near ``lu_ki * tau ~ pi / 2``: the delay-induced instability the paper reports. The optional
cure ``lu_delay_limit`` schedules the integral gain down to ``lu_delay_limit / tau`` for the
measured latency ``tau``.

``cheng`` -- Cheng, Ren, Dai (Sec. I): "a simple control law of the prediction of the base
platform and proportional derivative (PD) feedback". The tracked base (upper platform) pose is
filtered by a constant-acceleration Kalman filter (:class:`PosePredictor`, fixed bandwidth) and
extrapolated with its velocity across the measured latency; the desired feed pose relative to
the predicted base, through the shared inverse kinematics, gives leg lengths and rates, and
the leg drives close the PD around them (:mod:`cable_robot_pkg.fast.plant`). No feed feedback.

Both ``cheng`` and ``predictive`` predict the *reaction-free* base (:func:`reaction_model`):
the platforms are dynamically coupled (Cheng et al.), so the legs' reaction forces move the
base, which the tracker sees again; a predictor of the measured base sits inside that loop and,
once the payload's inertia is comparable to the base's, drives it unstable. The leg forces are
internal to base + payload and change neither momentum, so the base pose minus the reaction
share ``K e`` of the payload's relative displacement ``e`` (leg encoders) moves with the
external forces only; the legs are then commanded ``(I - J K)^-1`` times the payload error
relative to that base. Mass properties come from the config.

``predictive`` -- the project's own: (1) three views of the base fused at the same capture
stamps (upper platform tracker; trolley tracker + hinge encoders; feed tracker + leg encoders
through the shared forward kinematics); (2) an adaptive least-squares multi-step predictor
(:class:`WienerPredictor`, ``predictor: wiener``) fitted every second to the last 20 s of the
fused base motion and evaluated at the measured latency, its peak gain bounded by
``peak_gain_max``; until it has 4 s of history (and with ``predictor: kalman``) the Kalman
predictor with second-order extrapolation and a bandwidth and compensation gain re-scheduled to
the measured latency (:func:`schedule_predictor`: ``g * max|H| <= peak_gain_max`` and no lag in
the trolley's ``vibration_band``, weighted by the measured base motion spectrum); (3) a slow
integral trim on the tracked feed error (gain ``trim_gain``, delay margin
``pi / (2 trim_gain)`` s) that removes steady offsets.

Why the peak-gain bound: extrapolating across the latency is a phase lead whose gain grows with
frequency and latency (:func:`predictor_response`); through the coupled platforms an unbounded
gain makes the trolley and upper platform oscillate against the feed at 14-19 Hz; a lagging
compensation is negative damping of the trolley's 0.3-2 Hz modes.

Ablations (``without``): ``prediction`` uses the latest base estimate at its capture time
(no extrapolation; ``lu`` has none to remove); ``reaction`` predicts the measured base instead
of the reaction-free one; ``tracker_feedback`` ignores every tracker frame and computes the legs
open loop from the trajectory (the base assumed at its commanded pose); ``isolation`` holds the
legs at their nominal lengths.

Faults: a base measurement that is not finite is dropped; when no valid base measurement has
arrived for ``dropout_timeout`` the controller *holds* the last leg command (zero rate) and
reports ``holding``; when measurements return it re-initialises the predictor and resumes.
"""
from __future__ import annotations

import bisect
import math
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from paramotion.gough_stewart import (
    GoughStewartGeometry,
    SingularPoseError,
    UnreachablePoseError,
    forward_kinematics,
    inverse_kinematics,
)
from paramotion.rotations import matrix_from_rotvec, rotvec_from_matrix

if TYPE_CHECKING:
    from cable_robot_pkg.fast.configuration import FastConfig
    from cable_robot_pkg.fast.focal_surface import FeedSupportChain

MODES = ('lu', 'cheng', 'predictive')
PREDICTORS = ('kalman', 'wiener')


def _transition(dt):
    """Constant-acceleration state transition for [p, v, a]."""
    return np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])


def _process_noise(q, dt):
    """Discrete process noise of a white-jerk model with spectral density ``q``."""
    d2, d3, d4, d5 = dt ** 2, dt ** 3, dt ** 4, dt ** 5
    return q * np.array([[d5 / 20, d4 / 8, d3 / 6], [d4 / 8, d3 / 3, d2 / 2],
                         [d3 / 6, d2 / 2, dt]])


def _detrend(t, x):
    """``x`` (n, m) minus its least-squares straight line in ``t``."""
    A = np.column_stack([np.ones_like(t), t - t[0]])
    coef, *_ = np.linalg.lstsq(A, x, rcond=None)
    return x - A @ coef


def steady_state_covariance(q: float, r: float, dt: float, tol: float = 1e-12,
                            max_iter: int = 60) -> np.ndarray:
    """A-priori covariance of the steady-state :class:`ConstantAccelerationKF` (one coordinate,
    position measured with variance ``r`` every ``dt``): the solution ``P`` of the discrete
    Riccati equation ``P = F P F^T - F P e1 (e1^T P e1 + r)^-1 e1^T P F^T + Q``, by the
    structure-preserving doubling algorithm (quadratic convergence, ~10 iterations of 3x3
    algebra; a general DARE solver is 100x slower here)."""
    return steady_state_covariances([q], r, dt, tol, max_iter)[0]


def steady_state_covariances(qs: ArrayLike, r: float, dt: float, tol: float = 1e-12,
                             max_iter: int = 60) -> np.ndarray:
    """:func:`steady_state_covariance` for each process noise in ``qs``, (len(qs), 3, 3).

    The doubling iterations of all of them run as stacked 3x3 products and inverses (numpy
    takes each matrix of a stack through the same LAPACK/BLAS call as a lone one), each
    stopping at its own convergence, so every result equals its own lone run bit for bit;
    the predictor schedule asks for 32 of them at a time."""
    qs = np.asarray(qs, float).reshape(-1)
    A = np.repeat(_transition(dt).T[None], len(qs), axis=0)
    G = np.zeros((len(qs), 3, 3))
    G[:, 0, 0] = 1.0 / r
    H = np.stack([_process_noise(q, dt) for q in qs])
    eye = np.eye(3)
    active = np.arange(len(qs))       # the ones not converged yet
    for _ in range(max_iter):
        a, g, h = A[active], G[active], H[active]
        W = np.linalg.inv(eye + g @ h)
        a_t = np.swapaxes(a, 1, 2)
        A[active], G[active], h_next = a @ W @ a, g + a @ W @ g @ a_t, h + a_t @ h @ W @ a
        done = np.abs(h_next - h).max(axis=(1, 2)) <= tol * np.abs(h_next).max(axis=(1, 2))
        H[active] = h_next
        active = active[~done]
        if not active.size:
            break
    return H


def predictor_response(q: float, r: float, dt: float, horizon: float,
                       freqs: ArrayLike) -> np.ndarray:
    """Frequency response of the steady-state :class:`ConstantAccelerationKF` used as a
    predictor: measurements of a signal ``s`` sampled every ``dt`` and fused with noise
    variance ``r``, state extrapolated ``horizon`` seconds past the newest sample (the tracker
    latency). Returns complex ``H(f)`` = predicted value / true current value of a sinusoid at
    each frequency in ``freqs`` (Hz): 1 is perfect compensation, ``|1 - H|`` is the residual
    share of that frequency, ``|H| > 1`` amplifies it.

    Extrapolating a filtered [p, v, a] estimate across a delay tau is a phase lead that grows
    with the frequency, and so does its gain: for the shipped rotation predictor the peak
    ``max |H|`` (near 14 Hz) is 4.2 at 20 ms, 6.2 at 30 ms and 11.7 at 50 ms of latency."""
    return predictor_responses([q], r, dt, horizon, freqs)[0]


def predictor_responses(qs: ArrayLike, r: float, dt: float, horizon: float,
                        freqs: ArrayLike) -> np.ndarray:
    """:func:`predictor_response` for each process noise in ``qs``, (len(qs), len(freqs)):
    the covariances by :func:`steady_state_covariances`, the linear solves of all of them in
    one stacked call (each matrix through the same LAPACK call as alone)."""
    F = _transition(dt)
    P = steady_state_covariances(qs, r, dt)
    K = P[:, :, 0] / (P[:, 0, 0] + r)[:, None]
    # np.outer(K, e1) is K[:, None] * e1[None, :]; each (I - K e1^T) F as its own product.
    A = (np.eye(3) - K[:, :, None] * np.array([1.0, 0.0, 0.0])[None, None, :]) @ F
    h = np.array([1.0, horizon, 0.5 * horizon * horizon])
    z = np.exp(2j * np.pi * np.asarray(freqs, float) * dt)
    delay = np.exp(-2j * np.pi * np.asarray(freqs, float) * horizon)
    # x_k = A x_{k-1} + K z_k  ->  X = (zI - A)^-1 z K Z; prediction h . X; delay e^{-jw tau}.
    M = z[None, :, None, None] * np.eye(3) - A[:, None]
    rhs = np.broadcast_to(K[:, None, :, None], (len(K), len(z), 3, 1))
    X = np.linalg.solve(M, rhs)[..., 0] * z[None, :, None]
    return np.stack([(x @ h) * delay for x in X])


def schedule_predictor(q_max: float, r: float, dt: float, horizon: float, peak_max: float,
                       band: tuple[float, float], n_q: int = 32,
                       spectrum: tuple[ArrayLike, ArrayLike] | None = None,
                       lag_tolerance: float = 1e-3) -> tuple[float, float, float]:
    """Process noise ``q`` (<= ``q_max``) and compensation gain ``g`` (<= 1) of the base
    predictor for a measured latency (``horizon``).

    The predicted base motion is fed to the legs; the legs' reaction forces move the base
    (the platforms are coupled, Cheng et al.) and the tracker sees that motion again, a loop
    whose gain at high frequency is ``c * g * |H(f)|`` (:func:`predictor_response`), ``c``
    the coupling of the structure. Measured in the simulator: the loop oscillates at 14-19
    Hz (trolley + upper platform rocking against the feed) once ``g * max |H|`` exceeds
    6.2-8.6, i.e. ``c`` ~ 0.12-0.16. The schedule therefore keeps ``g * max|H| <= peak_max`` and,
    under that bound, minimises the residual base motion ``sum S(f) |1 - g H(f)|^2`` over
    the trolley's vibration ``band`` (Hz) -- ``S`` the measured base motion spectrum
    ``spectrum = (freqs, power)`` when given, else flat -- by choosing the predictor
    bandwidth (``q``) and the compensation gain (``g``) together.
    Returns ``(q, g, g * max|H|)``."""
    nyquist = 0.5 / dt
    if spectrum is not None:
        f_s, w = (np.asarray(a, float) for a in spectrum)
        inside = (f_s >= band[0]) & (f_s <= band[1])
        f_band, w = f_s[inside], w[inside]
    else:
        f_band, w = np.linspace(band[0], band[1], 24), np.ones(24)
    if len(f_band) == 0 or not np.sum(w) > 0:
        f_band, w = np.linspace(band[0], band[1], 24), np.ones(24)
    w = w / np.sum(w)
    f_check = np.linspace(band[0], band[1], 24)
    freqs = np.concatenate([f_band, f_check, np.geomspace(max(band[1], 0.1), nyquist, 160)])
    n_band = len(f_band)
    best = None
    qs = q_max * np.logspace(0.0, -12.0, n_q)
    for q, H in zip(qs, predictor_responses(qs, r, dt, horizon, freqs)):
        Hb = H[:n_band]
        if np.min(np.imag(H[:n_band + len(f_check)])) < -lag_tolerance:
            continue      # lags somewhere in the band: negative damping of a trolley mode
        peak = float(np.abs(H).max())
        g = float(np.real(np.sum(w * np.conj(Hb))) / max(np.sum(w * np.abs(Hb) ** 2), 1e-12))
        g = min(max(g, 0.0), 1.0, peak_max / peak)
        cost = float(np.sum(w * np.abs(1.0 - g * Hb) ** 2))
        if best is None or cost < best[0] - 1e-12:
            best = (cost, float(q), g, g * peak)
    if best is None:          # no predictor bandwidth leads everywhere: compensate nothing
        return float(q_max), 0.0, 0.0
    return best[1:]


def _finite(position: np.ndarray, rotation: np.ndarray) -> bool:
    """Every element of a float position and rotation is finite (``np.isfinite(a).all()``
    of both, on Python floats: 1 instead of 4 us for a pose's 12 numbers)."""
    isfinite = math.isfinite
    return all(map(isfinite, position.ravel().tolist())) \
        and all(map(isfinite, rotation.ravel().tolist()))


def _remember(cache, key, value, size=512):
    """``value`` stored in ``cache`` under ``key`` (the cache emptied when full); its arrays
    are made read-only, since later lookups hand out the same objects."""
    if len(cache) >= size:
        cache.clear()
    for a in value if isinstance(value, tuple) else (value,):
        a.setflags(write=False)
    cache[key] = value
    return value


class ConstantAccelerationKF:
    """Kalman filter for m independent coordinates sharing one [p, v, a] model and noise."""

    def __init__(self, m: int, process_noise: float, measurement_std: float):
        self.m = m
        self.q = float(process_noise)
        self.r = float(measurement_std) ** 2
        self.x = np.zeros((3, m))
        self.P = np.diag([1.0, 1.0, 1.0])
        self.t = None
        self._models = {}         # (dt, q) -> (F, Q), see _model
        self._extrapolations = {}  # (dt, order) -> F, see predict
        # The covariance does not depend on the measurements: from a given P, a step of dt
        # with noise q and a fused measurement of variance r always give the same P and
        # gain. Steps on the tracker's frame grid revisit the same covariances (about two
        # updates in three), so each step's result is kept by its input (see update).
        self._predicted = {}      # (P bytes, dt, q) -> F P F^T + Q
        self._fused = {}          # (P bytes, r) -> (gain column K[:, None], P after fusing)

    def reset(self, t: float, z: ArrayLike) -> None:
        """Start at measurement ``z`` (m,) at time ``t`` with unknown rates."""
        self.x = np.zeros((3, self.m))
        self.x[0] = z
        self.P = np.diag([self.r, 1.0, 100.0])
        self.t = t

    def update(self, t: float, z: ArrayLike) -> None:
        """Predict to ``t`` and fuse measurement ``z`` (m,)."""
        dt = t - self.t
        P = self.P
        if dt > 0:
            F, Q = self._model(dt)
            self.x = F @ self.x
            key = (P.tobytes(), dt, self.q)
            P = self._predicted.get(key)
            if P is None:
                P = _remember(self._predicted, key, F @ self.P @ F.T + Q)
            self.t = t
        key = (P.tobytes(), self.r)
        fused = self._fused.get(key)
        if fused is None:
            S = P[0, 0] + self.r
            K = P[:, 0] / S
            Kc = K[:, None]          # np.outer(K, v) is K[:, None] * v[None, :]
            fused = _remember(self._fused, key, (Kc, P - Kc * P[0][None, :]))
        Kc, self.P = fused
        self.x = self.x + Kc * (np.asarray(z) - self.x[0])[None, :]

    def _model(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Transition and process noise for a step of ``dt``, kept per (dt, q): measurements
        come on the tracker's frame grid, whose stamp differences take a few dozen values."""
        key = (dt, self.q)
        model = self._models.get(key)
        if model is None:
            if len(self._models) >= 256:
                self._models.clear()
            model = self._models[key] = (_transition(dt), _process_noise(self.q, dt))
        return model

    def predict(self, t: float, order: int = 2) -> np.ndarray:
        """State [p, v, a] (3, m) extrapolated to time ``t`` (no update); ``order`` 1
        extrapolates with the velocity only."""
        key = (t - self.t, order)
        F = self._extrapolations.get(key)      # a few dozen horizons recur (frame grid)
        if F is None:
            if len(self._extrapolations) >= 256:
                self._extrapolations.clear()
            F = _transition(key[0])
            if order < 2:
                F[0, 2] = F[1, 2] = 0.0
            self._extrapolations[key] = F
        return F @ self.x


class WienerPredictor:
    """Adaptive multi-step linear predictor of a sampled vector signal, fitted by least squares
    (a finite-impulse-response Wiener predictor, one per coordinate).

    The value ``n`` frames ahead of the newest frame ``z_j`` is predicted as
    ``z_j + sum_l w_l (z_{j - l s} - z_j)`` (``l = 1 .. taps - 1``, lag spacing ``s`` frames),
    the weights ``w`` minimising the squared prediction error over the last ``window`` s of
    the signal itself (refitted every ``refit`` s). Why: the base's vibration is dominated by
    lightly damped modes of the cable-suspended trolley whose frequencies depend on the pose
    and the wind; a predictor fitted to the measured motion extrapolates such oscillations
    across the tracker latency far better than a polynomial ([p, v, a]) extrapolation, whose
    error grows with (2 pi f tau)^3, and it accounts for the measurement noise by itself (the
    least-squares weights are the Wiener weights for the measured spectrum). The differences
    to ``z_j`` make the predictor exact for a constant signal.

    Frames are on a regular grid of ``period`` s (the tracker's); a frame with the stamp of the
    newest one updates it (mean of several views of the same body); a gap of up to ``max_gap``
    frames is bridged by linear interpolation, a longer one restarts the history.

    ``peak_max`` bounds each coordinate's ``max_f |H(f)|`` (:meth:`_bounded`): the predicted
    base motion drives the legs, whose reaction moves the base again (Cheng et al.'s coupled
    platforms), a loop that a predictor with a large high-frequency gain destabilises
    (:func:`schedule_predictor` bounds the Kalman predictor the same way)."""

    def __init__(self, m: int, period: float, taps: int = 16, spacing: int = 2,
                 window: float = 20.0, refit: float = 1.0, min_span: float = 4.0,
                 max_gap: int = 4, peak_max: float = math.inf):
        self.m = int(m)
        self.period = float(period)
        self.taps = int(taps)
        self.spacing = int(spacing)
        self.capacity = int(round(window / period)) + self.taps * self.spacing + 64
        self.refit = float(refit)
        self.min_frames = int(round(min_span / period))
        self.max_gap = int(max_gap)
        self._buf = np.zeros((2 * self.capacity, self.m))   # history, oldest first
        self._n = 0                    # rows of _buf in use
        self.last_stamp = None
        self.count = 0                 # views averaged into the newest frame
        self.weights = {}              # horizon (frames) -> (m, taps - 1) weights
        self.peaks = {}                # horizon -> (m,) max |H(f)| of the fitted weights
        self.peak_max = float(peak_max)
        freqs = np.geomspace(0.05, 0.5 / self.period, 240)
        lags = self.spacing * np.arange(1, self.taps)
        self._lag_phasors = np.exp(-2j * np.pi * lags[:, None] * freqs[None, :] * self.period) \
            - 1.0                      # (taps - 1, freqs): H(f) = 1 + w . this
        self.wanted = set()            # horizons asked for since the last fit
        self.fit_stamp = None
        self._lag_rows = self.spacing * np.arange(1, self.taps)
        # Values computed once per state and asked for several times per control update:
        # the predictions per horizon (until the history or the weights change) and the peak.
        self._version = 0              # counts changes of the history and of the weights
        self._predictions = (-1, {})   # (version, {horizon: predicted value})
        self._peak = None              # (groups, peak) of the current weights

    def _changed(self):
        self._version += 1

    def reset(self) -> None:
        """Forget the history and the fitted weights (a dropout or a new chart)."""
        self._n = 0
        self.last_stamp = None
        self.weights = {}
        self.peaks = {}
        self.fit_stamp = None
        self._peak = None
        self._changed()

    def add(self, stamp: float, value: ArrayLike) -> None:
        """Fuse ``value`` (m,) captured at ``stamp``."""
        value = np.asarray(value, float)
        self._changed()
        if self.last_stamp is not None:
            gap = (stamp - self.last_stamp) / self.period
            if abs(gap) < 0.25:               # another view of the newest frame
                self.count += 1
                self._buf[self._n - 1] += (value - self._buf[self._n - 1]) / self.count
                return
            steps = int(round(gap))
            if steps < 1:
                return
            if steps > self.max_gap or abs(gap - steps) > 0.25:
                self.reset()
            else:
                last = self._buf[self._n - 1].copy()
                for k in range(1, steps):
                    self._append(last + k / steps * (value - last))
        self._append(value)
        self.count = 1
        self.last_stamp = stamp

    def _append(self, value):
        if self._n == len(self._buf):          # keep the newest ``capacity`` rows
            self._buf[:self.capacity] = self._buf[self._n - self.capacity:self._n]
            self._n = self.capacity
        self._buf[self._n] = value
        self._n += 1

    @property
    def history(self) -> np.ndarray:
        """The stored frames (n, m), oldest first (at most ``window`` s and the taps)."""
        return self._buf[max(0, self._n - self.capacity):self._n]

    @property
    def ready(self) -> bool:
        """True once the weights for some horizon are fitted."""
        return bool(self.weights)

    def _regressors(self, z, start, stop):
        """(m, stop - start, taps - 1): lagged differences to the frames start .. stop - 1."""
        X = np.empty((self.m, stop - start, self.taps - 1))
        for i in range(1, self.taps):
            lag = self.spacing * i
            X[:, :, i - 1] = (z[start - lag:stop - lag] - z[start:stop]).T
        return X

    def fit(self, horizons: Iterable[int]) -> bool:
        """Least-squares weights for each horizon (frames) on the stored history."""
        z = self.history
        first = self.spacing * (self.taps - 1)
        horizons = sorted({int(h) for h in horizons if h > 0})
        if len(z) < self.min_frames or not horizons:
            return False
        stop = len(z) - max(horizons)
        if stop - first < 4 * self.taps:
            return False
        X = self._regressors(z, first, stop)
        Xt = np.transpose(X, (0, 2, 1))
        XtX = Xt @ X
        ridge = 1e-9 * np.trace(XtX, axis1=1, axis2=2)[:, None, None] * np.eye(self.taps - 1)
        XtX = XtX + ridge + 1e-30 * np.eye(self.taps - 1)
        for h in horizons:
            y = np.ascontiguousarray((z[first + h:stop + h] - z[first:stop]).T)  # (m, K)
            Xty = (Xt @ y[..., None])[..., 0]
            w = np.linalg.solve(XtX, Xty[..., None])[..., 0]
            peaks = self._peaks(w)
            for a in np.flatnonzero(peaks > self.peak_max):
                w[a], peaks[a] = self._bounded(XtX[a], Xty[a])
            self.weights[h], self.peaks[h] = w, peaks
        self.fit_stamp = self.last_stamp
        self._peak = None
        self._changed()
        return True

    def _peaks(self, w):
        """``max_f |H(f)|`` of weights ``w`` (..., taps - 1) (the delay has unit gain)."""
        return np.abs(1.0 + w @ self._lag_phasors).max(axis=-1)

    def _bounded(self, XtX, Xty, iterations=14):
        """Weights of one coordinate whose peak gain stays under ``peak_max``: the
        least-squares fit with white measurement noise of variance ``lam`` added to the
        regressors (``XtX + lam K (I + 1 1^T)``, the covariance of lagged differences of white
        noise), ``lam`` the smallest that meets the bound (bisection in log scale). More
        assumed noise makes the Wiener weights trade in-band prediction for less high-frequency
        gain; with no bound reachable the predictor tends to holding the latest sample."""
        p = len(Xty)
        noise = np.eye(p) + np.ones((p, p))
        scale = np.trace(XtX) / p
        lo, hi = -9.0, 2.0
        best = None
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            w = np.linalg.solve(XtX + 10.0 ** mid * scale * noise, Xty)
            peak = float(self._peaks(w))
            if peak <= self.peak_max:
                hi, best = mid, (w, peak)
            else:
                lo = mid
        if best is None:
            w = np.linalg.solve(XtX + 10.0 ** hi * scale * noise, Xty)
            best = (w, float(self._peaks(w)))
        return best

    def peak(self, groups: int = 2) -> np.ndarray:
        """Largest ``max_f |H(f)|`` (:meth:`response`, 0.05 Hz to Nyquist) over the fitted
        horizons, per group of ``m / groups`` coordinates (position, rotation)."""
        if not self.peaks:
            return np.ones(groups)
        if self._peak is None or self._peak[0] != groups:
            p = np.max(np.stack(list(self.peaks.values())), axis=0)
            self._peak = (groups, p.reshape(groups, -1).max(axis=1))
        return self._peak[1].copy()

    def response(self, horizon: int, freqs: ArrayLike) -> np.ndarray:
        """Complex frequency response (m, len(freqs)) of the fitted predictor including the
        ``horizon`` frames of delay it compensates: 1 is perfect prediction."""
        w = self.weights[horizon]
        f = np.asarray(freqs, float)
        lags = self.spacing * np.arange(1, self.taps)
        e = np.exp(-2j * np.pi * f[None, :] * lags[:, None] * self.period) - 1.0
        return (1.0 + w @ e) * np.exp(-2j * np.pi * f * horizon * self.period)[None, :]

    def predict(self, t: float) -> np.ndarray | None:
        """Predicted value at ``t`` (None until fitted): linear between the two integer
        horizons around ``t - last_stamp``; refits when ``refit`` s have passed."""
        if self.last_stamp is None or not self._n:
            return None
        h = max((t - self.last_stamp) / self.period, 0.0)
        n0 = int(math.floor(h + 1e-6))
        frac = h - n0 if h - n0 > 1e-6 else 0.0
        need = [n for n in (n0, n0 + 1 if frac > 0 else n0) if n > 0]
        self.wanted.update(need)
        due = self.fit_stamp is None or self.last_stamp - self.fit_stamp >= self.refit
        if due or any(n not in self.weights for n in need):
            if min(self._n, self.capacity) >= self.min_frames:   # else fit refuses at once
                self.fit(self.wanted | set(need))
            self.wanted = set(need)
        if any(n not in self.weights for n in need):
            return None
        if self._n <= self.spacing * (self.taps - 1):
            return None
        if self._predictions[0] != self._version:
            self._predictions = (self._version, {})
        known = self._predictions[1]
        last = self._buf[self._n - 1]
        out = []
        for n in (n0, n0 + 1):
            if n == 0:
                out.append(last)
            elif n in known:
                out.append(known[n])
            elif n in self.weights:
                r = known.get('r')
                if r is None:
                    r = known['r'] = (self._buf[self._n - 1 - self._lag_rows] - last).T
                known[n] = last + np.sum(self.weights[n] * r, axis=1)     # r: (m, taps - 1)
                out.append(known[n])
            else:
                out.append(None)
        if frac == 0.0 or out[1] is None:
            return out[0]
        return (1.0 - frac) * out[0] + frac * out[1]


class PosePredictor:
    """Predicts a tracked rigid body's pose forward from stamped, delayed measurements."""

    def __init__(self, process_noise: float, process_noise_rotation: float,
                 position_std: float, rotation_std: float, reset_gap: float = 0.5):
        self.pos = ConstantAccelerationKF(3, process_noise, max(position_std, 1e-6))
        self.rot = ConstantAccelerationKF(3, process_noise_rotation, max(rotation_std, 1e-7))
        self.R_ref = None
        self.last_stamp = None
        self.reset_gap = reset_gap

    @property
    def ready(self) -> bool:
        """True once a measurement has been fused."""
        return self.last_stamp is not None

    def add(self, stamp: float, position: ArrayLike, rotation: ArrayLike) -> bool:
        """Fuse a pose captured at ``stamp``; older or non-finite measurements are refused
        (returns False). Several measurements with the same stamp (the same body seen through
        different sensor chains) are all fused."""
        position = np.asarray(position, float)
        rotation = np.asarray(rotation, float)
        if not _finite(position, rotation):
            return False
        if self.last_stamp is not None and stamp < self.last_stamp:
            return False
        if self.last_stamp is None or stamp - self.last_stamp > self.reset_gap:
            self.R_ref = rotation.copy()
            self.pos.reset(stamp, position)
            self.rot.reset(stamp, np.zeros(3))
        else:
            phi = rotvec_from_matrix(self.R_ref.T @ rotation)
            self.pos.update(stamp, position)
            self.rot.update(stamp, phi)
            chart = self.rot.x[0]
            if math.sqrt(chart.dot(chart)) > 0.2:     # np.linalg.norm's arithmetic
                # Re-anchor the rotation-vector chart so that it stays small.
                self.R_ref = self.R_ref @ matrix_from_rotvec(self.rot.x[0])
                self.rot.x[0] = 0.0
        self.last_stamp = stamp
        return True

    def predict(self, t: float, order: int = 2
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(position, rotation, velocity, angular velocity in the reference frame) at ``t``,
        extrapolated with [p, v, a] (``order`` 2) or with [p, v] only (``order`` 1)."""
        xp = self.pos.predict(t, order)
        xr = self.rot.predict(t, order)
        R = self.R_ref @ matrix_from_rotvec(xr[0])
        return xp[0], R, xp[1], self.R_ref @ xr[1]

    def predict_pose(self, t: float, order: int = 2) -> tuple[np.ndarray, np.ndarray]:
        """(position, rotation) of :meth:`predict`, without the rates the controller does not
        use (the same floats, two products fewer)."""
        xp = self.pos.predict(t, order)
        xr = self.rot.predict(t, order)
        return xp[0], self.R_ref @ matrix_from_rotvec(xr[0])


class TargetHistory:
    """Recent feed targets by time, so that a delayed measurement is compared with the target
    at its own capture time."""

    def __init__(self, horizon: float = 1.0):
        self.items = deque()
        self.times = deque()      # the items' times, for bisection while they increase
        self.ordered = True       # every time at or after the one before
        self.horizon = horizon
        self._velocity = (None, None, None)   # (newest item, velocity, angular velocity)

    def add(self, t: float, position: ArrayLike, rotation: ArrayLike) -> None:
        if self.items and t < self.items[-1][0]:
            self.ordered = False
        self.items.append((t, np.asarray(position, float), np.asarray(rotation, float)))
        self.times.append(t)
        while len(self.items) > 2 and self.items[-1][0] - self.items[0][0] > self.horizon:
            self.items.popleft()
            self.times.popleft()

    def latest(self) -> tuple[float, np.ndarray, np.ndarray] | None:
        return self.items[-1] if self.items else None

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray] | None:
        """Target (position, rotation) at ``t``: linear in position, nearest in rotation."""
        if not self.items:
            return None
        prev = self.items[0]
        if t <= prev[0]:
            return prev[1], prev[2]
        if self.ordered:
            # The first item at or after ``t`` and the one before it, found by bisection.
            k = bisect.bisect_left(self.times, t)
            if k < len(self.items):
                prev, item = self.items[k - 1], self.items[k]
                w = (t - prev[0]) / max(item[0] - prev[0], 1e-12)
                rot = item[2] if w > 0.5 else prev[2]
                return prev[1] + w * (item[1] - prev[1]), rot
        else:
            for item in self.items:
                if item[0] >= t:
                    w = (t - prev[0]) / max(item[0] - prev[0], 1e-12)
                    rot = item[2] if w > 0.5 else prev[2]
                    return prev[1] + w * (item[1] - prev[1]), rot
                prev = item
        last = self.items[-1]
        return last[1], last[2]

    def velocity(self) -> tuple[np.ndarray, np.ndarray]:
        """Finite-difference target velocity (3,) and angular velocity (3,), map frame (kept
        until the next target: the controller asks at twice the target rate)."""
        if len(self.items) < 2:
            return np.zeros(3), np.zeros(3)
        newest = self.items[-1]
        if self._velocity[0] is not newest:
            (t0, p0, R0), (t1, p1, R1) = self.items[-2], newest
            dt = max(t1 - t0, 1e-9)
            w = rotvec_from_matrix(R1 @ R0.T) / dt
            self._velocity = (newest, (p1 - p0) / dt, w)
        return self._velocity[1].copy(), self._velocity[2].copy()


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _box_inertia(m, size):
    x, y, z = (float(s) for s in size)
    return m / 12.0 * np.diag([y * y + z * z, x * x + z * z, x * x + y * y])


def _disc_inertia(m, r, h):
    return m * np.diag([(3 * r * r + h * h) / 12.0, (3 * r * r + h * h) / 12.0, r * r / 2.0])


def reaction_model(cfg: FastConfig) -> tuple[np.ndarray, np.ndarray]:
    """``(K, J)``, 6 x 6 each, in the upper platform (base) frame at the nominal pose.

    The leg forces are internal to base + payload: they change neither the pair's linear
    momentum nor its angular momentum. Linearised about the nominal pose, with ``x_b`` the
    base's small displacement (position, rotation vector) and ``e`` the payload's displacement
    relative to the base, both momenta integrate to ``Y = G x_b + H e``, which only the
    external forces (wind, cables) change. ``K = G^-1 H``: ``x_b + K e`` is the *reaction-free*
    base, the pose the base would have had if the legs had not moved. ``J`` maps a base
    displacement to the payload's when rigidly attached. Mass properties from the config:
    the trolley as a box, ring and upper platform at the hinge and platform centres, legs
    halfway between their anchors, the payload a disc at the nominal relative pose (the
    hinge rotation of the trolley's parts is neglected: at most the track's zenith)."""
    raw = cfg.raw
    g = raw['gough_stewart']
    chain = cfg.chain
    hinge = np.array([0.0, 0.0, chain.upper_offset])          # base frame: upper centre = 0
    p_nom, R_nom = chain.nominal_relative_pose()
    trolley_c = hinge - np.asarray(chain.hinge_offset, float)
    legs_c = 0.5 * (cfg.geometry.base_anchors + p_nom + cfg.geometry.platform_anchors @ R_nom.T)
    parts = [(raw['trolley']['mass'], trolley_c,
              _box_inertia(raw['trolley']['mass'], raw['trolley']['size'])),
             (raw['orienting']['ring_mass'], hinge, np.zeros((3, 3))),
             (g['upper_mass'], np.zeros(3),
              _disc_inertia(g['upper_mass'], g['base_radius'], 0.06))]
    parts += [(g['leg_mass'], c, np.zeros((3, 3))) for c in legs_c]
    m_b = sum(m for m, _, _ in parts)
    c_b = sum(m * c for m, c, _ in parts) / m_b
    I_b = sum(inertia + m * (np.dot(c - c_b, c - c_b) * np.eye(3) - np.outer(c - c_b, c - c_b))
              for m, c, inertia in parts)
    m_p = float(g['feed_mass'])
    I_p = _disc_inertia(m_p, g['platform_radius'], 0.06)
    centre = (m_b * c_b + m_p * p_nom) / (m_b + m_p)

    def momenta(x_b, e):
        """Integrated linear and angular momentum (about the fixed ``centre``)."""
        d_b, th_b = x_b[:3], x_b[3:]
        dc_b = d_b + np.cross(th_b, c_b)
        dx_p = d_b + np.cross(th_b, p_nom) + e[:3]
        lin = m_b * dc_b + m_p * dx_p
        ang = I_b @ th_b + I_p @ (th_b + e[3:]) + m_b * np.cross(c_b - centre, dc_b) \
            + m_p * np.cross(p_nom - centre, dx_p)
        return np.concatenate([lin, ang])

    eye = np.eye(6)
    G = np.column_stack([momenta(eye[k], np.zeros(6)) for k in range(6)])
    H = np.column_stack([momenta(np.zeros(6), eye[k]) for k in range(6)])
    J = np.eye(6)
    J[:3, 3:] = -_skew(p_nom)
    return np.linalg.solve(G, H), J


def pose_error(target_p: ArrayLike, target_R: ArrayLike, p: ArrayLike,
               R: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Position error (3,) and rotation-vector error (3,) target minus actual, map frame."""
    return (np.asarray(target_p) - np.asarray(p),
            rotvec_from_matrix(np.asarray(target_R) @ np.asarray(R).T))


class SampleHistory:
    """Encoder samples (time, vector) kept for ``horizon`` seconds, read at a past time."""

    def __init__(self, horizon: float = 0.5):
        self.times = deque()
        self.values = deque()
        self.horizon = horizon

    def add(self, t: float, value: ArrayLike) -> None:
        value = np.asarray(value, float)
        if not np.isfinite(value).all() or (self.times and t < self.times[-1]):
            return
        self.times.append(t)
        self.values.append(value)
        while len(self.times) > 2 and self.times[-1] - self.times[0] > self.horizon:
            self.times.popleft()
            self.values.popleft()

    def at(self, t: float, tolerance: float = 0.02) -> np.ndarray | None:
        """Linearly interpolated value at ``t`` (None when ``t`` is not covered)."""
        if not self.times or t < self.times[0] - tolerance or t > self.times[-1] + tolerance:
            return None
        times = self.times
        k = bisect.bisect_left(times, t)          # np.searchsorted's index (side 'left')
        if k <= 0:
            return self.values[0]
        if k >= len(times):
            return self.values[-1]
        w = (t - times[k - 1]) / max(times[k] - times[k - 1], 1e-12)
        return (1.0 - w) * self.values[k - 1] + w * self.values[k]


@dataclass
class LegCommand:
    """Output of one controller update."""

    lengths: np.ndarray
    rates: np.ndarray
    clipped: bool
    holding: bool


class IsolationController:
    """Leg commands that keep the feed at its target while the upper platform vibrates."""

    def __init__(self, geometry: GoughStewartGeometry,
                 nominal_relative: tuple[ArrayLike, ArrayLike],
                 mode: str = 'predictive', lead: float = 0.005, trim_gain: float = 1.5,
                 trim_limit: tuple[float, float] = (0.03, math.radians(0.5)), lu_kp: float = 0.3,
                 lu_ki: float = 40.0, lu_kd: float = 0.0, lu_delay_limit: float = 0.0,
                 stroke_margin: float = 0.005, dropout_timeout: float = 0.1,
                 process_noise: float = 20.0, process_noise_rotation: float = 10.0,
                 position_std: float = 0.001, rotation_std: float = math.radians(0.01),
                 peak_gain_max: float = 4.0, vibration_band: tuple[float, float] = (0.3, 2.0),
                 slow_time: float = 1.0, chain: FeedSupportChain | None = None,
                 fuse: bool = True, without: Iterable[str] = frozenset(),
                 predictor: str = 'wiener', wiener_taps: int = 16,
                 wiener_spacing: float = 0.01, wiener_window: float = 20.0,
                 reaction: tuple[ArrayLike, ArrayLike] | None = None):
        if mode not in MODES:
            raise ValueError(f'unknown isolation mode {mode!r}')
        if predictor not in PREDICTORS:
            raise ValueError(f'unknown base predictor {predictor!r}')
        self.geometry = geometry
        self.mode = mode
        self.without = frozenset(without)
        self.open_loop = 'tracker_feedback' in self.without
        self.predict_base = 'prediction' not in self.without
        # Reaction-free base (:func:`reaction_model`): the predictors see x_b + K e, e the
        # payload's displacement relative to the base from the leg encoders, and the legs
        # are commanded e = (I - J K)^-1 e0 for the payload error e0 relative to it.
        self.reaction = None
        if reaction is not None and mode != 'lu' and 'reaction' not in self.without:
            K, J = (np.asarray(a, float) for a in reaction)
            self.reaction = (K, np.linalg.inv(np.eye(6) - J @ K))
        self._fk_cache = (None, None)
        self._reaction_cache = (None, None, None)   # (FK solution, its K e: shift, rotation)
        if self.open_loop and chain is None:
            raise ValueError('without tracker_feedback needs the chain (trajectory -> base)')
        fuse = fuse and mode == 'predictive'
        self.lead = lead
        self.trim_gain = trim_gain
        self.trim_limit = trim_limit
        self.lu_kp, self.lu_ki, self.lu_kd = lu_kp, lu_ki, lu_kd
        self.lu_delay_limit = lu_delay_limit
        self.lu_derivative = np.zeros(6)
        self.lo = geometry.leg_min + stroke_margin
        self.hi = geometry.leg_max - stroke_margin
        self.timeout = dropout_timeout
        # A gap longer than the dropout timeout restarts the predictor (recovery).
        self.base = PosePredictor(process_noise, process_noise_rotation, position_std,
                                  rotation_std, reset_gap=dropout_timeout)
        self.targets = TargetHistory()
        self.nominal_p, self.nominal_R = (np.asarray(a, float) for a in nominal_relative)
        self.nominal_lengths = inverse_kinematics(geometry, self.nominal_p, self.nominal_R)
        self.trim = np.zeros(6)
        self._trim_R = (None, None)    # (trim rotation vector, its matrix)
        self.lu_cmd = np.concatenate([self.nominal_p, np.zeros(3)])
        self.lu_prev_error = None
        self.last_feed_time = None
        self.last_base_arrival = None
        self.last_base_R = None
        self.command = LegCommand(self.nominal_lengths.copy(), np.zeros(6), False, True)
        self.clip_count = 0
        self.hold_count = 0
        self.slow_time = slow_time
        self.latency = None
        # Latency-scheduled predictor (:func:`schedule_predictor`): process noise and
        # compensation gain per position / rotation, recomputed when the latency changes.
        self.q_max = (float(process_noise), float(process_noise_rotation))
        self.noise_var = (max(position_std, 1e-6) ** 2, max(rotation_std, 1e-7) ** 2)
        self.peak_gain_max = float(peak_gain_max)
        self.vibration_band = tuple(float(f) for f in vibration_band)
        self.period = None        # measured tracker frame period (s)
        self.views = 3.0 if fuse and chain is not None else 1.0   # measurements per frame
        self._frame = [None, 0]   # stamp and count of the frame being fused
        self._scheduled = None    # (horizon, period, views) of the current schedule
        self.gains = np.ones(2)   # compensation gain, position and rotation
        # Base motion history (one measurement per frame) for the measured vibration spectrum.
        self.spectrum_window = 20.0
        self.reschedule_period = 5.0
        self.history = deque()
        self._spectrum_time = None
        self.loop_peak = np.zeros(2)   # g * max|H| after scheduling
        self.slow = None          # (time, position, rotation) of the slow base reference
        # Sensor fusion: the upper platform is also seen through the trolley tracker + hinge
        # encoders and through the feed tracker + leg encoders (forward kinematics).
        self.chain = chain
        self.fuse = fuse
        self.hinges = SampleHistory()
        self.legs = SampleHistory()
        self.fk_guess = (self.nominal_p, self.nominal_R)
        # Adaptive least-squares predictor of the fused base pose (``predictive`` mode with
        # ``predictor: wiener``); the Kalman predictor above serves until it is fitted.
        self.use_wiener = mode == 'predictive' and predictor == 'wiener'
        self.wiener_taps = int(wiener_taps)
        self.wiener_spacing = float(wiener_spacing)
        self.wiener_window = float(wiener_window)
        self.wiener = None
        self.wiener_ref = None    # rotation the predictor's rotation vectors are relative to

    @classmethod
    def from_config(cls, cfg: FastConfig, mode: str | None = None,
                    without: Iterable[str] = ()) -> IsolationController:
        """Build from a validated :class:`~cable_robot_pkg.fast.configuration.FastConfig`
        (``mode`` None: the config's ``isolation.mode``; ``without``: ablation names)."""
        iso = cfg.raw['isolation']
        tr = cfg.raw['tracker']
        return cls(cfg.geometry, cfg.chain.nominal_relative_pose(),
                   mode=mode or iso['mode'], lead=iso['lead'], trim_gain=iso['trim_gain'],
                   lu_kp=iso['lu_kp'], lu_ki=iso['lu_ki'], lu_kd=iso['lu_kd'],
                   lu_delay_limit=iso['lu_delay_limit'],
                   stroke_margin=iso['stroke_margin'], dropout_timeout=iso['dropout_timeout'],
                   process_noise=iso['process_noise'],
                   process_noise_rotation=iso['process_noise_rotation'],
                   position_std=max(tr['noise_position'], 1e-4),
                   rotation_std=math.radians(max(tr['noise_orientation_deg'], 1e-3)),
                   peak_gain_max=iso['peak_gain_max'],
                   vibration_band=iso['vibration_band'], chain=cfg.chain, fuse=iso['fuse'],
                   without=frozenset(without), predictor=iso['predictor'],
                   wiener_taps=iso['wiener_taps'], wiener_spacing=iso['wiener_spacing'],
                   wiener_window=iso['wiener_window'], reaction=reaction_model(cfg))

    def compile_kernels(self) -> None:
        """Compile, or load from numba's disk cache, the forward kinematics kernel that the
        base views and the reaction-free base use, by one solve at the nominal pose whose
        result is thrown away (no state of the controller changes). A node calls it while it
        starts: otherwise the first tracker frame pays for it (about a second of CPU with a
        warm cache, more from an empty one) and a launched simulator waits for the answer."""
        if self.fuse or self.reaction is not None:
            try:
                forward_kinematics(self.geometry, self.nominal_lengths, self.nominal_p,
                                   self.nominal_R)
            except (SingularPoseError, UnreachablePoseError, ValueError):
                pass

    # ------------------------------------------------------------------ inputs
    def set_target(self, t: float, position: ArrayLike, rotation: ArrayLike) -> None:
        """New feed target (map frame) valid at time ``t``."""
        self.targets.add(t, position, rotation)

    def add_base(self, now: float, stamp: float, position: ArrayLike, rotation: ArrayLike) -> bool:
        """Tracked upper platform pose captured at ``stamp``, received at ``now``; the
        predictors see its reaction-free position (:meth:`_reaction_free`)."""
        position, rotation = self._reaction_free(stamp, position, rotation)
        if self.base.add(stamp, position, rotation):
            self.last_base_arrival = now
            self.last_base_R = np.asarray(rotation, float)
            delay = max(now - stamp, 0.0)
            self.latency = delay if self.latency is None else \
                self.latency + 0.05 * (delay - self.latency)
            frame_stamp, count = self._frame
            if frame_stamp is not None and stamp == frame_stamp:
                self._frame[1] += 1
            else:
                if frame_stamp is not None and stamp > frame_stamp:
                    gap = stamp - frame_stamp
                    if gap < self.timeout:
                        self.period = gap if self.period is None else \
                            self.period + 0.05 * (gap - self.period)
                    self.views += 0.05 * (count - self.views)
                self._frame = [stamp, 1]
                self._record(stamp, position, rotation)
            if self.use_wiener:
                self._wiener_add(stamp, position, rotation)
            return True
        return False

    def _wiener_add(self, stamp, position, rotation):
        """One view of the base into the least-squares predictor: position and rotation
        vector relative to ``wiener_ref`` (re-anchored, and the history restarted, when the
        base has turned more than 0.5 rad from it)."""
        if self.wiener is None:
            if self.period is None:
                return
            spacing = max(1, int(round(self.wiener_spacing / self.period)))
            self.wiener = WienerPredictor(6, self.period, self.wiener_taps, spacing,
                                          self.wiener_window, min_span=4.0,
                                          max_gap=max(1, int(self.timeout / self.period)),
                                          peak_max=self.peak_gain_max)
        rotation = np.asarray(rotation, float)
        phi = None if self.wiener_ref is None else \
            rotvec_from_matrix(self.wiener_ref.T @ rotation)
        if phi is None or math.sqrt(phi.dot(phi)) > 0.5:    # np.linalg.norm's arithmetic
            self.wiener_ref = rotation.copy()
            self.wiener.reset()
            phi = np.zeros(3)
        self.wiener.add(stamp, np.concatenate([np.asarray(position, float), phi]))

    def add_hinge_state(self, t: float, angles: ArrayLike) -> None:
        """Orienting-mechanism encoder angles (alpha, beta) at time ``t``."""
        self.hinges.add(t, angles)

    def add_leg_state(self, t: float, lengths: ArrayLike) -> None:
        """Leg encoder lengths at time ``t``."""
        self.legs.add(t, lengths)

    def add_trolley(self, now: float, stamp: float, position: ArrayLike,
                    rotation: ArrayLike) -> bool:
        """Tracked trolley pose: with the hinge angles at ``stamp`` it is one more
        measurement of the upper platform (chain kinematics)."""
        if not self.fuse or self.chain is None or self.mode != 'predictive':
            return False
        hinge = self.hinges.at(stamp)
        if hinge is None:
            return False
        p, R = self.chain.upper_pose(position, rotation, hinge[0], hinge[1])
        return self.add_base(now, stamp, p, R)

    def _legs_pose(self, stamp):
        """Feed pose relative to the upper platform at ``stamp`` from the leg encoders
        (forward kinematics of the shared Gough-Stewart module; one solve per stamp), or
        None."""
        if self._fk_cache[0] == stamp:
            return self._fk_cache[1]
        lengths = self.legs.at(stamp)
        fk = None
        if lengths is not None:
            g = self.geometry
            lengths = np.clip(lengths, g.leg_min + 1e-9, g.leg_max - 1e-9)
            try:
                fk = forward_kinematics(g, lengths, *self.fk_guess)
            except (SingularPoseError, UnreachablePoseError, ValueError):
                fk = None
            if fk is not None and fk.converged:
                self.fk_guess = (fk.position, fk.rotation)
            else:
                fk = None
        self._fk_cache = (stamp, fk)
        return fk

    def _reaction_free(self, stamp, position, rotation):
        """Base pose minus the part of its motion the legs' own reaction caused (Cheng et
        al.'s coupling): ``x_b + K e`` (:func:`reaction_model`), ``e`` the payload's pose
        relative to the base at ``stamp`` from the leg encoders. Leg forces are internal to
        base + payload, so at the vibration frequencies (above the cable suspension's) this
        pose moves only with wind and cables, and predicting it does not feed the legs'
        motion back into the legs (a positive feedback of gain ~ |K| |H| otherwise)."""
        position = np.asarray(position, float)
        rotation = np.asarray(rotation, float)
        if self.reaction is None:
            return position, rotation
        fk = self._legs_pose(stamp)
        if fk is None:
            return position, rotation
        if self._reaction_cache[0] is not fk:    # the views of one frame share its stamp
            e = np.concatenate([fk.position - self.nominal_p,
                                rotvec_from_matrix(fk.rotation @ self.nominal_R.T)])
            k = self.reaction[0] @ e                  # base frame
            self._reaction_cache = (fk, k[:3], matrix_from_rotvec(k[3:]))
        _, k_p, k_R = self._reaction_cache
        return position + rotation @ k_p, rotation @ k_R

    def _base_from_feed(self, stamp, position, rotation):
        """Upper platform pose from the tracked feed and the leg lengths at ``stamp``
        (forward kinematics of the shared Gough-Stewart module), or None."""
        fk = self._legs_pose(stamp)
        if fk is None:
            return None
        R_b = np.asarray(rotation) @ fk.rotation.T
        return np.asarray(position) - R_b @ fk.position, R_b

    @property
    def gain(self) -> float:
        """Smallest compensation gain in use (1 = the whole predicted base motion)."""
        return float(self.gains.min())

    def _record(self, stamp, position, rotation):
        if self.history and stamp - self.history[-1][0] > self.timeout:
            self.history.clear()      # a dropout: the spectrum restarts
        self.history.append((stamp, np.array(position, float), np.array(rotation, float)))
        while self.history and stamp - self.history[0][0] > self.spectrum_window:
            self.history.popleft()

    def base_spectra(
            self, min_span: float = 4.0
    ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]] | None:
        """Measured power spectra of the base position and rotation (Hann-windowed, linearly
        detrended periodogram of the last ``spectrum_window`` s of base measurements), as
        ``((freqs, power_position), (freqs, power_rotation))``; None with less than
        ``min_span`` s of history."""
        if len(self.history) < 16 or self.period is None:
            return None
        t = np.fromiter((h[0] for h in self.history), float)
        if t[-1] - t[0] < min_span:
            return None
        grid = np.arange(t[0], t[-1], self.period)
        p = np.stack([h[1] for h in self.history])
        R0 = self.history[-1][2]
        phi = np.stack([rotvec_from_matrix(R0.T @ h[2]) for h in self.history])
        window = np.hanning(len(grid))
        freqs = np.fft.rfftfreq(len(grid), self.period)
        out = []
        for x in (p, phi):
            x = np.stack([np.interp(grid, t, x[:, k]) for k in range(3)], 1)
            x = _detrend(grid, x)
            X = np.fft.rfft(x * window[:, None], axis=0)
            out.append((freqs, np.sum(np.abs(X) ** 2, axis=1)))
        return tuple(out)

    def schedule(self) -> bool:
        """Re-schedule the base predictor when the measured latency (prediction horizon),
        frame period or number of fused views has changed (:func:`schedule_predictor`).

        Why: extrapolating the base across the tracker latency amplifies the high
        frequencies, and the leg reaction forces close that amplification into a loop through
        the base (measured: 14-15 Hz oscillation of trolley + upper platform against the feed
        from 40 ms of latency with the unscheduled predictor). The schedule bounds the loop's
        gain and keeps the best isolation in the trolley's vibration band.

        A change of the horizon counts from one frame period on (at least 1 ms): across
        processes the controller's sim-time clock advances in steps of the simulator's
        publish period (the frame period) and reaches it in another order than the frames, so
        each measured delay is only known to within a frame period, and the filtered latency
        wanders by up to a period (measured: 21 to 24 ms of horizon for 20 ms of latency); a
        schedule (64 predictor responses, some 15 ms of CPU) on every smaller change would
        follow that quantisation (measured: about ten schedules per sim second with 1 ms, 2.4
        with half a period, with the simulator a period ahead)."""
        if self.period is None or self.latency is None:
            return False
        horizon = max(self.latency + self.lead, 0.0)
        key = (horizon, self.period, self.views)
        old = self._scheduled
        stamp = self._frame[0]
        due = self._spectrum_time is None or stamp - self._spectrum_time >= \
            self.reschedule_period
        if old is not None and abs(horizon - old[0]) < max(1e-3, old[1]) \
                and abs(self.period - old[1]) < 0.05 * old[1] \
                and abs(self.views - old[2]) < 0.25 and not due:
            return False
        self._scheduled = key
        self._spectrum_time = stamp
        spectra = self.base_spectra()   # None until 4 s of base history (flat weights then)
        views = max(self.views, 1.0)
        for k, kf in enumerate((self.base.pos, self.base.rot)):
            q, g, peak = schedule_predictor(self.q_max[k], self.noise_var[k] / views,
                                            self.period, horizon, self.peak_gain_max,
                                            self.vibration_band,
                                            spectrum=None if spectra is None else spectra[k])
            kf.q = q
            self.gains[k] = g
            self.loop_peak[k] = peak
        return True

    def add_feed(self, now: float, stamp: float, position: ArrayLike, rotation: ArrayLike) -> bool:
        """Tracked feed pose: the PID (``lu``), the integral trim and a base view
        (``predictive``); ignored by ``cheng`` and without tracker feedback."""
        position = np.asarray(position, float)
        rotation = np.asarray(rotation, float)
        if not _finite(position, rotation):
            return False
        if self.open_loop:
            return False
        if self.mode == 'lu':
            self._lu_step(now, position, rotation)
        elif self.mode == 'predictive':
            if self.fuse:
                base = self._base_from_feed(stamp, position, rotation)
                if base is not None:
                    self.add_base(now, stamp, *base)
            target = self.targets.at(stamp)
            if target is None or self.last_feed_time is None:
                self.last_feed_time = now
                return True
            e = np.concatenate(pose_error(target[0], target[1], position, rotation))
            dt = min(now - self.last_feed_time, 0.1)
            self.trim += self.trim_gain * dt * e
            self.trim[:3] = np.clip(self.trim[:3], -self.trim_limit[0], self.trim_limit[0])
            self.trim[3:] = np.clip(self.trim[3:], -self.trim_limit[1], self.trim_limit[1])
        self.last_feed_time = now
        return True

    def lu_integral_gain(self) -> float:
        """Integral gain of the ``lu`` PID: ``lu_ki``, or with the delay cure
        (``lu_delay_limit > 0``) at most ``lu_delay_limit / tau`` for the measured latency
        ``tau`` (the loop ``ki e^{-s tau} / s`` keeps a phase margin of
        ``pi/2 - lu_delay_limit`` rad)."""
        if self.lu_delay_limit <= 0.0 or not self.latency:
            return self.lu_ki
        return min(self.lu_ki, self.lu_delay_limit / self.latency)

    def _lu_step(self, now, position, rotation):
        """One PID step on the latest tracked feed error taken as current (velocity form:
        ``du = kp de + ki e dt + kd d(de/dt)``, derivative low-passed over 10 ms), rotated
        into the base frame of the latest base measurement."""
        target = self.targets.latest()
        if target is None or self.last_base_R is None:
            return
        e = np.concatenate(pose_error(target[1], target[2], position, rotation))
        dt = 0.0 if self.last_feed_time is None else now - self.last_feed_time
        prev = e if self.lu_prev_error is None else self.lu_prev_error
        d_prev = self.lu_derivative.copy()
        if dt > 0:
            self.lu_derivative += dt / (0.01 + dt) * ((e - prev) / dt - self.lu_derivative)
        step = self.lu_kp * (e - prev) + self.lu_integral_gain() * dt * e \
            + self.lu_kd * (self.lu_derivative - d_prev)
        Rb = self.last_base_R
        self.lu_cmd[:3] += Rb.T @ step[:3]
        self.lu_cmd[3:] += Rb.T @ step[3:]
        self.lu_prev_error = e

    # ------------------------------------------------------------------ output
    def _base_command(self, t):
        """Base pose the legs compensate at ``t``: the slow base reference plus the gain-scaled
        predicted vibration about it."""
        x = None
        if not self.predict_base:
            t = self.base.last_stamp           # the latest estimate, at its capture time
        elif self.wiener is not None:
            x = self.wiener.predict(t)
        if x is not None:          # its peak gain is bounded in the fit
            self.loop_peak = self.wiener.peak()
            return x[:3], self.wiener_ref @ matrix_from_rotvec(x[3:])
        p_b, R_b = self.base.predict_pose(t, order=2 if self.mode == 'predictive' else 1)
        if self.mode != 'predictive' or self.slow is None:
            return p_b, R_b
        g_p, g_r = self.gains.tolist()
        if g_p >= 1.0 and g_r >= 1.0:          # self.gain >= 1.0, NaN included
            return p_b, R_b
        _, p_s, R_s = self.slow
        dphi = rotvec_from_matrix(R_s.T @ R_b)
        return p_s + g_p * (p_b - p_s), R_s @ matrix_from_rotvec(g_r * dphi)

    def _update_slow(self, now):
        p_b, R_b = self.base.predict_pose(now)
        if self.slow is None:
            self.slow = (now, p_b, R_b)
            return
        t0, p_s, R_s = self.slow
        a = min(1.0, max(now - t0, 0.0) / self.slow_time)
        dphi = rotvec_from_matrix(R_s.T @ R_b)
        self.slow = (now, p_s + a * (p_b - p_s), R_s @ matrix_from_rotvec(a * dphi))

    def _relative(self, t, target_p, target_R):
        """Desired lower platform pose in the (compensated) upper platform frame at ``t``."""
        p_b, R_b = self._base_command(t)
        p_d = target_p + self.trim[:3]
        trim_rotvec = self.trim[3:].tolist()
        if self._trim_R[0] != trim_rotvec:      # the trim changes with feed frames only
            self._trim_R = (trim_rotvec, matrix_from_rotvec(trim_rotvec))
        R_d = self._trim_R[1] @ target_R
        rel_p, rel_R = R_b.T @ (p_d - p_b), R_b.T @ R_d
        if self.reaction is not None:
            # (p_b, R_b) is the reaction-free base: moving the payload by e relative to the
            # base moves the base by -K e, so the legs move it by (I - J K)^-1 e0.
            e0 = np.concatenate([rel_p - self.nominal_p,
                                 rotvec_from_matrix(rel_R @ self.nominal_R.T)])
            e = self.reaction[1] @ e0
            rel_p, rel_R = self.nominal_p + e[:3], matrix_from_rotvec(e[3:]) @ self.nominal_R
        return rel_p, rel_R

    def _clip(self, lengths):
        lo, hi = self.lo, self.hi
        clipped = any(x < lo or x > hi for x in lengths.tolist())
        if clipped:
            self.clip_count += 1
            return np.clip(lengths, lo, hi), True
        return lengths.copy(), False      # np.clip's result when nothing is outside

    def _open_loop_update(self, latest):
        """Legs from the trajectory alone: the base assumed at the pose the coarse loop
        commands for the latest target (the trolley at its target, hinges at their angles)."""
        _, _, p_u, R_u = self.chain.coarse_targets(latest[1], latest[2])
        lengths, clipped = self._clip(inverse_kinematics(
            self.geometry, R_u.T @ (latest[1] - p_u), R_u.T @ latest[2]))
        self.command = LegCommand(lengths, np.zeros(6), clipped, False)
        return self.command

    def update(self, now: float) -> LegCommand:
        """Leg command (:class:`LegCommand`) for the current time ``now``."""
        latest = self.targets.latest()
        if self.open_loop and latest is not None:
            return self._open_loop_update(latest)
        stale = (self.last_base_arrival is None
                 or now - self.last_base_arrival > self.timeout)
        latest = self.targets.latest()
        if stale or latest is None or not self.base.ready:
            self.hold_count += 1
            self.command = LegCommand(self.command.lengths, np.zeros(6), False, True)
            return self.command
        if self.mode == 'lu':
            R = matrix_from_rotvec(self.lu_cmd[3:])
            lengths, clipped = self._clip(inverse_kinematics(self.geometry, self.lu_cmd[:3], R))
            rates = np.zeros(6)
        else:
            if self.mode == 'predictive':
                self.schedule()
                self._update_slow(now)
            h = 0.002
            v, w = self.targets.velocity()
            t0 = now + self.lead
            age = t0 - latest[0]
            p0 = latest[1] + v * age
            R0 = matrix_from_rotvec(w * age) @ latest[2]
            p1 = p0 + v * h
            R1 = matrix_from_rotvec(w * h) @ R0
            l0 = inverse_kinematics(self.geometry, *self._relative(t0, p0, R0))
            l1 = inverse_kinematics(self.geometry, *self._relative(t0 + h, p1, R1))
            lengths, clipped = self._clip(l0)
            rates = np.where((l0 < self.lo) | (l0 > self.hi), 0.0, (l1 - l0) / h)
        self.command = LegCommand(lengths, rates, clipped, False)
        return self.command
