"""``paramotion report``: dispatch to each part's write_report, an index, one-line errors."""
import sys
import types

from paramotion import report
from paramotion.cli import main


def test_unknown_part_is_one_line_error_and_nothing_written(tmp_path, capsys):
    out = tmp_path / 'results'
    assert main(['report', '--only', 'coverge', '--out', str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count('\n') == 0 and "'coverge'" in err and 'coverage' in err
    assert not out.exists()


def test_parts_write_their_pages_and_the_index_lists_them(tmp_path, monkeypatch):
    calls = []

    def fake_writer(name):
        def write_report(out_dir, quick=False):
            calls.append((name, quick))
            page = out_dir / f'{name}.md'
            page.write_text(f'# {name}\n')
            return [page]
        return write_report

    for name in ('alpha', 'beta'):
        module = types.ModuleType(f'fake_report_{name}')
        module.write_report = fake_writer(name)
        monkeypatch.setitem(sys.modules, module.__name__, module)
    monkeypatch.setattr(report, 'REPORTS', {'alpha': 'fake_report_alpha',
                                            'beta': 'fake_report_beta'})
    out = tmp_path / 'results'
    assert main(['report', '--only', 'beta', '--quick', '--out', str(out)]) == 0
    assert calls == [('beta', True)]
    assert main(['report', '--only', 'alpha', '--out', str(out)]) == 0
    index = (out / 'README.md').read_text()
    # --only keeps the other part's row; rows follow REPORTS order
    assert index.index('[alpha.md]') < index.index('[beta.md]')
    assert 'Machine:' in index and 'Date:' in index


def test_a_part_without_write_report_is_refused_before_anything_runs(tmp_path, monkeypatch,
                                                                      capsys):
    module = types.ModuleType('fake_report_empty')
    monkeypatch.setitem(sys.modules, module.__name__, module)
    monkeypatch.setattr(report, 'REPORTS', {'empty': 'fake_report_empty'})
    out = tmp_path / 'results'
    assert main(['report', '--out', str(out)]) == 2
    assert 'write_report' in capsys.readouterr().err
    assert not out.exists()


def test_index_lists_pages_already_there_without_running_anything(tmp_path, monkeypatch):
    monkeypatch.setattr(report, 'REPORTS', {'alpha': 'no_such_module_alpha'})
    out = tmp_path / 'results'
    out.mkdir()
    (out / 'alpha.md').write_text('# alpha\n')
    assert main(['report', '--index', '--out', str(out)]) == 0
    assert '| alpha | [alpha.md](alpha.md) | not timed |' in (out / 'README.md').read_text()
