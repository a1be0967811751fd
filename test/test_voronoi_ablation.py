"""Ablations (``--without NAME``, node/launch parameter ``without``): each construct of the
paper switched off fails the way the paper says. Without the singularity factors of P1 the
planner joins configurations across the base-line singularity (the paper's forbidden region
for a parallel robot); without the collision predicates of P2 it plans through a wall. Both
failures are found by the independent direct-geometry checker."""
import json
import math

import numpy as np
import pytest
from test_voronoi_planner import SQUARE, independent_check

from paramotion.cli import main as cli_main
from paramotion.errors import UserError
from voronoi_pkg.planar import PAPER_START, Domain, paper_model, planar_model
from voronoi_pkg.planner import VoronoiPlanner

COARSE = {'h': 1.5, 'dphi_deg': 5.0}


def test_without_singularity_the_path_crosses_the_base_line():
    goal = (-10.0, 15.0, -math.pi / 2)           # P3 above the base line, the start below
    res = VoronoiPlanner(paper_model(), **COARSE).plan(PAPER_START, goal)
    assert res.status == 'no_path' and res.stats['decided_by'] == 'singularity certificate'
    res = VoronoiPlanner(paper_model(without=['singularity']), **COARSE).plan(PAPER_START, goal)
    assert res.found, res.reason
    assert 'base line' in independent_check(res.path)


def test_without_collision_the_path_goes_through_a_wall():
    """A wall across the square between start and goal (same singularity cell): with P2 the
    diagram search answers no path; without P2 the planner returns a path through the wall."""
    wall = [(-30.0, -22.0), (60.0, -22.0), (60.0, -18.0), (-30.0, -18.0)]
    start, goal = (30.0, -10.0, 1.0), (30.0, -32.0, 1.0)

    def model(without=()):
        return planar_model(((0.0, 0.0), (15.0, 0.0)), 10.0, [tuple(p) for p in SQUARE],
                            [wall], Domain(), without=without)

    res = VoronoiPlanner(model(), **COARSE).plan(start, goal)
    assert res.status == 'no_path' and res.stats['decided_by'] == 'diagram search'
    res = VoronoiPlanner(model(['collision']), **COARSE).plan(start, goal)
    assert res.found, res.reason
    assert 'obstacle segment' in independent_check(res.path, obstacles=[wall])


@pytest.mark.parametrize('without, words', [
    (['bogus'], "unknown construct 'bogus'"),
    (['singularity', 'collision'], 'no predicate'),
])
def test_bad_ablations_are_refused(without, words):
    with pytest.raises(UserError, match=words):
        paper_model(without=without)


def test_cli_without_is_recorded_and_bad_names_give_one_line(tmp_path, capsys):
    out = tmp_path / 'o'
    code = cli_main(['voronoi', 'plan', '--start', '35', '-20', '90', '--goal', '-10', '-15',
                     '-90', '--grid', '3', '--slice-deg', '15', '--no-figures',
                     '--without', 'singularity', '--out', str(out)])
    assert code == 0
    doc = json.loads((out / 'result.json').read_text())
    assert doc['without'] == ['singularity']
    assert np.isfinite(doc['min_rho'])
    capsys.readouterr()
    code = cli_main(['voronoi', 'plan', '--start', '35', '-20', '90', '--goal', '-10', '-15',
                     '-90', '--without', 'walls', '--out', str(tmp_path / 'never')])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'walls' in err[0]
    assert not (tmp_path / 'never').exists()


def test_a_wall_crossed_while_parallel_is_caught_between_samples():
    """At phi = -90 deg the platform is parallel to the left wall: the collision set of that
    slice is the line x = -25, which rho samples 0.05 apart step over. The swept check
    refuses the step, and the independent checker agrees."""
    model = paper_model()
    a = np.array([[-24.99, -2.8, -math.pi / 2]])
    b = np.array([[-25.04, -2.8, -math.pi / 2]])
    assert model.rho(a)[0] > 0 and model.rho(b)[0] > 0
    assert model.swept_hits(a, b)[0]
    assert 'sweeps' in independent_check(np.vstack([a, b]))
    inside = np.array([[-24.0, -2.8, -math.pi / 2]])
    assert not model.swept_hits(a, inside)[0]
