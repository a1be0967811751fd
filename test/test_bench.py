"""``paramotion bench``: the JSON line carries every headline key with the right type (speed is
never asserted here), a missing world is reported as not measured, bad options are refused."""
import json

import pytest

from paramotion.cli import main

KEYS = ['fk_single_per_s', 'fk_batched_per_s', 'kntu_poses_per_s', 'rho_per_s',
        'voronoi_paper_query_s', 'fast_real_time_factor', 'fast_real_time_factor_cpu',
        'coverage_two_rooms_sim_per_wall', 'climber_sim_per_wall']


def _last_json(capsys):
    lines = capsys.readouterr().out.strip().splitlines()
    return json.loads(lines[-1]), lines


@pytest.mark.slow
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
    import coverage_pkg.bench
    monkeypatch.setattr(coverage_pkg.bench, 'PACKAGED_WORLD', tmp_path / 'absent.json')
    assert main(['bench', '--json', '--quick', '--only', 'coverage']) == 0
    res, lines = _last_json(capsys)
    assert res['coverage_two_rooms_sim_per_wall'] is None
    assert 'world' in res['not_measured']['coverage']
    assert any('not measured' in line for line in lines)


def test_table_without_json_has_no_json_line(capsys):
    assert main(['bench', '--quick', '--only', 'kntu']) == 0
    out = capsys.readouterr().out
    assert 'KNTU cow poses/s' in out and '{' not in out


def test_shared_package_imports_no_robot_package():
    """paramotion/ is what every robot shares: none of its modules imports a robot package
    (the CLI and the bench/report dispatchers name modules as strings)."""
    import ast
    from pathlib import Path

    import paramotion
    robots = {'coverage_pkg', 'climber_pkg', 'cable_robot_pkg', 'voronoi_pkg'}
    offenders = []
    for path in Path(paramotion.__file__).parent.rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ''] if isinstance(node, ast.ImportFrom) else []
            offenders += [f'{path.name}: {n}' for n in names if n.split('.')[0] in robots]
    assert offenders == []


@pytest.mark.slow
def test_write_report_measures_each_lever_on_the_lockstep_benchmarks(monkeypatch, tmp_path):
    """The performance page: every figure, then one row per Graph lever, each measured with
    that lever's Graph defaults in force (seen by the benchmark itself)."""
    import types

    import paramotion.bench as bench
    import paramotion.graph as graph
    seen = []

    def smoke(quick, options):
        from paramotion.smoke.scenario import run_lockstep
        seen.append(dict(graph.GRAPH_DEFAULTS))
        res = run_lockstep(None, duration=0.5)
        return {'smoke_sim_s': float(res['sim_time_s'])}

    fake = types.SimpleNamespace(
        BENCHES={'smoke': (smoke, {'smoke_sim_s': 'smoke sim s'})}, LOCKSTEP=('smoke',),
        report_lines=lambda quick, log: ['## Extra table', '', '| a |', '|---|', '| 1 |'])
    monkeypatch.setattr(bench, 'bench_modules', lambda: [fake])
    paths = bench.write_report(tmp_path, quick=True)
    text = (tmp_path / 'performance.md').read_text()
    assert paths == [tmp_path / 'performance.md']
    assert [s['executor'] for s in seen] == ['lockstep'] + [v['executor'] for _, v in
                                                            bench.LEVERS]
    assert [s['direct_time'] for s in seen[1:]] == [v['direct_time'] for _, v in bench.LEVERS]
    for label, _ in bench.LEVERS:
        assert f'| {label} | 0.500 |' in text
    assert '| smoke sim s | 0.500 |' in text and '## Extra table' in text
    assert 'Machine:' in text and 'paramotion report --only performance --quick' in text
    assert graph.GRAPH_DEFAULTS['executor'] == graph.DEFAULT_EXECUTOR   # restored
