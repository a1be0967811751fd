"""Config validation of the FAST feed support: bad input gets one clear error before a run."""
import math

import pytest
import yaml

from cable_robot_pkg.fast.configuration import load_config
from cable_robot_pkg.fast.scenario import register
from paramotion.cli import main as cli_main
from paramotion.errors import UserError


def write(tmp_path, data, name='bad.yaml'):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data) if not isinstance(data, str) else data)
    return path


def test_default_config_is_valid_and_consistent():
    cfg = load_config()
    assert cfg.cables.n == 10
    assert sorted({c.kind for c in cfg.cable_specs}) == ['drive', 'pretension', 'suspension']
    assert cfg.raw['isolation']['rate'] > cfg.raw['cable_controller']['rate']
    assert cfg.suspended_mass > cfg.raw['trolley']['mass']


@pytest.mark.parametrize('override, words', [
    ({'cables': {'EA': -5.0}}, ['cables.EA', '-5', '> 0']),
    ({'cables': {'damping': -1.0}}, ['cables.damping', '>= 0']),
    ({'cables': {'tension_max': 100.0}}, ['cables.tension_max', 'must exceed']),
    ({'trolley': {'mass': 0.0}}, ['trolley.mass']),
    ({'track': {'zenith_deg': 40.0}}, ['track.zenith_deg', 'unreachable']),
    ({'focal_surface': {'centre': [0.0, 0.0, 30.0]}}, ['unreachable', 'tower']),
    ({'gough_stewart': {'leg_min': 0.85, 'leg_max': 0.95}}, ['leg stroke', 'too short']),
    ({'gough_stewart': {'envelope_position': 0.4}}, ['too short', '0.4']),
    ({'isolation': {'rate': 20.0}}, ['isolation.rate', 'cable_controller.rate']),
    ({'isolation': {'mode': 'magic'}}, ['isolation.mode', 'predictive']),
    ({'isolation': {'peak_gain_max': 0.5}}, ['isolation.peak_gain_max', '>= 1']),
    ({'isolation': {'vibration_band': [2.0, 0.3]}}, ['isolation.vibration_band', 'f_low']),
    ({'isolation': {'predictor': 'oracle'}}, ['isolation.predictor', 'wiener']),
    ({'isolation': {'wiener_taps': 7.5}}, ['isolation.wiener_taps', 'integer']),
    ({'isolation': {'wiener_spacing': 0.0}}, ['isolation.wiener_spacing', '> 0']),
    ({'wind': {'spectrum': 'pink'}}, ['wind.spectrum', 'kaimal']),
    ({'towers': {'T1': [80.0, 0.0, 12.0]}}, ['towers.T1', 'outside the field']),
    ({'cables': {'tension_min': 9000.0, 'tension_ref': 9500.0}}, ['unreachable', 'tensions']),
])
def test_invalid_config_is_refused_with_a_clear_message(tmp_path, override, words):
    path = write(tmp_path, override)
    with pytest.raises(UserError) as info:
        load_config(path)
    msg = str(info.value)
    assert '\n' not in msg and msg.startswith('bad.yaml')
    for w in words:
        assert w in msg, msg


def test_unknown_section_missing_file_and_bad_yaml(tmp_path):
    with pytest.raises(UserError, match='unknown section'):
        load_config(write(tmp_path, {'cabels': {}}))
    # A misspelt or retired key is refused too, not silently ignored.
    with pytest.raises(UserError, match=r'isolation\.latency_full'):
        load_config(write(tmp_path, {'isolation': {'latency_full': 0.027}}))
    # Tower names are the user's own.
    towers = {'T1': [24.0, 24.0, 12.0], 'T2': [-24.0, 24.0, 12.0], 'T3': [-24.0, -24.0, 12.0],
              'T4': [24.0, -24.0, 12.0]}
    assert load_config(write(tmp_path, {'towers': towers}, 'towers.yaml'))
    with pytest.raises(UserError, match='no such file'):
        load_config(tmp_path / 'nope.yaml')
    with pytest.raises(UserError, match='not valid YAML'):
        load_config(write(tmp_path, 'cables: [1, 2', 'broken.yaml'))
    with pytest.raises(UserError, match='unknown point'):
        load_config(write(tmp_path, {'cables': {'list': [
            {'name': f'c{i}', 'kind': 'drive', 'anchors': ['T9'], 'attach': [0, 0, 0]}
            for i in range(8)]}}))


def test_a_valid_unseen_config_loads(tmp_path):
    """A different, consistent layout (bigger towers spacing, meridian track) is accepted."""
    cfg = load_config(write(tmp_path, {
        'towers': {'T1': [22.0, 22.0, 11.0], 'T2': [-22.0, 22.0, 11.0],
                   'T3': [-22.0, -22.0, 11.0], 'T4': [22.0, -22.0, 11.0]},
        'track': {'kind': 'meridian', 'zenith_deg': 12.0, 'speed': 0.08},
        'cables': {'EA': 90000.0}}, 'ok.yaml'))
    assert cfg.track.kind == 'meridian' and math.isclose(cfg.raw['cables']['EA'], 9e4)


def test_cli_reports_bad_config_before_running(tmp_path, capsys):
    path = write(tmp_path, {'cables': {'EA': -1.0}})
    out = tmp_path / 'run'
    code = cli_main(['fast', '--config', str(path), '--duration', '5', '--out', str(out)])
    err = capsys.readouterr().err
    assert code == 2 and 'cables.EA' in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
    code = cli_main(['fast', '--duration', '-3', '--out', str(out)])
    assert code == 2 and '--duration' in capsys.readouterr().err
    assert callable(register)
