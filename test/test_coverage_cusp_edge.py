"""A cusp a circuit sensed, then reached by a trace along its GVD edge, is one narrow cell.

The world is gen_halls_6048's shape: a T of halls, the stem 4.3 m wide above a crossbar
3.4 m high with a pillar in the crossbar below the stem. The robot starts in the stem, a
vast cell; its boundary circuit senses the cusps where the GVD edges round the pillar leave
the stem and creates a narrow node at each. The first of them is traced round the pillar's
left, along the crossbar, and back up the pillar's right side into the cusp of another of
those nodes, (6.3, 4.9), from its other end. A cusp joins one vast cell and one narrow cell
(Section IV-C): the two narrow nodes are one, and the cusp's own branch is the edge just
traced, so the robot does not drive it again (switch ``cusp_edge_traced``, ours, off by
default: without it, the node is covered on its own and merged when its trace joins).
"""
import math

import pytest

from coverage_pkg.algorithm1 import PaperConfig
from coverage_pkg.kinematic import run_kinematic
from coverage_pkg.world import world_from_dict

T_PILLAR = {'name': 't_pillar', 'start': [5.434, 5.973],
            'boundary': [[10.932, 3.381], [10.932, 0.0], [0.0, 0.0], [0.0, 3.381],
                         [3.947, 3.381], [3.947, 8.319], [8.275, 8.319], [8.275, 3.381]],
            'obstacles': [[[6.785, 2.971], [6.502, 2.905], [6.307, 2.71], [6.242, 2.479],
                           [6.475, 2.025], [7.186, 2.172]]]}
CUSP = (6.3, 4.9)


def _cusp_node(r):
    return next(n for n in r['planner'].nodes
                if n.kind == 'narrow' and math.dist(n.anchor, CUSP) < 0.3)


@pytest.mark.slow                         # two closed-loop runs, about 10 s
def test_a_cusp_reached_along_its_edge_merges_its_node_and_its_branch_is_not_driven():
    """The trace that ends at the circuit's cusp merges that cusp's narrow node into its
    own (a same_cell event naming the cusp's edge), and the cusp's branch ends 'traced' where
    it starts (switch ``cusp_edge_traced``). Without it, the node stays apart, its branch is
    driven from the cusp along the edge traced already, and the path is longer."""
    r = run_kinematic(world_from_dict(T_PILLAR), PaperConfig(cusp_edge_traced=True),
                      max_time=3000)
    assert r['state'] == 'done' and r['covered_fraction'] >= 0.99
    pl = r['planner']
    m = _cusp_node(r)
    assert m.merged_into is not None and m.covered
    assert any(e[1] == 'same_cell' and f'narrow node {m.id} ' in e[4] and 'cusp' in e[4]
               for e in pl.events)
    own = [b for n in pl.nodes for b in n.branches if math.dist(b.start, CUSP) < 0.3]
    assert own and all(b.end == 'traced' and b.end_xy == b.start for b in own)

    off = run_kinematic(world_from_dict(T_PILLAR), PaperConfig(cusp_edge_traced=False),
                        max_time=3000)
    assert off['state'] == 'done' and off['covered_fraction'] >= 0.99
    assert not any(e[1] == 'same_cell' and 'cusp' in e[4] for e in off['planner'].events)
    driven = [b for n in off['planner'].nodes for b in n.branches
              if math.dist(b.start, CUSP) < 0.3 and b.end is not None
              and b.end_xy is not None and math.dist(b.end_xy, b.start) > 1.0]
    assert driven                         # the cusp's edge traced a second time
    assert off['path_length'] > r['path_length'] + 2.0
