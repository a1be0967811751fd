"""Load and validate the FAST feed-support config (field model, cables, platforms, wind).

The config is a YAML file (default ``cable_robot_pkg/fast/config/fast.yaml``); a user file is
merged over the defaults key by key, so it only needs the keys it changes. :func:`load_config`
checks every number's sign and range and then the system as a whole *before* a run starts:

- every track target must be reachable: trolley inside the field below the towers, hinge angles
  within range, and cable tensions within ``[tension_min, tension_max]`` balancing the weight
  (:meth:`CableSystem.tension_distribution`);
- the Gough-Stewart stroke must hold the nominal pose plus the isolation envelope (trolley
  excursion ``envelope_position`` in any direction, rotation ``envelope_rotation_deg``) at the
  extreme track targets.

Any failure raises :class:`paramotion.errors.UserError` with one line naming the key and what is
wrong, e.g. ``fast.yaml: cables.EA = -1 must be > 0``.
"""
from __future__ import annotations

import copy
import itertools
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import yaml
from numpy.typing import ArrayLike

from cable_robot_pkg.fast.cables import Cable, CableSystem, InfeasibleTensionError, gravity_wrench
from cable_robot_pkg.fast.focal_surface import (
    FeedSupportChain,
    FocalSurface,
    Track,
    hinge_rotation,
)
from paramotion import yamlfile
from paramotion.errors import UserError
from paramotion.gough_stewart import GoughStewartGeometry, inverse_kinematics

DEFAULT_CONFIG = os.path.join(os.path.dirname(__file__), 'config', 'fast.yaml')

CABLE_KINDS = ('drive', 'suspension', 'pretension')
TRACK_KINDS = ('circle', 'meridian', 'hold')
LEG_ACTUATORS = ('servo', 'force')
SPECTRA = ('kaimal', 'davenport', 'white')
#: Isolation controllers: ``lu`` (PID on direct terminal feedback, Lu et al.), ``cheng`` (base
#: position prediction + the legs' PD, Cheng et al.), ``predictive`` (the project's own).
ISOLATION_MODES = ('lu', 'cheng', 'predictive')
#: Base predictors of the ``predictive`` mode (``isolation.predictor``).
BASE_PREDICTORS = ('kalman', 'wiener')
#: Constructs that ``--without NAME`` (node parameter and launch argument ``without``) removes.
ABLATIONS = ('tracker_feedback', 'isolation', 'prediction', 'reaction')


def parse_without(value: str | Iterable[object] | None,
                  name: str = 'without') -> frozenset[str]:
    """Ablation names from a comma-separated string or a list of strings; a name that is not
    one of :data:`ABLATIONS` raises :class:`UserError` with one line naming ``name``."""
    if isinstance(value, str):
        items = [x.strip() for x in value.split(',')]
    else:
        items = [str(x).strip() for x in value or ()]
    items = [x for x in items if x]
    unknown = [x for x in items if x not in ABLATIONS]
    if unknown:
        raise UserError(f'{name} {", ".join(unknown)!s}: unknown construct; known: '
                        f'{", ".join(ABLATIONS)}')
    return frozenset(items)


#: Sections whose keys are names chosen by the user (towers, anchors), not fixed fields.
_FREE_FORM_SECTIONS = ('towers', 'ground_anchors')


def _merge(base, override):
    """Recursive dict merge: ``override`` wins; lists are replaced whole."""
    out = copy.deepcopy(base)
    for k, v in override.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


