"""voronoi_pkg.report: the quick report writes its table and picture from fresh runs."""
import pytest

from voronoi_pkg.report import write_report


@pytest.mark.slow
def test_quick_report_writes_markdown_and_png(tmp_path):
    md, png = write_report(tmp_path, quick=True)
    text = md.read_text()
    assert md.name == 'voronoi.md' and png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    for needle in ('paper query (Fig. 3)', '| block |', 'diagram search', 'singularity (P1)',
                   'collision (P2)', 'configurations/s'):
        assert needle in text, needle
    # The diagram's nodes are all ties: the table says 1.0000.
    assert '| 1.0000 |' in text
