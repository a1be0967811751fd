"""Stochastic wind load on the trolley: turbulent force and torque plus discrete gusts.

The FAST papers name wind as the disturbance the feed support must reject (Lu, Zhu, Ren, Sec. I:
"wind-induced vibration of the trolley ... might be as high as 0.5 m"; Cheng, Ren, Dai: "0.5 m in
position and 3 deg in orientation"). We model it the usual way for wind engineering:

- wind speed ``U (1 + ...)`` along ``direction`` with turbulent components u, v, w whose power
  spectral densities follow a Kaimal or Davenport spectrum (or white noise up to Nyquist):

  Kaimal    ``f S(f) / sigma^2 = 4 f L/U / (1 + 6 f L/U)^(5/3)``
  Davenport ``f S(f) / sigma^2 = (2/3) x^2 / (1 + x^2)^(4/3)``, ``x = f L / U``

  with ``sigma = I U`` (turbulence intensity I, lateral/vertical scaled by 0.8/0.5). Time series
  are synthesised once per block by the spectral-representation method (random phases, inverse
  FFT), which is exact for the chosen spectrum, then read out with linear interpolation;
- quasi-steady drag ``F = 1/2 rho Cd A |V| V``;
- torque ``= r_cp x F`` (centre of pressure) plus a shaped random torque of size
  ``|F| * torque_scale``, standing for the uneven pressure over the cabin;
- 1-cosine gusts ``g(t) = a U (1 - cos(2 pi (t - t0) / T)) / 2`` at Poisson times.

``intensity`` (the scenario's ``--wind``) scales the mean speed and the gust rate; 0 is no
wind. Everything is drawn from one seeded generator, so a run is reproducible.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

RHO_AIR = 1.225  # kg/m^3


def spectrum(kind: str, f: ArrayLike, mean_speed: float, length: float,
             sigma: float) -> np.ndarray:
    """One-sided PSD S(f) (units^2/Hz) of a turbulent component of std ``sigma``."""
    f = np.asarray(f, float)
    u = max(mean_speed, 0.1)
    if kind == 'kaimal':
        n = f * length / u
        s = 4.0 * length / u / (1.0 + 6.0 * n) ** (5.0 / 3.0)
    elif kind == 'davenport':
        x = np.maximum(f * length / u, 1e-12)
        s = (2.0 / 3.0) * x ** 2 / (1.0 + x ** 2) ** (4.0 / 3.0) / np.maximum(f, 1e-12)
    elif kind == 'white':
        s = np.ones_like(f)
    else:
        raise ValueError(f'unknown wind spectrum {kind!r}')
    return sigma ** 2 * s


def synthesize(rng: np.random.Generator, kind: str, mean_speed: float, length: float,
               sigma: float, dt: float, n: int) -> np.ndarray:
    """A zero-mean series of ``n`` samples at ``dt`` with the given spectrum, scaled to exactly
    ``sigma`` standard deviation (spectral representation, random phases)."""
    f = np.fft.rfftfreq(n, dt)
    s = spectrum(kind, f, mean_speed, length, 1.0)
    s[0] = 0.0
    amp = np.sqrt(s * (f[1] - f[0]) / 2.0) * n
    phase = rng.uniform(0.0, 2.0 * math.pi, size=f.shape)
    x = np.fft.irfft(amp * np.exp(1j * phase), n)
    std = x.std()
    return x * (sigma / std) if std > 0 else x


class WindModel:
    """Wind force and torque on the trolley as a function of time (deterministic per seed)."""

    def __init__(self, mean_speed: float, direction: float, turbulence_intensity: float,
                 integral_length: float, spectrum_kind: str, area: float,
                 drag_coefficient: float, centre_of_pressure: ArrayLike, torque_scale: float,
                 gust_rate: float, gust_amplitude: float, gust_duration: float,
                 intensity: float = 1.0, seed: int | None = 0, sample_dt: float = 0.02,
                 block_seconds: float = 600.0):
        self.U = mean_speed * intensity
        self.direction = direction
        self.I = turbulence_intensity
        self.L = integral_length
        self.kind = spectrum_kind
        self.area = area
        self.cd = drag_coefficient
        self.r_cp = np.asarray(centre_of_pressure, float)
        self.torque_scale = torque_scale
        self.gust_rate = gust_rate * intensity / 60.0   # per second
        self.gust_amp = gust_amplitude
        self.gust_T = gust_duration
        self.dt = sample_dt
        self.n = int(2 ** math.ceil(math.log2(block_seconds / sample_dt)))
        self.rng = np.random.default_rng(seed)
        self.blocks = {}
        self.gusts = []          # (start time, amplitude)
        self._gust_horizon = 0.0

    @classmethod
    def from_config(cls, wind: dict, trolley: dict, intensity: float = 1.0,
                    seed: int | None = None) -> WindModel:
        """Build from the config's ``wind`` and ``trolley`` sections."""
        return cls(wind['mean_speed'], math.radians(wind['direction_deg']),
                   wind['turbulence_intensity'], wind['integral_length'], wind['spectrum'],
                   trolley['wind_area'], trolley['drag_coefficient'],
                   trolley['centre_of_pressure'], wind['torque_scale'], wind['gust_rate'],
                   wind['gust_amplitude'], wind['gust_duration'], intensity=intensity,
                   seed=wind['seed'] if seed is None else seed)

    def _block(self, k):
        """Turbulence block k: (6, n) series u, v, w and three torque shapes."""
        if k not in self.blocks:
            sig = self.I * self.U
            rows = [synthesize(self.rng, self.kind, self.U, self.L, s, self.dt, self.n)
                    for s in (sig, 0.8 * sig, 0.5 * sig)]
            rows += [synthesize(self.rng, self.kind, self.U, self.L, 1.0, self.dt, self.n)
                     for _ in range(3)]
            self.blocks[k] = np.array(rows)
        return self.blocks[k]

    def turbulence_columns(self, t: float) -> tuple[np.ndarray, int, np.ndarray, int, float]:
        """Where the turbulence at ``t`` is read: ``(block, j, block2, j2, frac)``, the
        series being ``(1 - frac) block[:, j] + frac block2[:, j2]`` (blocks made on first
        use, from the shared generator)."""
        x = t / self.dt
        i = int(math.floor(x))
        frac = x - i
        k, j = divmod(i, self.n)
        b = self._block(k)
        k2, j2 = divmod(i + 1, self.n)
        b2 = b if k2 == k else self._block(k2)
        return b, j, b2, j2, frac

    def _turbulence(self, t):
        b, j, b2, j2, frac = self.turbulence_columns(t)
        return (1.0 - frac) * b[:, j] + frac * b2[:, j2]

    def _gust(self, t):
        while self._gust_horizon <= t + self.gust_T and self.gust_rate > 0:
            self._gust_horizon += self.rng.exponential(1.0 / self.gust_rate)
            self.gusts.append((self._gust_horizon, self.gust_amp * self.rng.uniform(0.5, 1.0)))
        if self.gusts and self.gusts[0][0] + self.gust_T <= t - 60.0:
            # Gusts over for a minute are dropped (they add nothing to the sum below).
            self.gusts = [(t0, a) for t0, a in self.gusts if t0 + self.gust_T > t - 60.0]
        g = 0.0
        for t0, a in self.gusts:
            if t0 <= t < t0 + self.gust_T:
                g += a * self.U * 0.5 * (1.0 - math.cos(2.0 * math.pi * (t - t0) / self.gust_T))
        return g

    def velocity(self, t: float) -> np.ndarray:
        """Wind velocity (3,) in the map frame at time ``t``."""
        if self.U <= 0.0:
            return np.zeros(3)
        return self._velocity(t, self._turbulence(t))

    def _velocity(self, t, turbulence):
        u, v, w = turbulence[:3]
        along = self.U + u + self._gust(t)
        c, s = math.cos(self.direction), math.sin(self.direction)
        return np.array([along * c - v * s, along * s + v * c, w])

    def kernel_parameters(self) -> np.ndarray:
        """The constants of :meth:`wrench` as the compiled plant step takes them (its
        ``wind`` argument, the last two entries filled per step): U, cos and sin of the
        direction, ``0.5 rho Cd A``, torque scale, turbulence intensity, fraction, gust."""
        return np.array([self.U, math.cos(self.direction), math.sin(self.direction),
                         0.5 * RHO_AIR * self.cd * self.area, self.torque_scale, self.I,
                         0.0, 0.0])

    def wrench(self, t: float,
               rotation: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Wind force (3,) and torque (3,) about the trolley origin, map axes.

        Runs every physics step: the turbulence is interpolated once for velocity and torque
        shapes, and the 3-vector norm and cross product are written out (same arithmetic as
        ``np.linalg.norm`` and ``np.cross``, without their per-call overhead).
        """
        if self.U <= 0.0:
            return np.zeros(3), np.zeros(3)
        turbulence = self._turbulence(t)
        vel = self._velocity(t, turbulence)
        force = 0.5 * RHO_AIR * self.cd * self.area * math.sqrt(vel.dot(vel)) * vel
        r = self.r_cp if rotation is None else np.asarray(rotation) @ self.r_cp
        f0, f1, f2 = force.tolist()
        r0, r1, r2 = r.tolist()
        arm = np.array([r1 * f2 - r2 * f1, r2 * f0 - r0 * f2, r0 * f1 - r1 * f0])
        torque = arm + math.sqrt(force.dot(force)) * self.torque_scale * self.I \
            * turbulence[3:]
        return force, torque
