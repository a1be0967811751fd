"""Climbing robot description: ring/leg/sensor geometry loaded from the parameter file.

The parameter file (``climber_pkg/config/climber.yaml`` by default) is the single source of the
robot's dimensions for the simulator, the ultrasonic sensors and the planner. Frames: each ring
frame has its origin at the centre of its joint circle, z along the ring axis (up the trunk for
ring 1 and ring 2 alike), x towards the first sensor gap; joints and sensors lie in z = 0.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np
import yaml

from paramotion import yamlfile
from paramotion.errors import UserError
from paramotion.gough_stewart import GoughStewartGeometry

DEFAULT_CONFIG = os.path.join(os.path.dirname(__file__), 'config', 'climber.yaml')


@dataclass(frozen=True)
class RobotConfig:
    """Everything the nodes need to know about the robot's body."""

    geometry: GoughStewartGeometry
    ring_inner_radius: float
    ring_outer_radius: float
    ring_thickness: float
    ring_mass: float
    leg_radius: float
    leg_mass: float
    leg_max_speed: float
    sensor_mount_radius: float
    sensor_angles: tuple[float, float, float]  # rad, in the ring frame
    sensor_min_range: float
    sensor_max_range: float
    sensor_fov: float
    clamp_close_time: float
    clamp_open_time: float

    def sensor_rays(self) -> tuple[np.ndarray, np.ndarray]:
        """Sensor origins (3, 3) and unit directions (3, 3) in the ring frame (inward, z = 0)."""
        ang = np.asarray(self.sensor_angles)
        radial = np.stack([np.cos(ang), np.sin(ang), np.zeros(3)], axis=1)
        return self.sensor_mount_radius * radial, -radial

    def max_trunk_radius(self, margin: float = 0.0) -> float:
        """Largest trunk radius the bore admits with the given radial margin."""
        return self.ring_inner_radius - margin


def _get(tree, path, source):
    node = tree
    for key in path.split('.'):
        if not isinstance(node, dict) or key not in node:
            raise UserError(f'{source}: missing key {path!r}')
        node = node[key]
    return node


def _num(tree, path, source, lo=0.0, hi=math.inf, lo_open=True):
    value = _get(tree, path, source)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise UserError(f'{source}: {path} must be a finite number, got {value!r}')
    if (value <= lo if lo_open else value < lo) or value > hi:
        raise UserError(f'{source}: {path}={value} outside the allowed range '
                        f'{"(" if lo_open else "["}{lo}, {hi}]')
    return float(value)


def load_robot_config(path: str | os.PathLike[str] | None = None) -> RobotConfig:

    """Read and validate the robot parameter file; raises UserError naming the bad key."""
    path = path or DEFAULT_CONFIG
    try:
        with open(path, encoding='utf-8') as handle:
            tree = yamlfile.safe_load(handle)
    except OSError as exc:
        raise UserError(f'robot config {path}: cannot read ({exc.strerror})') from exc
    except yaml.YAMLError as exc:
        raise UserError(f'robot config {path}: not valid YAML ({exc})') from exc
    src = f'robot config {path}'
    anchor = _num(tree, 'rings.anchor_radius', src, hi=10)
    inner = _num(tree, 'rings.inner_radius', src, hi=anchor)
    outer = _num(tree, 'rings.outer_radius', src, lo=anchor, hi=10)
    half_b = _num(tree, 'rings.base_half_angle_deg', src, hi=29.9)
    half_p = _num(tree, 'rings.platform_half_angle_deg', src, hi=29.9)
    lmin = _num(tree, 'legs.min_length', src, hi=100)
    lmax = _num(tree, 'legs.max_length', src, lo=lmin, hi=100)
    angles = _get(tree, 'ultrasonic.angles_deg', src)
    if (not isinstance(angles, list) or len(angles) != 3
            or not all(isinstance(a, (int, float)) for a in angles)):
        raise UserError(f'{src}: ultrasonic.angles_deg must be a list of three angles')
    smin = _num(tree, 'ultrasonic.min_range', src, hi=10)
    smax = _num(tree, 'ultrasonic.max_range', src, lo=smin, hi=10)
    mount = _num(tree, 'ultrasonic.mount_radius', src, hi=outer)
    geom = GoughStewartGeometry.from_rings(anchor, anchor, math.radians(half_b),
                                           math.radians(half_p), lmin, lmax)
    return RobotConfig(
        geometry=geom, ring_inner_radius=inner, ring_outer_radius=outer,
        ring_thickness=_num(tree, 'rings.thickness', src, hi=1),
        ring_mass=_num(tree, 'rings.mass', src, hi=1000),
        leg_radius=_num(tree, 'legs.radius', src, hi=0.5),
        leg_mass=_num(tree, 'legs.mass', src, hi=1000),
        leg_max_speed=_num(tree, 'legs.max_speed', src, hi=10),
        sensor_mount_radius=mount, sensor_angles=tuple(math.radians(a) for a in angles),
        sensor_min_range=smin, sensor_max_range=smax,
        sensor_fov=_num(tree, 'ultrasonic.field_of_view', src, hi=math.pi),
        clamp_close_time=_num(tree, 'clamps.close_time', src, lo=0, lo_open=False, hi=60),
        clamp_open_time=_num(tree, 'clamps.open_time', src, lo=0, lo_open=False, hi=60))
