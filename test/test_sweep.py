"""The shared Dask sweep runner: results in case order and equal to the serial run, errors
raised, a private ROS domain per case, and ``paramotion fast sweep`` identical on Dask."""
import json
import time

import pytest

from paramotion.cli import main
from paramotion.errors import UserError
from paramotion.sweep import chunked, run_tasks

pytestmark = pytest.mark.slow  # local Dask clusters of worker processes


def _square_slowly(case):
    # Later cases finish first, so case order must come from the runner, not completion order.
    time.sleep(0.05 * (3 - case))
    return {'case': case, 'square': case * case}


def _fail_on_two(case):
    if case == 2:
        raise ValueError('case 2 is bad')
    return case


def _ros_names(tag):
    """A node named after ``tag`` in its own Graph context; the node names it can see."""
    import rclpy

    from paramotion.graph import Graph
    with Graph() as graph:
        node = rclpy.create_node(f'sweep_probe_{tag}', context=graph.context)
        try:
            deadline = time.monotonic() + 1.5
            seen = set()
            while time.monotonic() < deadline:  # give other workers' nodes a chance to show up
                seen |= set(node.get_node_names())
                time.sleep(0.1)
            return {'domain': graph.domain_id, 'names': sorted(seen)}
        finally:
            node.destroy_node()


def test_local_cluster_matches_serial_in_case_order():
    cases = [0, 1, 2, 3]
    serial = run_tasks(_square_slowly, cases, serial=True, progress=False)
    dask = run_tasks(_square_slowly, cases, workers=2, progress=False)
    assert serial == [{'case': c, 'square': c * c} for c in cases]
    assert dask == serial


def _triple(case):
    return 3 * case


def test_many_cases_travel_in_chunks_and_come_back_in_order():
    assert chunked(list(range(10)), 2) == [[0, 1], [2, 3], [4, 5], [6, 7], [8, 9]]
    assert chunked(list(range(3)), 2) == [[0], [1], [2]]
    assert [len(c) for c in chunked(list(range(50)), 2)] == [7] * 7 + [1]
    cases = list(range(50))
    assert run_tasks(_triple, cases, workers=2, progress=False) == [3 * c for c in cases]


def test_failing_case_raises_and_bad_options_refused():
    with pytest.raises(ValueError, match='case 2 is bad'):
        run_tasks(_fail_on_two, [1, 2, 3], workers=2, progress=False)
    with pytest.raises(UserError, match='--workers'):
        run_tasks(_square_slowly, [1], workers=0, progress=False)
    assert run_tasks(_square_slowly, [], progress=False) == []


def test_without_dask_a_sweep_says_how_to_get_it_and_serial_still_runs(monkeypatch):
    # dask is the optional extra 'sweeps': a missing install is one clear line, not a traceback.
    import builtins
    real_import = builtins.__import__

    def no_dask(name, *args, **kwargs):
        if name == 'dask' or name.startswith('dask.'):
            raise ImportError(f'No module named {name!r}')
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, '__import__', no_dask)
    with pytest.raises(UserError, match=r'paramotion\[sweeps\].*--serial'):
        run_tasks(_triple, [1, 2], workers=2, progress=False)
    assert run_tasks(_triple, [1, 2], serial=True, progress=False) == [3, 6]


def test_each_case_has_its_own_ros_domain():
    # conftest sets ROS_DOMAIN_ID with discovery on: the runner must still isolate the cases.
    results = run_tasks(_ros_names, ['a', 'b'], workers=2, progress=False)
    for tag, res in zip(['a', 'b'], results):
        assert f'sweep_probe_{tag}' in res['names']
        other = 'b' if tag == 'a' else 'a'
        assert f'sweep_probe_{other}' not in res['names'], res


def test_fast_sweep_on_dask_writes_the_serial_result(tmp_path):
    base = ['fast', 'sweep', '--duration', '1.0', '--settle', '0.3', '--latencies', '0.04']
    assert main(base + ['--out', str(tmp_path / 'serial'), '--serial']) == 0
    assert main(base + ['--out', str(tmp_path / 'dask'), '--workers', '2']) == 0
    serial = json.loads((tmp_path / 'serial' / 'sweep.json').read_text())
    dask = json.loads((tmp_path / 'dask' / 'sweep.json').read_text())
    assert [r['mode'] for r in serial['rows']] == ['lu', 'cheng', 'predictive']
    assert dask == serial


def _dask_map(fn, cases):
    return run_tasks(fn, cases, workers=2, progress=False)


def test_arrangement_search_on_dask_equals_serial():
    from cable_robot_pkg.cdrpm.arrangements import search_edge_arrangements
    from cable_robot_pkg.cdrpm.description import load_description
    d = load_description(None)
    size = (d.frame_half_size, d.platform_half_size, d.cable_radius)
    serial = search_edge_arrangements(*size, pitch=0.5, step=0.4, keep=3)
    dask = search_edge_arrangements(*size, pitch=0.5, step=0.4, keep=3, map_cases=_dask_map)
    assert len(serial[0]) == 3 and serial[1]['home_ok'] > 3
    assert json.dumps(dask, sort_keys=True) == json.dumps(serial, sort_keys=True)


def test_coverage_sweep_on_dask_writes_the_serial_results(tmp_path, capsys):
    from coverage_pkg.worldgen import write_worlds
    worlds = tmp_path / 'worlds'
    write_worlds(str(worlds), 2, 0, None)
    base = ['coverage', 'sweep', '--worlds', str(worlds), '--max-sim-time', '20']
    assert main(base + ['--out', str(tmp_path / 'serial'), '--serial']) == 0
    assert main(base + ['--out', str(tmp_path / 'dask'), '--workers', '2']) == 0
    names = sorted(p.name for p in (tmp_path / 'serial').iterdir())
    assert names == sorted(p.name for p in (tmp_path / 'dask').iterdir())
    assert 'summary.json' in names and len(names) == 3
    for name in names:
        serial = json.loads((tmp_path / 'serial' / name).read_text())
        dask = json.loads((tmp_path / 'dask' / name).read_text())
        for result in (serial, dask):  # wall-clock timings are the only expected difference
            result.pop('wall_time_s', None)
            result.pop('planner_update_ms', None)
        assert dask == serial, name
    summary = json.loads((tmp_path / 'serial' / 'summary.json').read_text())
    assert len(summary['rows']) == 2 and summary['rows'][0]['path_length_m'] > 0
    assert main(['coverage', '--out', str(tmp_path / 'x')]) == 2
    assert '--world FILE is required' in capsys.readouterr().err
