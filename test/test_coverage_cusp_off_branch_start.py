"""A cusp crossed off a branch's start, while the robot still drives along the branch's
bearing, leads into its narrow cell along the path behind (EventSensing._trace_heading,
TraceGVD._way_in).

The world is gen_halls_5102's shape: an L of a tower 4.4 m wide and 7.05 m high and a hall
2.69 m high running east from its foot. The points more than delta (2 m) from every wall in
the tower form a vast strip 0.4 m across; its top tip lies between the cusps of the tower's
two top corners, (2.0, 5.05) and (2.4, 5.05). The robot starts in the top-right corner's
narrow cell, traces that corner's dead end, comes back and leaves along the branch towards
the strip; 0.35 m on D crosses delta, where the two closest walls are already the top and
the left one.
"""
import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

L_HALL = {'name': 'l_hall_tower', 'start': [2.42, 6.27],
          'boundary': [[9.6, 2.69], [9.6, 0.0], [0.0, 0.0], [0.0, 7.05], [4.4, 7.05],
                       [4.4, 2.69]],
          'obstacles': []}


def _to_top_left(r):
    """How near the robot came to the tower's top-left corner (0, 7.05)."""
    path = np.asarray(r['path'])
    return float(np.hypot(path[:, 0], path[:, 1] - 7.05).min())


@pytest.mark.slow                         # two closed-loop runs, about 3 s
def test_a_cusp_crossed_off_a_branch_start_is_the_edge_come_along(monkeypatch):
    """Read from the path behind, the cusp's way in is the top-right corner's edge; the
    circuit senses the top-left corner's cusp as a new one, its narrow cell is traced and
    the world is covered. With the GVD law's pair of closest obstacles read there instead
    (no heading yet off the branch's start), the cusp claims the top-left corner's edge,
    the circuit's cusp there is known, and the corner stays unentered."""
    r = run_kinematic(world_from_dict(L_HALL), PaperConfig(), max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert _to_top_left(r) < 2.0

    monkeypatch.setattr(PaperPlanner, '_trace_heading',
                        lambda self: self.task.get('heading') if self.mode == 'gvd' else None)
    off = run_kinematic(world_from_dict(L_HALL), PaperConfig(), max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] < 0.99
    assert _to_top_left(off) > 2.3