class _Reader:
    """Typed access to the raw dict with errors that name the file and the key."""

    def __init__(self, raw, source):
        self.raw = raw
        self.source = source

    def fail(self, key, why):
        raise UserError(f'{self.source}: {key} {why}')

    def get(self, key):
        node = self.raw
        for part in key.split('.'):
            if not isinstance(node, dict) or part not in node:
                self.fail(key, 'is missing')
            node = node[part]
        return node

    def num(self, key, lo=None, hi=None, lo_open=False):
        v = self.get(key)
        if isinstance(v, str):
            # PyYAML (YAML 1.1) reads exponents without a sign, e.g. 2.0e5, as strings.
            try:
                v = float(v)
            except ValueError:
                pass
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            self.fail(key, f'= {v!r} must be a finite number')
        if lo is not None and (v <= lo if lo_open else v < lo):
            self.fail(key, f'= {v!r} must be {">" if lo_open else ">="} {lo}')
        if hi is not None and v > hi:
            self.fail(key, f'= {v!r} must be <= {hi}')
        self._store(key, float(v))
        return float(v)

    def _store(self, key, value):
        """Write the parsed number back so later readers of ``raw`` get a float."""
        parts = key.split('.')
        node = self.raw
        for part in parts[:-1]:
            node = node[part]
        node[parts[-1]] = value

    def vec(self, key, n=3, value=None):
        v = self.get(key) if value is None else value
        try:
            a = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            self.fail(key, f'= {v!r} must be a list of {n} numbers')
        if a.shape != (n,) or not np.all(np.isfinite(a)):
            self.fail(key, f'= {v!r} must be a list of {n} finite numbers')
        return a

    def choice(self, key, choices):
        v = self.get(key)
        if v not in choices:
            self.fail(key, f'= {v!r} must be one of {", ".join(choices)}')
        return v


@dataclass
class FastConfig:
    """Validated config: the raw dict plus the objects built from it."""

    raw: dict
    source: str
    cables: CableSystem
    cable_specs: list
    geometry: GoughStewartGeometry
    surface: FocalSurface
    track: Track
    chain: FeedSupportChain
    suspended_mass: float
    com_below_trolley: float

    def section(self, name: str) -> dict:
        """A top-level section of the raw config (a dict)."""
        return self.raw[name]

    def value(self, key: str) -> object:
        """A raw value by dotted key, e.g. ``'cables.EA'``."""
        return _Reader(self.raw, self.source).get(key)

    def tension_targets(self, trolley_position: ArrayLike,
                        feed_rotation: ArrayLike) -> np.ndarray:
        """Planned cable tensions at a level trolley pose (raises InfeasibleTensionError)."""
        c = self.raw['cables']
        return self.cables.tension_distribution(
            trolley_position, np.eye(3), self.load_wrench(feed_rotation), c['tension_min'],
            c['tension_max'], np.full(self.cables.n, c['tension_ref']))

    def load_wrench(self, feed_rotation: ArrayLike) -> np.ndarray:
        """Weight of everything hanging on the cables as a wrench about the trolley origin,
        for a feed orientation (the hinge tilts the platforms' centre of mass)."""
        axis = np.asarray(feed_rotation)[:, 2]
        offset = np.asarray(self.chain.hinge_offset) - self.com_below_trolley * axis
        return gravity_wrench(self.suspended_mass, offset)


def load_config(path: str | os.PathLike[str] | None = None,
                overrides: dict | None = None) -> FastConfig:
    """Read, merge over the defaults, and validate a config; returns :class:`FastConfig`."""
    with open(DEFAULT_CONFIG, encoding='utf-8') as f:
        raw = yamlfile.safe_load(f)
    source = os.path.basename(DEFAULT_CONFIG)
    if path is not None:
        source = os.path.basename(str(path))
        try:
            with open(path, encoding='utf-8') as f:
                user = yamlfile.safe_load(f)
        except FileNotFoundError:
            raise UserError(f'config {path}: no such file') from None
        except yaml.YAMLError as exc:
            first = str(exc).splitlines()[0] if str(exc) else 'parse error'
            raise UserError(f'config {path}: not valid YAML ({first})') from None
        if user is None:
            user = {}
        if not isinstance(user, dict):
            raise UserError(f'config {path}: top level must be a mapping of sections')
        unknown = sorted(set(user) - set(raw))
        if unknown:
            raise UserError(f'{source}: unknown section(s) {", ".join(unknown)}; '
                            f'known: {", ".join(sorted(raw))}')
        for section, value in user.items():
            if section in _FREE_FORM_SECTIONS or not isinstance(value, dict) \
                    or not isinstance(raw[section], dict):
                continue
            keys = [f'{section}.{k}' for k in sorted(set(value) - set(raw[section]))]
            if keys:
                raise UserError(f'{source}: unknown key(s) {", ".join(keys)}; known in '
                                f'{section}: {", ".join(sorted(raw[section]))}')
        raw = _merge(raw, user)
    if overrides:
        raw = _merge(raw, overrides)
    return validate(raw, source)


