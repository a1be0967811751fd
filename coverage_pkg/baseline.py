"""Baseline of Section II: coverage with a robot-size detector (plain boustrophedon).

With a detector no bigger than the robot (range r), every point of ``FCS_r`` is "vast"
(``D > r``), so the hierarchical decomposition collapses to the Morse (boustrophedon)
decomposition of the free configuration space: back-and-forth lapping along the slices of
``h = x`` with spacing ``2 r`` plus boundary following, critical points and Reeb graph exactly
as in :mod:`coverage_pkg.morse`; there is no GVD to trace. The same online planner
(:class:`coverage_pkg.planner.CoveragePlanner`) runs it with ``detector='robot'``; this module
only chooses the settings that a detector this small needs:

* a finer evidence grid (r / 5), a small wall clearance (the robot must pass close to the walls
  to sweep them with its own footprint);
* lapping slices ``2 r (1 - overlap)`` apart and tight "followed" tolerances: with a detector
  of range r, any tracking error between slices ``2 r`` apart leaves an unswept strip.
"""
from __future__ import annotations

from coverage_pkg.planner import PlannerConfig


def robot_size_config(radius: float = 0.25, overlap: float = 0.2,
                      **overrides: float | int | str | bool) -> PlannerConfig:
    """PlannerConfig of the robot-size-detector baseline for a robot of radius ``radius``."""
    values = dict(
        delta=radius, radius=radius, detector='robot',
        resolution=radius / 5.0,
        clearance_margin=0.1 * radius,
        lap_spacing=2.0 * radius * (1.0 - overlap),
        trace_tolerance=0.2 * radius,
        lap_tolerance=0.3 * radius,
        # A pocket of 0.2 m^2 is a speckle to a 2 m detector but a whole footprint to this one.
        min_unseen_area=0.0,
    )
    values.update(overrides)
    return PlannerConfig(**values)
