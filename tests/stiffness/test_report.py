"""The HTML report writer: verdict first, escaped text, tables, figures written as PNG."""

import pytest
from matplotlib.figure import Figure

from stiffness.report.html import Report


def small_figure() -> Figure:
    fig = Figure(figsize=(3, 2))
    fig.add_subplot().plot([0, 1, 2], [0, 1, 4])
    return fig


def test_verdict_comes_first_whatever_the_order(tmp_path):
    r = Report("title")
    r.heading("Details")
    r.paragraph("body text")
    r.verdict("the conclusion", "good")
    page = r.write(tmp_path).read_text()
    assert page.index("the conclusion") < page.index("Details") < page.index("body text")
    assert 'class="verdict good"' in page


def test_text_is_escaped(tmp_path):
    r = Report("<script>alert(1)</script>", subtitle="a & b")
    r.paragraph("x < y")
    r.table(["<h>"], [["<td>"]], caption="c > d")
    r.verdict("<b>", "warn")
    page = r.write(tmp_path).read_text()
    assert "<script>" not in page and "&lt;script&gt;" in page
    assert "x &lt; y" in page and "a &amp; b" in page and "&lt;td&gt;" in page and "c &gt; d" in page
    assert "<b>" not in page


def test_table_formats_numbers_and_missing_values():
    r = Report("t")
    r.table(["name", "value", "n", "ok"], [["a", 0.0123456, 7, True], ["b", None, float("nan"), False]])
    page = r.html()
    assert "0.01235" in page and ">7<" in page and ">yes<" in page and ">no<" in page
    assert page.count("–") == 2


def test_figures_are_written_as_png_with_unique_names(tmp_path):
    r = Report("t")
    a = r.figure(small_figure(), "TCP dx", "caption one")
    b = r.figure(small_figure(), "TCP dx")
    index = r.write(tmp_path / "out")
    assert a != b and a.endswith(".png") and "/" not in a and " " not in a
    for name in (a, b):
        png = (tmp_path / "out" / name).read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        assert f'src="{name}"' in index.read_text()
    assert "caption one" in index.read_text()


def test_unknown_verdict_kind_is_rejected():
    with pytest.raises(ValueError, match="good"):
        Report("t").verdict("x", "great")
