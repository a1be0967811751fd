"""The same smoke nodes, each in its own process, talking over DDS on a free-running sim."""
from paramotion.bag.reader import bag_info
from paramotion.smoke.scenario import TOPICS, run_processes


def test_smoke_graph_across_processes(tmp_path):
    result = run_processes(tmp_path / 'bag', duration=6.0, rtf=4.0, log_dir=tmp_path / 'logs')
    assert result['sim_time_s'] >= 6.0
    assert abs(result['final_gap_m'] - result['target_gap_m']) < 0.05
    info = bag_info(tmp_path / 'bag')
    assert info.complete, info.problem
    assert set(info.topics) == set(TOPICS)
    # Time started only once the recorder listened: the first seconds were recorded too.
    assert info.start_ns <= 50_000_000
    assert info.topics['/smoke/range'].count >= 100