def validate(raw: dict, source: str = 'config') -> FastConfig:
    """Check every field, then reachability and stroke; build the model objects.

    One step per section of the file, in the order a reader meets them: the field and its
    anchor points, the trolley, the cables, the orienting chain and the Gough-Stewart
    isolator, the focal surface and track, the wind, the tracker and controllers, then the
    hanging mass and the reachability of every target within the leg stroke.
    """
    r = _Reader(raw, source)
    size, points = _field_points(r)
    tsize = _check_trolley(r)
    system, cables, t_min, t_max = _cables(r, points, tsize)
    hinge, upper_offset, ring_mass, angle_max = _orienting(r)
    geometry, leg_min, leg_max, env_p, env_r = _gough_stewart(r, raw)
    chain = FeedSupportChain(hinge, upper_offset, float(raw['gough_stewart']['nominal_height']))
    surface, track = _focal_track(r)
    _check_wind(r)
    _check_tracker_and_controllers(r, raw, leg_min, leg_max)
    suspended, com_below = _hanging_mass(raw, ring_mass, chain.upper_offset)
    cfg = FastConfig(raw, source, system, cables, geometry, surface, track, chain, suspended,
                     com_below)
    _check_reachability(cfg, r, size, angle_max, t_min, t_max, env_p, env_r)
    return cfg


def _field_points(r):
    """Field box and the named tower/ground anchor points (all inside the field)."""
    size = r.vec('field.size')
    if np.any(size <= 0):
        r.fail('field.size', f'= {size.tolist()} must be positive')
    half = np.array([size[0] / 2, size[1] / 2])

    def inside(key, p, top=True):
        if np.any(np.abs(p[:2]) > half + 1e-9) or p[2] < -1e-9 or (top and p[2] > size[2] + 1e-9):
            r.fail(key, f'= {p.tolist()} lies outside the field model {size.tolist()} m')

    points = {}
    for group in ('towers', 'ground_anchors'):
        g = r.get(group)
        if not isinstance(g, dict) or not g:
            r.fail(group, 'must map names to [x, y, z] points')
        for name, v in g.items():
            p = r.vec(f'{group}.{name}', value=v)
            inside(f'{group}.{name}', p)
            points[name] = p
    return size, points


def _check_trolley(r):
    """Trolley mass, wind area, drag, size and centre of pressure; returns the size."""
    for key in ('trolley.mass', 'trolley.wind_area', 'trolley.drag_coefficient'):
        r.num(key, 0.0, lo_open=True)
    tsize = r.vec('trolley.size')
    if np.any(tsize <= 0):
        r.fail('trolley.size', f'= {tsize.tolist()} must be positive')
    r.vec('trolley.centre_of_pressure')
    return tsize


