"""The paper planner's selectable modes end to end: ``rules=paper`` (every sensing rule of ours
set to the paper's reading), ``ours=on`` (the modes of ours that are off in the default, on)
and single switches, from the command line, the launch argument and the node parameter
``modes`` down to the PaperConfig the planner runs with."""
import json
from pathlib import Path

import pytest

from coverage_pkg.algorithm1 import MODE_FIELDS, OUR_MODES, PAPER_RULES, PaperConfig, parse_modes
from paramotion.cli import main as cli_main
from paramotion.errors import ParameterError, UserError

WORLDS = Path(__file__).resolve().parents[1] / 'coverage_pkg' / 'worlds'
DOOR_ROOMS = str(WORLDS / 'door_rooms.json')
DEMO_ROOMS = str(WORLDS / 'demo_rooms.json')


def test_paper_rules_set_every_rule_of_ours_the_default_has_on():
    """rules=paper changes each switch of ours that is on in the default (docs: the rules of
    ours, on) and nothing else; every switch it sets is a mode field."""
    base = PaperConfig()
    assert set(PAPER_RULES) <= set(MODE_FIELDS)
    assert all(getattr(base, k) != v for k, v in PAPER_RULES.items())
    ours_on = {'meet_scan', 'sliver_openings', 'circuit_join', 'cusp_meet', 'meet_margin',
               'circuit_same_way', 'circuit_same_side', 'meet_side_pair', 'way_come_held',
               'meet_own_obstacles'}
    assert set(PAPER_RULES) == ours_on


def test_ours_on_sets_every_mode_of_ours_the_default_has_off_and_nothing_else():
    """ours=on turns on the seven modes of ours (docs: our planner beside the paper's), each
    off in the default and none of the paper's rules; ours=off puts them back."""
    base = PaperConfig()
    assert set(OUR_MODES) <= set(MODE_FIELDS)
    assert all(getattr(base, k) is False and v is True for k, v in OUR_MODES.items())
    assert not set(OUR_MODES) & set(PAPER_RULES)
    assert set(OUR_MODES) == {'traced_way', 'circuit_sweeps', 'cusp_edge_traced',
                              'cusp_meet_gap', 'pinch_ends_cell', 'fork_at_meet',
                              'start_on_gvd'}
    assert parse_modes('ours=on') == OUR_MODES
    assert parse_modes('ours=on,start_on_gvd=false') == {**OUR_MODES, 'start_on_gvd': False}
    assert parse_modes(['ours=on', 'ours=off']) == {k: False for k in OUR_MODES}
    assert parse_modes('rules=paper,ours=on') == {**PAPER_RULES, **OUR_MODES}


def test_later_modes_override_earlier_ones():
    assert parse_modes('rules=paper,meet_scan=true') == {**PAPER_RULES, 'meet_scan': True}
    assert parse_modes(['meet_scan=false', 'rules=ours']) == {
        k: getattr(PaperConfig(), k) for k in PAPER_RULES}
    assert parse_modes(['handover=false', 'meet_margin=0.05']) == {
        'handover': False, 'meet_margin': 0.05}
    assert parse_modes('') == {}


@pytest.mark.parametrize('text, words', [
    ('handover', 'mode "handover" must be NAME=VALUE'),
    ('rules=strict', 'rules takes paper or ours'),
    ('ours=all', 'ours takes on or off'),
    ('view_margin=0.1', 'view_margin is not a mode of the paper planner'),
    ('meet_scan=maybe', 'meet_scan takes true or false'),
    ('meet_margin=-0.1', 'meet_margin must be finite and >= 0'),
    ('meet_margin=nan', 'meet_margin must be finite and >= 0'),
])
def test_a_bad_mode_is_named_in_one_line(text, words):
    with pytest.raises(UserError, match=words) as info:
        parse_modes(text)
    assert '\n' not in str(info.value)


def test_the_launch_argument_reaches_the_planner_node():
    from paramotion import launch_xml
    desc = launch_xml.load('coverage', {'modes': 'rules=paper,handover=false'})
    assert desc.node('coverage_planner').params['modes'] == 'rules=paper,handover=false'
    assert launch_xml.load('coverage').node('coverage_planner').params['modes'] == ''


