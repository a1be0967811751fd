"""The paper planner's hierarchical decomposition graph on hand-made worlds equals the graph
computed by hand from the paper's definitions (Sections IV-V, Fig. 12, 13), node by node in the
order the robot creates them (ROS-free loop, delta = 2 m).

Hand rules used below: a corner of the walls (interior angle 90 degrees) has a GVD edge along
its bisector, and its cusp point (D = delta) lies delta from both walls; a corridor of
half-width w has its GVD on the centre line, and where it opens onto a room past a wall's end
the cusp lies sqrt(delta^2 - w^2) beyond that end. Each corner's GVD edge is its own narrow node
(Fig. 12: 'narrow nodes ... at the corners ... each subgraph has just one GVD edge'); a corridor
is ONE narrow node with an edge to each vast node per cusp it ends at.
"""
import functools
import math
from pathlib import Path

import pytest
from test_coverage_decomposition import T_HALL, TWO_ROOMS

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import load_world, world_from_dict

WORLDS = Path(__file__).resolve().parents[1] / 'coverage_pkg' / 'worlds'
TOL = 0.35          # m, a sensed cusp/anchor against its hand-computed place
S = math.sqrt(2.0 ** 2 - 0.75 ** 2)      # corridor half-width 0.75 m: cusp 1.854 m past its end
S1 = math.sqrt(2.0 ** 2 - 1.0 ** 2)      # half-width 1 m: 1.732 m

# TWO_ROOMS: two 8 x 8 m rooms joined by a 4 m corridor 1.5 m wide; T_HALL: a 20 x 6 m
# crossbar on a 3 m wide, 8 m long stem, the robot starts in the stem.
# Fig. 13's layout: a left room with an obstacle in its middle, a corridor 2 m wide that
# splits at a meet point around a block into two corridors 2 m wide, both ending in the right
# room (cusps Cs2 and Cs3).
FIG13 = {'name': 'fig13',
         'boundary': [[0, 0], [12, 0], [12, 6], [14, 6], [14, 4], [18, 4], [18, 0], [30, 0],
                      [30, 14], [18, 14], [18, 10], [14, 10], [14, 8], [12, 8], [12, 14],
                      [0, 14]],
         'obstacles': [[[5, 6], [7, 6], [7, 8], [5, 8]], [[15, 6], [18, 6], [18, 8], [15, 8]]],
         'start': [1.0, 1.0]}


@functools.lru_cache(maxsize=None)
def _run(name, handover=True):
    if name == 'island_hall':       # an 18 x 12 m hall with a 2 x 2 m pillar
        world = load_world(WORLDS / 'island_hall.json')
    else:
        world = world_from_dict({w['name']: w for w in (TWO_ROOMS, T_HALL, FIG13)}[name])
    r = run_kinematic(world, PaperConfig(handover=handover), max_time=1500)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    return r['planner']


def _check_graph(p, nodes, edges):
    """``nodes``: (kind, hand anchor) of the graph's nodes in creation order; ``edges``:
    (vast, narrow, hand cusp) by positions in ``nodes``. Every node after the start was created
    by the cusp event at its anchor; every edge carries a sensed cusp at its hand place; no
    other node or edge exists."""
    alive = [n for n in p.nodes if n.merged_into is None]
    assert [n.kind for n in alive] == [k for k, _ in nodes]
    for n, (_, xy) in zip(alive, nodes):
        assert math.dist(n.anchor, xy) < TOL, (n.id, n.anchor, xy)
    assert alive[0].created_by is None
    for n in p.nodes[1:]:
        ev = p.events[n.created_by]
        assert ev[1] == 'cusp' and math.dist(ev[2:4], n.anchor) < 1e-3
    pos = {n.id: k for k, n in enumerate(alive)}
    got = sorted((pos[p.same_node(v)], pos[w], c) for v, w, c in p.edges)
    assert len(got) == len(edges), got
    for v, w, xy in edges:
        match = [g for g in got if g[:2] == (v, w) and math.dist(g[2], xy) < TOL]
        assert len(match) == 1, (v, w, xy, got)