def _cables(r, points, tsize):
    """Cable material, tension limits and the cable list: ``(system, cables, t_min, t_max)``."""
    EA = r.num('cables.EA', 0.0, lo_open=True)
    damping = r.num('cables.damping', 0.0)
    t_min = r.num('cables.tension_min', 0.0, lo_open=True)
    t_max = r.num('cables.tension_max', 0.0, lo_open=True)
    if t_max <= t_min:
        r.fail('cables.tension_max', f'= {t_max} must exceed cables.tension_min = {t_min}')
    r.num('cables.tension_ref', t_min, t_max)
    floor = r.num('cables.tension_floor', 0.0)
    if floor >= t_min:
        r.fail('cables.tension_floor', f'= {floor} must be below cables.tension_min = {t_min}')
    r.num('cables.winch_speed_max', 0.0, lo_open=True)
    specs = r.get('cables.list')
    if not isinstance(specs, list) or len(specs) < 7:
        r.fail('cables.list', 'must list at least 7 cables (6 DOF need one redundant cable)')
    cables, names = [], set()
    for i, c in enumerate(specs):
        key = f'cables.list[{i}]'
        if not isinstance(c, dict):
            r.fail(key, 'must be a mapping with name, kind, anchors, attach')
        name = c.get('name')
        if not isinstance(name, str) or not name or name in names:
            r.fail(f'{key}.name', f'= {name!r} must be a unique non-empty string')
        names.add(name)
        kind = c.get('kind')
        if kind not in CABLE_KINDS:
            r.fail(f'{key}.kind', f'= {kind!r} must be one of {", ".join(CABLE_KINDS)}')
        anchors = c.get('anchors')
        want = 2 if kind == 'suspension' else 1
        if not isinstance(anchors, list) or len(anchors) != want:
            r.fail(f'{key}.anchors', f'must name {want} tower/ground point(s) for a {kind} cable')
        for a in anchors:
            if a not in points:
                r.fail(f'{key}.anchors', f'names unknown point {a!r}; known: '
                       f'{", ".join(sorted(points))}')
        attach = r.vec(f'{key}.attach', value=c.get('attach'))
        if np.any(np.abs(attach) > tsize / 2 + 1e-9):
            r.fail(f'{key}.attach', f'= {attach.tolist()} lies outside the trolley box '
                   f'{tsize.tolist()}')
        cables.append(Cable(name, kind, np.array([points[a] for a in anchors]), attach))
    return CableSystem(cables, EA, damping), cables, t_min, t_max


def _orienting(r):
    """Hinges between trolley and upper platform and the servo gains:
    ``(hinge offset, upper offset, ring mass, angle_max)``."""
    hinge = r.vec('orienting.hinge_offset')
    upper_offset = r.num('orienting.upper_offset', 0.0)
    ring_mass = r.num('orienting.ring_mass', 0.0, lo_open=True)
    angle_max = math.radians(r.num('orienting.angle_max_deg', 0.0, 60.0, lo_open=True))
    r.num('orienting.torque_max', 0.0, lo_open=True)
    for key in ('orienting.servo_position_gain', 'gough_stewart.servo_position_gain',
                'orienting.servo_velocity_gain', 'gough_stewart.servo_velocity_gain'):
        r.num(key, 0.0, 1.0, lo_open=True)
    return hinge, upper_offset, ring_mass, angle_max


def _gough_stewart(r, raw):
    """The isolator: ``(geometry, leg_min, leg_max, envelope position, envelope rotation)``."""
    gs = 'gough_stewart'
    for key in ('base_radius', 'platform_radius', 'nominal_height', 'upper_mass', 'feed_mass',
                'leg_mass', 'drive_force_max', 'actuator_stiffness', 'actuator_damping',
                'actuator_bandwidth_hz'):
        r.num(f'{gs}.{key}', 0.0, lo_open=True)
    r.choice(f'{gs}.actuator', LEG_ACTUATORS)
    for key in ('base_half_angle_deg', 'platform_half_angle_deg'):
        r.num(f'{gs}.{key}', 0.0, 30.0, lo_open=True)
    leg_min = r.num(f'{gs}.leg_min', 0.0, lo_open=True)
    leg_max = r.num(f'{gs}.leg_max', 0.0, lo_open=True)
    if leg_max <= leg_min:
        r.fail(f'{gs}.leg_max', f'= {leg_max} must exceed {gs}.leg_min = {leg_min}')
    env_p = r.num(f'{gs}.envelope_position', 0.0)
    env_r = math.radians(r.num(f'{gs}.envelope_rotation_deg', 0.0, 30.0))
    g = raw[gs]
    geometry = GoughStewartGeometry.from_rings(
        g['base_radius'], g['platform_radius'], math.radians(g['base_half_angle_deg']),
        math.radians(g['platform_half_angle_deg']), leg_min, leg_max)
    return geometry, leg_min, leg_max, env_p, env_r


