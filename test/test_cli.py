"""The ``paramotion`` command line: every subcommand has --help; bad input is one line."""
import subprocess
import sys

import pytest

from paramotion.cli import build_parser, main


def _subcommands(parser, prefix=()):
    for action in parser._actions:
        if action.__class__.__name__ == '_SubParsersAction':
            for name, sub in action.choices.items():
                yield prefix + (name,)
                yield from _subcommands(sub, prefix + (name,))


def test_every_subcommand_has_help(capsys):
    commands = list(_subcommands(build_parser()))
    assert ('smoke',) in commands and ('bag', 'record') in commands
    assert ('bag', 'play') in commands and ('bag', 'info') in commands
    for cmd in commands:
        with pytest.raises(SystemExit) as exit_info:
            main(list(cmd) + ['--help'])
        assert exit_info.value.code == 0, cmd
        assert 'usage: paramotion' in capsys.readouterr().out


def test_bad_argument_is_one_line_error_and_nothing_written(tmp_path, capsys):
    out = tmp_path / 'run'
    assert main(['smoke', '--duration', '-1', '--out', str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count('\n') == 0 and '--duration' in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_existing_output_is_refused(tmp_path, capsys):
    assert main(['smoke', '--out', str(tmp_path)]) == 2
    assert 'already exists' in capsys.readouterr().err


@pytest.mark.slow            # starts a node process
def test_node_executable_refuses_bad_parameter_with_one_line():
    proc = subprocess.run(
        [sys.executable, '-m', 'paramotion.smoke.range_sensor_node', '--ros-args',
         '-p', 'max_range:=-3.0'], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith('error:')]
    assert len(lines) == 1 and "'max_range'" in lines[0] and 'allowed' in lines[0]