def _cells(p, node):
    """The Reeb graph of a vast node: per Morse cell (parent cell, kind and place of the
    critical point that opened it, kind and place of the one that closed it)."""
    out = []
    for c in p.nodes[node].cells:
        def crit(idx):
            if idx is None:
                return None
            ev = p.events[idx]
            return (ev[1] if ev[1] != 'critical' else ev[4].split(':')[0], ev[2:4])
        out.append((c.parent, crit(c.opened_by), crit(c.closed_by)))
    return out


@pytest.mark.slow
def test_two_rooms_and_a_corridor_make_the_hand_computed_graph():
    """The start (D = 1 m) is the corner's narrow node; its GVD edge ends at the cusp (2, 2),
    which creates the left room's vast node; that room's boundary circuit senses, in the
    order it passes them, the corners (8, 0), the corridor, (8, 8), (0, 8); the corridor's GVD
    edge ends at the right room's cusp, whose circuit senses its four corners. The corridor
    is one narrow node with an edge to each room."""
    p = _run('two_rooms_corridor')
    _check_graph(p, [('narrow', (1, 1)), ('vast', (2, 2)), ('narrow', (6, 2)),
                     ('narrow', (8 - S, 4)), ('narrow', (6, 6)), ('narrow', (2, 6)),
                     ('vast', (12 + S, 4)), ('narrow', (14, 2)), ('narrow', (18, 2)),
                     ('narrow', (18, 6)), ('narrow', (14, 6))],
                 [(1, 0, (2, 2)), (1, 2, (6, 2)), (1, 3, (8 - S, 4)), (1, 4, (6, 6)),
                  (1, 5, (2, 6)), (6, 3, (12 + S, 4)), (6, 7, (14, 2)), (6, 8, (18, 2)),
                  (6, 9, (18, 6)), (6, 10, (14, 6))])
    # Each room's Reeb graph is one Morse cell, closed where the slice ends at its right wall.
    for node, wall in ((1, 8.0), (6, 20.0)):
        (parent, opened, closed), = _cells(p, node)
        assert parent is None and opened[0] == 'cusp'
        assert closed[0] == 'death' and abs(closed[1][0] - wall) < TOL


@pytest.mark.slow
def test_t_hall_graph_from_the_stem_to_the_crossbar():
    """The stem (3 m wide, D <= 1.5 m) is the start's narrow node; its foot's corners meet at
    the meet point (10, 1.5); its GVD edge ends at the cusp 1.32 m into the crossbar (D = 2 m
    from the stem's wall ends), which creates the crossbar's vast node; the crossbar's circuit
    senses its four corners, right side first."""
    p = _run('t_hall')
    up = 8 + math.sqrt(2.0 ** 2 - 1.5 ** 2)
    _check_graph(p, [('narrow', (10, 1)), ('vast', (10, up)), ('narrow', (18, 10)),
                     ('narrow', (18, 12)), ('narrow', (2, 12)), ('narrow', (2, 10))],
                 [(1, 0, (10, up)), (1, 2, (18, 10)), (1, 3, (18, 12)), (1, 4, (2, 12)),
                  (1, 5, (2, 10))])
    assert [math.dist(m[:2], (10, 1.5)) < TOL for m in p.nodes[0].meets] == [True]
    (parent, opened, closed), = _cells(p, 1)
    assert closed[0] == 'death' and abs(closed[1][0] - 20.0) < TOL


@pytest.mark.slow                     # a closed-loop run, 10-20 s
def test_a_pillar_splits_the_hall_cell_at_its_left_side():
    """One vast node (D(3, 3) = 3 m), four corner narrow nodes. Its Reeb graph: the first
    cell closes at the split critical point on the pillar's left side (x = 8, 5 <= y <= 7);
    the split opens two cells, one below the pillar and one above, each closed by the death
    of its slice at the right wall."""
    p = _run('island_hall')
    _check_graph(p, [('vast', (3, 3)), ('narrow', (2, 2)), ('narrow', (16, 2)),
                     ('narrow', (16, 10)), ('narrow', (2, 10))],
                 [(0, 1, (2, 2)), (0, 2, (16, 2)), (0, 3, (16, 10)), (0, 4, (2, 10))])
    first, below, above = sorted(_cells(p, 0)[:3], key=lambda c: (c[0] is not None,))
    assert first[0] is None and first[2][0] == 'split'
    x, y = first[2][1]
    assert abs(x - 8.0) < TOL and 5.0 - TOL <= y <= 7.0 + TOL
    for parent, opened, closed in (below, above):
        assert parent == 0 and opened == first[2]
        assert closed[0] == 'death' and abs(closed[1][0] - 18.0) < TOL
    assert sorted(c.prev_span[1] < 6.0 for c in p.nodes[0].cells[1:3]) == [False, True]


