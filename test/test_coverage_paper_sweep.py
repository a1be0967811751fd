"""``paramotion coverage sweep --planner``: the sweep runs the planner it is given."""
import json
import shutil
from pathlib import Path

import pytest

from paramotion.cli import main

WORLDS = Path(__file__).resolve().parents[1] / 'coverage_pkg' / 'worlds'


@pytest.mark.slow
def test_sweep_runs_the_paper_planner_when_asked(tmp_path, capsys):
    worlds = tmp_path / 'worlds'
    worlds.mkdir()
    shutil.copy(WORLDS / 'door_rooms.json', worlds)
    out = tmp_path / 'out'
    assert main(['coverage', 'sweep', '--worlds', str(worlds), '--planner', 'paper',
                 '--max-sim-time', '15', '--serial', '--out', str(out)]) == 0
    summary = json.loads((out / 'summary.json').read_text())
    result = json.loads((out / 'door_rooms.json').read_text())
    assert summary['planner'] == 'paper' and result['planner'] == 'paper'
    # The paper planner's graph: its nodes carry the event that created them.
    assert 'created_by_event' in result['hierarchical_graph']['nodes'][0]
    with pytest.raises(SystemExit):
        main(['coverage', 'sweep', '--worlds', str(worlds), '--planner', 'cells', '--serial',
              '--out', str(tmp_path / 'bad')])
    assert "--planner: invalid choice: 'cells'" in capsys.readouterr().err


def test_paper_measure_reads_seed_ranges_and_measures_a_world():
    """``python -m coverage_pkg.paper_measure --seeds ...``: seed lists and ranges; one world's
    row carries issue 28's figures."""
    from coverage_pkg.paper_measure import measure_world, parse_seeds
    assert parse_seeds('100-102,300') == [100, 101, 102, 300]
    row = measure_world(100, max_time=20.0)
    assert row['world'] == 'gen_mixed_100' and 0.0 < row['covered'] < 1.0
    assert 0.0 <= row['primitive'] <= 1.0 and 0.0 < row['median_ms'] <= row['p99_ms']


def test_paper_measure_reads_world_files_and_refuses_a_bad_one(tmp_path, capsys):
    """``--world FILE.json`` measures a world file instead of generated seeds; a bad file
    stops the command with one line naming it, before any run."""
    from coverage_pkg.paper_measure import main, measure_world
    world = WORLDS / 'pillar_room.json'
    row = measure_world(str(world), max_time=10.0)
    assert row['world'] == 'pillar_room' and 0.0 < row['covered'] < 1.0
    bad = tmp_path / 'bad.json'
    bad.write_text('{"name": "bad", "boundary": [[0, 0], [1, 0]], "obstacles": [], '
                   '"start": [0.5, 0.5]}')
    with pytest.raises(SystemExit) as exc:
        main(['--world', str(world), '--world', str(bad)])
    assert str(exc.value).startswith('paper_measure: ') and 'bad.json' in str(exc.value)
    assert '\n' not in str(exc.value) and capsys.readouterr().out == ''


def test_paper_measure_floor_adds_the_floor_the_walks_and_the_paths_split(capsys):
    """``--floor``: seven more columns, the floor of Algorithm 1 (a multiple of the bound,
    below the path's), path / floor, the two nearest-first walks (at or above the floor),
    the floor's required length (below the floor) and the path split into ground driven for
    the first time and driven again (adding up to the path); header, rule and rows have as
    many columns."""
    from coverage_pkg.paper_measure import main
    main(['--world', str(WORLDS / 't_hall.json'), '--floor'])
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].endswith('| floor/bound | path/floor | nearest-first/bound | '
                             'circuits-first/bound | required/bound | first-time/bound | '
                             'again/bound |')
    assert len({line.count('|') for line in lines}) == 1
    cells = [c.strip() for c in lines[2].split('|')]
    ratio = float(cells[4])
    floor, over, walk, circuits, required, first, again = (float(c) for c in cells[-8:-1])
    assert 1.0 < floor < ratio and over == pytest.approx(ratio / floor, abs=0.01)
    assert floor <= walk + 0.01 and floor <= circuits + 0.01
    assert 0.0 < required <= floor
    # the T's stem and one arm are traced out and back: ground is driven again
    assert again > 0.1 and first + again == pytest.approx(ratio, abs=0.011)
