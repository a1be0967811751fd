"""``paramotion coverage sweep --planner``: the sweep runs the planner it is given."""
import json
import shutil
from pathlib import Path

import pytest

from paramotion.cli import main

WORLDS = Path(__file__).resolve().parents[1] / 'coverage_pkg' / 'worlds'


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
