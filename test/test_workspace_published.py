"""The published-figures table, the Fig. 7 reading, the held-out summary and the report."""
import numpy as np
import pytest

from cable_robot_pkg.cdrpm import paper_figures as pf
from cable_robot_pkg.cdrpm.description import load_description
from cable_robot_pkg.cdrpm.workspace import orientation_workspace


@pytest.fixture(scope='module')
def neuron():
    return load_description()


def test_fig7_trend_agrees_with_the_orientation_workspace(neuron):
    """The r_y limit read per r_x equals the accessible interval of the orientation scan."""
    rows = pf.fig7_trend(neuron, rx_deg=(0.0, 30.0, 60.0), rz_deg=(0.0, 30.0), step_deg=2.0)
    scan = orientation_workspace(neuron, (0, 0, 0), rz_deg=(0, 30), rx_range=(0, 60),
                                 ry_range=(-90, 90), step_deg=2.0).boundary()
    for row in rows:
        k = 0 if row.rz == 0 else 1
        entry = next(e for e in scan[k]['rows'] if e['rx'] == row.rx)
        assert row.ry_limit == min(entry['ry_max'], -entry['ry_min'])
        side = 'limit_max' if entry['ry_max'] <= -entry['ry_min'] else 'limit_min'
        assert row.decided_by.split('+')[0] == entry[side]


def test_fig7_verdict_reads_the_paper_statements():
    rows = [pf.Fig7Row(0.0, 0.0, 60.0, 'cable_cable'), pf.Fig7Row(0.0, 45.0, 40.0, 'cable_body'),
            pf.Fig7Row(30.0, 0.0, 50.0, 'cable_cable'),
            pf.Fig7Row(30.0, 45.0, 30.0, 'cable_cable')]
    v = pf.fig7_verdict(rows)
    assert v['shrinks'] and v['body_decides'] and v['cable_first_with_rz']
    rows[1] = pf.Fig7Row(0.0, 45.0, 70.0, 'cable_cable')
    v = pf.fig7_verdict(rows)
    assert not v['shrinks'] and not v['body_decides']


def test_without_cable_cable_lifts_the_fitted_fig7_limit(neuron):
    """At the centre with r_z = 0 only cable-cable contact bounds r_y (the held-out
    disagreement with the paper's cable-body limit): switched off, the scan runs to its end;
    switching the body test off changes nothing there."""
    kw = dict(rx_deg=(0.0, 45.0), rz_deg=(0.0,), step_deg=2.0)
    base = pf.fig7_trend(neuron, **kw)
    assert all(r.decided_by == 'cable_cable' for r in base)
    assert all(r.decided_by == 'range' for r in pf.fig7_trend(neuron, without={'cable_cable'},
                                                              **kw))
    no_body = pf.fig7_trend(neuron, without={'cable_body'}, **kw)
    assert [r.ry_limit for r in no_body] == [r.ry_limit for r in base]


@pytest.mark.slow            # every published figure recomputed (quick grids): seconds
def test_published_table_marks_fitted_and_held_out(neuron):
    res = pf.published_table(neuron, quick=True)
    use = {r['figure']: r['use'] for r in res['rows']}
    fitted = [f for f, u in use.items() if u == 'fitted']
    assert len(fitted) == 6 and all('in frame' in f or 'TOW +-30/30/10' in f for f in fitted)
    assert len(res['rows']) == 22
    # Fitted figures agree by construction; the held-out Fig. 7 trend does not.
    assert all(r['agrees'] for r in res['rows'] if r['use'] == 'fitted')
    assert not res['fig7_verdict']['shrinks']
    # About the fixed axes the limit shrinks, but cable-cable contact still sets it.
    assert res['fig7_fixed_verdict']['shrinks']
    assert res['fig7_fixed_verdict']['decided_high'] == 'cable_cable'
    # The workpiece removes positions by cable-workpiece contact, not by the other types.
    lost = res['workpiece']['lost_percent']
    assert lost['cable_workpiece'] > 50 and lost['cable_cable'] == lost['cable_body'] == 0


def test_fig7_rotation_conventions():
    """Moving axes: Rx Ry Rz (as the rest of the package); fixed axes: Rz Ry Rx."""
    from cable_robot_pkg.cdrpm.kinematics import rotation_matrix_deg
    moving = pf.fig7_rotations(20.0, 35.0, 10.0)
    fixed = pf.fig7_rotations(20.0, 35.0, 10.0, axes='fixed')
    np.testing.assert_allclose(moving, rotation_matrix_deg(20, 35, 10))
    np.testing.assert_allclose(fixed, rotation_matrix_deg(0, 0, 10) @ rotation_matrix_deg(
        0, 35, 0) @ rotation_matrix_deg(20, 0, 0))
    assert np.abs(moving - fixed).max() > 0.1
    with pytest.raises(ValueError, match='axes'):
        pf.fig7_rotations(0, 0, 0, axes='xyz')