@pytest.mark.slow                     # a closed-loop run, 20-35 s per mode
@pytest.mark.parametrize('handover', [True, False], ids=['fig13_order', 'algorithm1_order'])
def test_fig13_corridor_is_one_narrow_node_joined_by_both_of_its_cusps(handover):
    """Fig. 13: the corridor's GVD edge from Cs1 reaches the meet point Mp1 (14, 7), whose two
    branches end at the right room's cusps Cs2 (19.73, 5) and Cs3 (19.73, 9). In Fig. 13's
    order (the default) the robot reaches the symmetric fork along +x and takes the
    right-hand, lower branch ('The robot chooses the lower edge, and follows it ... to the
    cusp point Cs2'); Cs2 creates the right room's vast node and the robot covers the room
    from there; the room's circuit senses Cs3 ('Cp6, which is also the cusp point Cs3') and
    creates a narrow node there, whose trace back towards Mp1 joins the corridor's traced
    GVD edge: the two narrow nodes are one cell, the later one merges into the corridor's
    node and its edge to the room is the corridor's. In Algorithm 1's order (``handover``
    off: the corridor traced whole first) the robot takes the lower edge first too, so both
    cusps create a vast node, Cs2's first, and the trace ends at Cs3, whose node is nearest and
    covered first; its circuit finds Cs2's node is the same cell. Either way the graph: two
    vast nodes, one corridor node with three edges, the corner nodes."""
    p = _run('fig13', handover)
    room = (18 + S1, 5) if handover else (18 + S1, 9)
    _check_graph(p, [('narrow', (1, 1)), ('vast', (2, 2)), ('narrow', (10, 2)),
                     ('narrow', (12 - S1, 7)), ('narrow', (10, 12)), ('narrow', (2, 12)),
                     ('vast', room), ('narrow', (20, 2)), ('narrow', (28, 2)),
                     ('narrow', (28, 12)), ('narrow', (20, 12))],
                 [(1, 0, (2, 2)), (1, 2, (10, 2)), (1, 3, (12 - S1, 7)), (1, 4, (10, 12)),
                  (1, 5, (2, 12)), (6, 3, (18 + S1, 9)), (6, 3, (18 + S1, 5)),
                  (6, 7, (20, 2)), (6, 8, (28, 2)), (6, 9, (28, 12)), (6, 10, (20, 12))])
    corridor = p.nodes[3]
    hand = [(14, 7), (15, 9), (15, 5)]          # Mp1 and the two bends around the block
    assert sorted(min(range(3), key=lambda k: math.dist(m[:2], hand[k]))
                  for m in corridor.meets) == [0, 1, 2]
    assert all(min(math.dist(m[:2], h) for h in hand) < TOL for m in corridor.meets)
    # At Mp1 the robot takes the lower edge: the first branch to end at a cusp in the right
    # room ends at Cs2.
    first = next(e for e in p.events if e[1] == 'branch_end' and e[4].endswith('cusp') and
                 e[2] > 18)
    assert math.dist(first[2:4], (18 + S1, 5)) < TOL, first
    # The corridor is traced to both of its cusps in the right room: a branch ends at Cs2
    # (traced from Cs1 through Mp1) and one starts or ends at Cs3 (traced from the room).
    for cusp in ((18 + S1, 9), (18 + S1, 5)):
        assert any(math.dist(b.start, cusp) < TOL or (b.end == 'cusp' and
                                                       math.dist(b.end_xy, cusp) < TOL)
                   for b in corridor.branches), cusp
    assert [n.merged_into for n in p.nodes if n.kind == 'narrow' and
            n.merged_into is not None] in ([], [3])
    # Creation order: the left room's nodes, the corridor, then the right room's (Fig. 13).
    assert [n.id for n in p.nodes if n.kind == 'vast'][:2] == [1, 6]
    split = [c for c in p.nodes[1].critical if c[2].startswith('split')]
    assert split and abs(split[0][0] - 5.0) < 1.0 and 6.0 - TOL <= split[0][1] <= 8.0 + TOL
