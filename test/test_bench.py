"""``paramotion bench``: the JSON line carries every headline key with the right type (speed is
never asserted here), a missing world is reported as not measured, bad options are refused."""
import json

from paramotion.cli import main

KEYS = ['fk_single_per_s', 'fk_batched_per_s', 'kntu_poses_per_s', 'rho_per_s',
        'voronoi_paper_query_s', 'fast_real_time_factor', 'coverage_two_rooms_sim_per_wall']


def _last_json(capsys):
    lines = capsys.readouterr().out.strip().splitlines()
    return json.loads(lines[-1]), lines


def test_bench_quick_json_has_every_key_as_a_positive_number(capsys):
    assert main(['bench', '--json', '--quick']) == 0
    res, lines = _last_json(capsys)
    assert res['not_measured'] == {}
    for key in KEYS:
        assert isinstance(res[key], float) and res[key] > 0, key
    assert isinstance(res['cpu_count'], int) and res['usable_cores'] >= 1
    assert res['quick'] is True
    assert any(line.startswith('FK batched solves/s') for line in lines)


def test_missing_world_and_bad_options(capsys, tmp_path):
    assert main(['bench', '--json', '--quick', '--only', 'kntu']) == 0
    res, _ = _last_json(capsys)
    assert isinstance(res['kntu_poses_per_s'], float)
    assert 'fk_single_per_s' not in res
    assert main(['bench', '--only', 'coverage', '--world', str(tmp_path / 'none.json')]) == 2
    assert 'no such file' in capsys.readouterr().err
    assert main(['bench', '--only', 'warp']) == 2
    assert "unknown ['warp']" in capsys.readouterr().err


def test_coverage_without_world_is_null_with_reason(monkeypatch, capsys, tmp_path):
    import paramotion.bench as bench
    monkeypatch.setattr(bench, 'PACKAGED_WORLD', tmp_path / 'absent.json')
    assert main(['bench', '--json', '--quick', '--only', 'coverage']) == 0
    res, lines = _last_json(capsys)
    assert res['coverage_two_rooms_sim_per_wall'] is None
    assert 'world' in res['not_measured']['coverage']
    assert any('not measured' in line for line in lines)


def test_table_without_json_has_no_json_line(capsys):
    assert main(['bench', '--quick', '--only', 'kntu']) == 0
    out = capsys.readouterr().out
    assert 'KNTU cow poses/s' in out and '{' not in out