def test_the_planner_node_runs_the_modes_it_is_given():
    from coverage_pkg.planner_node import CoveragePlannerNode
    from paramotion.graph import Graph
    with Graph() as graph:
        node = graph.add(CoveragePlannerNode, modes='rules=paper,handover=false')
        cfg = node.config
        assert {k: getattr(cfg, k) for k in PAPER_RULES} == PAPER_RULES
        assert cfg.handover is False
        ours = graph.add(CoveragePlannerNode, name='coverage_planner_ours', modes='ours=on')
        assert ours.config == PaperConfig(**OUR_MODES)
        default = graph.add(CoveragePlannerNode, name='coverage_planner_default')
        assert default.config == PaperConfig()


@pytest.mark.parametrize('params, words', [
    ({'modes': 'meet_scan=maybe'}, "parameter 'modes': mode \"meet_scan=maybe\": meet_scan "
     'takes true or false'),
    ({'modes': 'delta=3'}, "parameter 'modes': .*delta is not a mode"),
    ({'planner': 'grid', 'modes': 'rules=paper'}, "'modes' applies to planner 'paper' only"),
])
def test_the_planner_node_refuses_a_bad_mode(params, words):
    from coverage_pkg.planner_node import CoveragePlannerNode
    from paramotion.graph import Graph
    with Graph() as graph:
        with pytest.raises(ParameterError, match=words):
            graph.add(CoveragePlannerNode, **params)


@pytest.mark.parametrize('extra, words', [
    (['--mode', 'bogus=1'], '--mode: mode "bogus=1": bogus is not a mode'),
    (['--planner', 'grid', '--mode', 'rules=paper'], '--mode: applies to --planner paper only'),
])
def test_a_bad_mode_on_the_command_line_stops_before_anything_runs(tmp_path, capsys, extra,
                                                                   words):
    out = tmp_path / 'out'
    code = cli_main(['coverage', '--world', DOOR_ROOMS, '--out', str(out)] + extra)
    err = capsys.readouterr().err.strip()
    assert code == 2 and words in err and len(err.splitlines()) == 1
    assert not out.exists()


def _covered_in_the_ros_graph(tmp_path, world, mode, modes):
    """``paramotion coverage --world world --mode mode`` (the ROS graph, one executor): its
    result, after checking that the run is complete, covers >= 99 % of CVS and records the
    ``modes`` the planner node ran with (read from its configuration)."""
    out = tmp_path / 'out'
    code = cli_main(['coverage', '--world', world, '--mode', mode, '--out', str(out)])
    r = json.loads((out / 'result.json').read_text())
    assert r['modes'] == modes
    assert code == 0 and r['outcome'] == 'complete'
    assert r['covered_fraction_of_cvs'] >= 0.99
    return r


def test_the_papers_rules_alone_cover_two_rooms_and_a_corridor_in_the_ros_graph(tmp_path):
    """Closed loop, the ROS graph: with every rule of ours off the planner still senses the
    corridor's cusps and the rooms' events and covers the world (99.97 % here); the result
    records the modes the planner node ran with, read from its configuration."""
    r = _covered_in_the_ros_graph(tmp_path, DOOR_ROOMS, 'rules=paper', PAPER_RULES)
    kinds = [e[1] for e in r['events']]
    assert kinds.count('node_created') >= 2 and 'cusp' in kinds


def test_a_runs_label_names_its_ablations_and_modes():
    """The figure title and the summary line of a run name what was switched, so that a
    picture of an ablation or of our planner is never taken for the default's."""
    from coverage_pkg.figure import planner_label
    assert planner_label('paper') == 'paper planner'
    assert planner_label('grid', (), ()) == 'grid planner'
    assert planner_label('paper', ('cusp', 'meet'), ['ours=on']) == \
        'paper planner, without cusp,meet, modes ours=on'


def test_our_planner_covers_the_demo_world_without_laps_in_the_ros_graph(tmp_path, capsys):
    """Closed loop, the ROS graph, ours=on (our planner beside the paper's): the demo world
    is covered and no lap is driven, since each room lies within delta - 0.2 m of its
    boundary circuit (circuit_sweeps; the default drives laps there, 0.18 times the bound in
    the ROS-free loop); the result records the seven modes the planner node ran with."""
    r = _covered_in_the_ros_graph(tmp_path, DEMO_ROOMS, 'ours=on', OUR_MODES)
    assert '(paper planner, modes ours=on, extended detector): complete' in \
        capsys.readouterr().out
    assert r['primitive_lengths_m'].get('lap', 0.0) == 0.0
    assert r['primitive_lengths_m']['boundary'] > 0.0