def test_perturbed_anchors_stay_in_the_frame_and_move(neuron):
    rng = np.random.default_rng(0)
    moved = pf.perturbed_description(neuron, rng, 0.03)
    delta = np.abs(moved.frame_points - neuron.frame_points)
    assert np.all(delta <= 0.03 + 1e-12) and np.any(delta > 0.01)
    assert np.all(np.abs(moved.frame_points) <= neuron.frame_half_size + 1e-12)


def test_summarise_heldout_counts_overlaps():
    def row(shrinks, body, share, gap, worst=None, tow=False, sizes=()):
        fig7 = {'shrinks': shrinks, 'body_decides': body,
                'decided_high': 'cable_body' if body else 'cable_cable'}
        r = {'screen_worst': 9.0 if worst is None else worst, 'fig7': fig7,
             'fig7_fixed': {**fig7, 'shrinks': True},
             'workpiece_share': share, 'workpiece_gap_m': gap}
        if worst is not None:
            r.update({'table2_worst': worst, 'tow_box_fits': tow,
                      'workpiece_sizes': [{'share': s, 'gap_m': g} for s, g in sizes]})
        return r
    rows = [row(True, True, 60.0, 0.5), row(True, False, 20.0, 0.5),
            row(False, False, 61.0, 0.45, worst=3.0, tow=True, sizes=[(58.0, 0.55)]),
            row(True, True, 10.0, None, worst=4.0, tow=True, sizes=[(30.0, 0.2)]),
            row(False, False, 30.0, 0.3, worst=6.0, tow=True)]
    s = pf.summarise_heldout(rows)
    assert s['candidates'] == 5 and s['fig7_shrinks'] == 3
    assert s['fig7_shrinks_by_cable_body'] == 2 and s['workpiece_60_at_default_size'] == 2
    assert s['fig7_and_workpiece'] == 1
    assert s['table2_within_5'] == 2 and s['table2_and_tow_box'] == 2
    assert s['fitted_with_fig7_trend'] == 1 and s['fitted_with_workpiece_60_some_size'] == 1
    assert s['fitted_with_both'] == 0
    assert s['best_table2_screen_with_fig7_trend'] == 4.0
    assert s['fig7_fixed_shrinks'] == 5 and s['fig7_fixed_shrinks_by_cable_body'] == 2
    assert s['fitted_with_fig7_fixed_trend'] == 1


@pytest.mark.slow
def test_report_quick_writes_the_tables(tmp_path):
    from cable_robot_pkg.cdrpm.report import write_report
    paths = write_report(tmp_path, quick=True)
    assert [p.name for p in paths] == ['workspace.md', 'workspace_fig7.png']
    text = paths[0].read_text()
    for needle in ('fitted to Table II and the TOW box', '| held out |', '| fitted |',
                   'Ablation', 'Sensitivity', 'machine:', 'command:'):
        assert needle in text
    assert paths[1].stat().st_size > 10_000


@pytest.mark.slow            # the held-out study end to end
def test_heldout_cli_on_a_coarse_pitch(tmp_path, capsys):
    """``paramotion workspace heldout`` on a 1 m pitch: counts consistent with the rows."""
    import json

    from paramotion.cli import main as cli_main
    out = tmp_path / 'heldout'
    assert cli_main(['workspace', 'heldout', '--pitch', '1.0', '--serial',
                     '--out', str(out)]) == 0
    data = json.loads((out / 'result.json').read_text())
    s = data['summary']
    assert s['candidates'] == data['rows_total'] > 0
    assert s['fig7_shrinks'] >= s['fig7_shrinks_by_cable_body'] >= s['fig7_and_workpiece']
    assert s['table2_within_5'] >= s['table2_and_tow_box'] >= s['fitted_with_both']
    assert 'candidates' in capsys.readouterr().out


def test_report_summarises_a_heldout_result(tmp_path):
    """The report's held-out section renders the counts of a heldout result file."""
    import json

    from cable_robot_pkg.cdrpm.report import _heldout_lines
    assert 'has not been run' in _heldout_lines(tmp_path)[0]
    fig7 = {'shrinks': True, 'body_decides': True, 'decided_high': 'cable_body'}
    rows = [{'screen_worst': 20.0, 'near_table2': False, 'fig7': fig7, 'fig7_fixed': fig7,
             'workpiece_share': 10.0, 'workpiece_gap_m': None}]
    (tmp_path / 'workspace_heldout').mkdir()
    (tmp_path / 'workspace_heldout' / 'result.json').write_text(json.dumps({
        'summary': pf.summarise_heldout(rows), 'command': 'paramotion workspace heldout',
        'date_utc': 'today', 'machine': 'here', 'wall_time_s': 60.0,
        'stats': {'candidates_total': 9, 'near_table2_screen': 0, 'sampled_others': 1,
                  'sample_seed': 0}}))
    text = '\n'.join(_heldout_lines(tmp_path))
    assert 'Of the 9 edge-anchored candidates' in text and '1 are evaluated' in text
    assert "| ... with cable-body contact setting it at r_x = 45 deg (the paper's Fig. 7) | " \
           '1 | 1 |' in text