def _focal_track(r):
    """Focal surface and the feed's track on it (the target must be on the reachable cap)."""
    centre = r.vec('focal_surface.centre')
    radius = r.num('focal_surface.radius', 0.0, lo_open=True)
    zmax = math.radians(r.num('focal_surface.zenith_max_deg', 0.0, 60.0))
    surface = FocalSurface(centre, radius)
    kind = r.choice('track.kind', TRACK_KINDS)
    zen = math.radians(r.num('track.zenith_deg', 0.0, 90.0))
    if zen > zmax + 1e-12:
        r.fail('track.zenith_deg', f'= {math.degrees(zen):g} is beyond '
               f'focal_surface.zenith_max_deg = {math.degrees(zmax):g} (unreachable target)')
    track = Track(surface, kind, zen, math.radians(r.num('track.azimuth_deg')),
                  r.num('track.speed', 0.0))
    return surface, track


def _check_wind(r):
    """Wind model: mean, turbulence spectrum, gusts, seed."""
    r.num('wind.mean_speed', 0.0)
    r.num('wind.direction_deg')
    r.num('wind.turbulence_intensity', 0.0, 2.0)
    r.num('wind.integral_length', 0.0, lo_open=True)
    r.choice('wind.spectrum', SPECTRA)
    r.num('wind.torque_scale', 0.0)
    r.num('wind.gust_rate', 0.0)
    r.num('wind.gust_amplitude', 0.0, 3.0)
    r.num('wind.gust_duration', 0.0, lo_open=True)
    seed = r.get('wind.seed')
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        r.fail('wind.seed', f'= {seed!r} must be a non-negative integer')


def _check_tracker_and_controllers(r, raw, leg_min, leg_max):
    """Tracker, cable controller, isolation controller and simulator settings."""
    r.num('tracker.noise_position', 0.0, 1.0)
    r.num('tracker.noise_orientation_deg', 0.0, 10.0)
    r.num('tracker.rate', 0.0, 2000.0, lo_open=True)
    r.num('tracker.latency', 0.0, 0.5)
    cable_rate = r.num('cable_controller.rate', 0.0, 1000.0, lo_open=True)
    for key in ('kp', 'ki', 'kd'):
        r.num(f'cable_controller.{key}', 0.0)
    r.num('cable_controller.correction_max', 0.0, lo_open=True)
    iso_rate = r.num('isolation.rate', 0.0, 2000.0, lo_open=True)
    if iso_rate <= cable_rate:
        r.fail('isolation.rate', f'= {iso_rate:g} Hz must exceed cable_controller.rate = '
               f'{cable_rate:g} Hz (fine loop faster than the coarse loop)')
    r.choice('isolation.mode', ISOLATION_MODES)
    r.choice('isolation.predictor', BASE_PREDICTORS)
    taps = r.num('isolation.wiener_taps', 2, 64)
    if taps != int(taps):
        r.fail('isolation.wiener_taps', f'= {taps!r} must be an integer')
    r.num('isolation.wiener_spacing', 0.0, 0.1, lo_open=True)
    r.num('isolation.wiener_window', 1.0, 120.0)
    for key in ('trim_gain', 'process_noise', 'process_noise_rotation', 'lu_kp', 'lu_ki',
                'lu_kd', 'lu_delay_limit', 'stroke_margin'):
        r.num(f'isolation.{key}', 0.0)
    r.num('isolation.dropout_timeout', 0.0, lo_open=True)
    r.num('isolation.lead', -0.05, 0.1)
    r.num('isolation.peak_gain_max', 1.0, 100.0)
    band = raw['isolation'].get('vibration_band')
    if not (isinstance(band, (list, tuple)) and len(band) == 2
            and all(isinstance(f, (int, float)) and not isinstance(f, bool) for f in band)
            and 0.0 < band[0] < band[1] <= 0.5 * raw['tracker']['rate']):
        r.fail('isolation.vibration_band', f'= {band!r} must be [f_low, f_high] Hz with '
               '0 < f_low < f_high <= half the tracker rate')
    if not isinstance(raw['isolation'].get('fuse'), bool):
        r.fail('isolation.fuse', f"= {raw['isolation'].get('fuse')!r} must be true or false")
    if 2 * raw['isolation']['stroke_margin'] >= leg_max - leg_min:
        r.fail('isolation.stroke_margin', 'leaves no usable leg stroke')
    r.num('sim.physics_dt', 1e-5, 0.01)
    r.num('sim.solver_iterations', 1, 1000)


