"""The paper planner (coverage_pkg/algorithm1.py): Algorithm 1 of Acar, Choset and Lee driven by
sensed events alone; its pieces and a closed loop on a hand-made world."""
import math
from pathlib import Path

import numpy as np
import pytest

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner, TracedPaths
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.sonar import SonarRing
from coverage_pkg.world import load_world, world_from_dict
from paramotion.errors import UserError

DOOR_ROOMS = Path(__file__).resolve().parents[1] / 'coverage_pkg' / 'worlds' / 'door_rooms.json'


def _planner(**kw):
    ring = SonarRing()
    return PaperPlanner(PaperConfig(**kw), ring.mount_angles(), ring.beam_width,
                        ring.min_range, ring.max_range)


def test_bad_without_is_refused_with_one_line():
    with pytest.raises(UserError, match='without "cusps" must be one of cusp, critical, meet'):
        _planner(without=('cusps',))


@pytest.mark.parametrize('echo, kind', [(4.0, 'vast'), (1.5, 'narrow')])
def test_create_node_takes_its_kind_from_the_ring_distance(echo, kind):
    """CreateNode(x, D(x)): vast where D > delta, narrow otherwise (Section IV-A)."""
    p = _planner()
    p.on_odometry(0.0, 0.0, 0.0, 0.0)
    for k in range(12):
        p.on_odometry(0.1 * k, 0.0, 0.0, 0.0)
        p.on_sweep(0.1 * k, np.full(16, echo))
        p.update(0.1 * k)
    assert [n.kind for n in p.nodes] == [kind]
    assert p.nodes[0].created_by is None         # the start: no event created it


def test_traced_paths_join_samples_only_inside_the_disk_the_ring_saw_free():
    paths = TracedPaths(clearance=0.35)
    for x in np.arange(0.0, 3.2, 0.32):          # along a wall: D = 0.6 m everywhere
        paths.add(float(x), 0.0, 0.6)
    route = paths.route(paths.nearest((0.0, 0.0)), paths.nearest((2.88, 0.0)))
    wide = TracedPaths(clearance=0.35)
    for x in np.arange(0.0, 3.2, 0.32):          # in the open: D = 3 m
        wide.add(float(x), 0.0, 3.0)
    hops = wide.route(0, len(wide.xy) - 1)
    steps = [math.dist(a, b) for a, b in zip(hops, hops[1:])]
    assert max(steps) > 1.0 and max(steps) <= wide.hop + 1e-9   # shortcuts, up to one hop
    steps = [math.dist(a, b) for a, b in zip(route, route[1:])]
    assert max(steps) <= 0.32 + 1e-9            # no shortcut: 0.64 m > D - clearance
    assert route[0] == (0.0, 0.0) and route[-1] == pytest.approx((2.88, 0.0))


@pytest.mark.slow
def test_rooms_and_corridor_are_covered_by_sensed_events_alone():
    """The start is vast (D > delta): its boundary circuit senses the room's corner cusps and
    the corridor's; every other node was created by one of those cusp events, and each edge
    carries the cusp that created it."""
    r = run_kinematic(load_world(DOOR_ROOMS), PaperConfig(), max_time=600)
    p = r['planner']
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    g = p.to_dict()
    start, *others = g['nodes']
    assert start['kind'] == 'vast' and start['created_by_event'] is None
    for n in others:
        ev = p.events[n['created_by_event']]
        assert ev[1] == 'cusp' and math.dist(ev[2:4], n['anchor']) < 1e-3
    assert sum(n['kind'] == 'vast' for n in g['nodes']) == 2     # the room beyond the corridor
    assert len(g['edges']) == len(others)
    for e in g['edges']:
        kinds = {g['nodes'][e['vast']]['kind'], g['nodes'][e['narrow']]['kind']}
        assert kinds == {'vast', 'narrow'}
    assert all(n['covered'] and n['closed_by_event'] is not None for n in g['nodes'])
    prim = p.primitive_lengths()
    assert set(prim) <= {'lap', 'boundary', 'gvd', 'transit'} and prim['gvd'] > 4.0


@pytest.mark.slow                         # a closed-loop run, 10-25 s
def test_obstacles_a_lap_runs_into_are_followed_and_their_slices_resumed_beyond():
    """A 15 x 15 m hall with four pillars 5 m apart: each pillar is met by a lap (a critical
    point: the slice splits), gets its own boundary circuit, and the slice is resumed on its
    far side, so the hall is covered."""
    pillars = [[[cx - 0.4, cy - 0.4], [cx + 0.4, cy - 0.4], [cx + 0.4, cy + 0.4],
                [cx - 0.4, cy + 0.4]] for cx in (5.0, 10.0) for cy in (5.0, 10.0)]
    world = world_from_dict({'name': 'pillars', 'boundary': [[0, 0], [15, 0], [15, 15], [0, 15]],
                             'obstacles': pillars, 'start': [2.5, 2.5]})
    r = run_kinematic(world, PaperConfig(), max_time=900)
    vast = r['planner'].nodes[0]
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    assert len(vast.circuits) == 5                    # the hall's boundary and each pillar's
    for circ in vast.circuits[1:]:
        ev = r['planner'].events[circ['opened_by']]
        assert ev[1] == 'critical' and 'split' in ev[4]
        assert min(math.dist(ev[2:4], (cx, cy)) for cx in (5, 10) for cy in (5, 10)) < 1.0