def _hanging_mass(raw, ring_mass, upper_offset):
    """Mass hanging from the trolley and its centre of mass below the trolley's:
    ``(suspended mass, com_below)``."""
    g = raw['gough_stewart']
    upper_mass = float(g['upper_mass'])
    legs_mass = 6 * float(g['leg_mass'])
    feed_mass = float(g['feed_mass'])
    hanging = ring_mass + upper_mass + legs_mass + feed_mass
    # Centre of mass of the hanging chain below the hinge, along the feed axis.
    com = (upper_offset * (upper_mass + ring_mass)
           + (upper_offset + g['nominal_height'] / 2) * legs_mass
           + (upper_offset + g['nominal_height']) * feed_mass) / hanging
    suspended = float(raw['trolley']['mass']) + hanging
    return suspended, hanging * com / suspended


def _check_reachability(cfg, r, size, angle_max, t_min, t_max, env_p, env_r):
    """Every track target reachable by cables, hinges and legs (with the isolation envelope)."""
    tower_top = min(float(c.anchors[:, 2].min()) for c in cfg.cable_specs
                    if c.kind != 'pretension')
    rel_p, rel_R = cfg.chain.nominal_relative_pose()
    corners = [np.array(s) * env_p for s in itertools.product((-1, 1), repeat=3)]
    tilts = [hinge_rotation(a, b) for a, b in itertools.product((-env_r, env_r), repeat=2)]
    duration = 3600.0
    for feed_p, feed_R in cfg.track.sample(duration, n=24):
        trolley_p, (alpha, beta), _, _ = cfg.chain.coarse_targets(feed_p, feed_R)
        where = f'target feed position {np.round(feed_p, 3).tolist()}'
        if np.any(np.abs(trolley_p[:2]) > size[:2] / 2) or trolley_p[2] >= tower_top \
                or feed_p[2] <= 0.0:
            raise UserError(f'{cfg.source}: {where} is unreachable: trolley would be at '
                            f'{np.round(trolley_p, 3).tolist()}, outside the field below the '
                            f'tower pulleys (z < {tower_top:g} m)')
        if max(abs(alpha), abs(beta)) > angle_max:
            raise UserError(f'{cfg.source}: {where} is unreachable: hinge angles '
                            f'{math.degrees(alpha):.1f}/{math.degrees(beta):.1f} deg exceed '
                            f'orienting.angle_max_deg = {math.degrees(angle_max):g}')
        try:
            cfg.tension_targets(trolley_p, feed_R)
        except InfeasibleTensionError as exc:
            raise UserError(f'{cfg.source}: {where} is unreachable: {exc}') from None
        # The legs must absorb a trolley displacement/rotation of the envelope size: the
        # upper platform moves by -d, the lower one must stay put.
        lengths = [inverse_kinematics(cfg.geometry, rel_p, rel_R)]
        for d in corners:
            for T in tilts:
                lengths.append(inverse_kinematics(cfg.geometry, T.T @ (rel_p - d), T.T @ rel_R))
        lengths = np.array(lengths)
        lo, hi = float(lengths.min()), float(lengths.max())
        if lo < cfg.geometry.leg_min or hi > cfg.geometry.leg_max:
            raise UserError(
                f'{cfg.source}: gough_stewart leg stroke [{cfg.geometry.leg_min:g}, '
                f'{cfg.geometry.leg_max:g}] m is too short: the nominal pose plus the isolation '
                f'envelope (+-{env_p:g} m, +-{math.degrees(env_r):g} deg) needs '
                f'[{lo:.3f}, {hi:.3f}] m')
