"""A small HTML report writer: verdict first, then headings, text, tables and matplotlib figures.

The page is one self-contained ``index.html`` (inline CSS, no scripts) next to the PNGs of its
figures, so it reads in any browser without a terminal or a network. All text is HTML-escaped.

Example
-------
>>> from matplotlib.figure import Figure
>>> r = Report("compare: kr125_axial vs campaign.csv")
>>> r.verdict("The 6-DoF model halves the TCP error.", "good")
>>> r.table(["body", "RMS mm"], [["TCP", 0.0312]])
>>> fig = Figure(); _ = fig.add_subplot().plot([0, 1], [0, 1])
>>> _ = r.figure(fig, "tcp_dx", "TCP deflection along x against load")
>>> path = r.write("out/report")          # out/report/index.html, out/report/tcp_dx.png
"""

from __future__ import annotations

import html
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

VERDICT_KINDS = ("good", "warn", "bad", "info")

_CSS = """
body { font-family: -apple-system, "Segoe UI", Helvetica, Arial, sans-serif; margin: 2em auto;
       max-width: 1200px; padding: 0 1em; color: #1d1d1f; line-height: 1.45; }
h1 { font-size: 1.6em; border-bottom: 2px solid #ccc; padding-bottom: .3em; }
h2 { font-size: 1.25em; margin-top: 1.8em; border-bottom: 1px solid #e3e3e3; }
h3 { font-size: 1.05em; margin-top: 1.4em; }
.subtitle { color: #555; margin-top: -.6em; }
.verdict { border-left: 6px solid; padding: .7em 1em; margin: 1em 0; font-size: 1.08em;
           border-radius: 3px; white-space: pre-wrap; }
.verdict.good { border-color: #2e7d32; background: #edf7ee; }
.verdict.warn { border-color: #ed8c00; background: #fff6e5; }
.verdict.bad  { border-color: #c62828; background: #fdecea; }
.verdict.info { border-color: #1565c0; background: #e8f1fb; }
table { border-collapse: collapse; margin: .8em 0; font-size: .92em; }
caption { caption-side: top; text-align: left; color: #555; padding-bottom: .3em; }
th, td { border: 1px solid #d0d0d0; padding: .25em .6em; }
th { background: #f3f3f3; text-align: left; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
tr:nth-child(even) td { background: #fafafa; }
figure { margin: 1.2em 0; }
figure img { max-width: 100%; border: 1px solid #e3e3e3; }
figcaption { color: #555; font-size: .92em; }
pre { background: #f6f6f6; padding: .6em; overflow-x: auto; }
"""


@dataclass
class _Block:
    html: str


def _esc(text: Any) -> str:
    return html.escape(str(text), quote=True)


def _cell(v: Any, fmt: str) -> tuple[str, bool]:
    """Cell text and whether it is numeric (right-aligned)."""
    if v is None:
        return "–", True
    if isinstance(v, bool):
        return ("yes" if v else "no"), False
    if isinstance(v, int):
        return str(v), True
    if isinstance(v, float) or hasattr(v, "dtype"):
        try:
            f = float(v)
        except (TypeError, ValueError):
            return str(v), False
        return ("–" if math.isnan(f) else fmt.format(f)), True
    return str(v), False


class Report:
    """An HTML report assembled block by block and written with `write`.

    Verdicts are placed at the top of the page, under the title, whatever the order they were
    added in, so the reader sees the conclusion first.

    Parameters
    ----------
    title : str
        The page title (also the ``<title>``).
    subtitle : str, optional
        One line under the title, e.g. the input files.
    """

    def __init__(self, title: str, subtitle: str = ""):
        self.title = title
        self.subtitle = subtitle
        self._verdicts: list[_Block] = []
        self._blocks: list[_Block] = []
        self._images: dict[str, bytes] = {}

    # -- content --------------------------------------------------------------------------------
    def verdict(self, text: str, kind: str = "info") -> None:
        """A conclusion box shown at the top; ``kind`` is one of good, warn, bad, info."""
        if kind not in VERDICT_KINDS:
            raise ValueError(f"verdict kind {kind!r} must be one of {', '.join(VERDICT_KINDS)}")
        self._verdicts.append(_Block(f'<div class="verdict {kind}">{_esc(text)}</div>'))

    def heading(self, text: str, level: int = 2) -> None:
        """A section heading, level 2 (section) or 3 (subsection)."""
        level = min(max(int(level), 2), 4)
        self._blocks.append(_Block(f"<h{level}>{_esc(text)}</h{level}>"))

    def paragraph(self, text: str) -> None:
        self._blocks.append(_Block(f"<p>{_esc(text)}</p>"))

    def preformatted(self, text: str) -> None:
        """Monospaced text, e.g. a command line to reproduce the report."""
        self._blocks.append(_Block(f"<pre>{_esc(text)}</pre>"))

    def table(self, header: list[str], rows: list[list[Any]], caption: str = "",
              fmt: str = "{:.4g}") -> None:
        """A table; floats are written with ``fmt``, None and NaN as a dash."""
        parts = ["<table>"]
        if caption:
            parts.append(f"<caption>{_esc(caption)}</caption>")
        parts.append("<tr>" + "".join(f"<th>{_esc(h)}</th>" for h in header) + "</tr>")
        for row in rows:
            cells = []
            for v in row:
                text, numeric = _cell(v, fmt)
                cls = ' class="num"' if numeric else ""
                cells.append(f"<td{cls}>{_esc(text)}</td>")
            parts.append("<tr>" + "".join(cells) + "</tr>")
        parts.append("</table>")
        self._blocks.append(_Block("\n".join(parts)))

    def figure(self, fig: Figure, name: str, caption: str = "", dpi: int = 100) -> str:
        """Render ``fig`` to PNG now (the figure may be discarded after) and place it here.

        Returns the PNG file name, made unique and safe from ``name``.
        """
        stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("._") or "figure"
        fname, k = f"{stem}.png", 2
        while fname in self._images:
            fname, k = f"{stem}_{k}.png", k + 1
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi)
        self._images[fname] = buf.getvalue()
        cap = f"<figcaption>{_esc(caption)}</figcaption>" if caption else ""
        alt = _esc(caption or name)
        self._blocks.append(_Block(f'<figure><img src="{_esc(fname)}" alt="{alt}">{cap}</figure>'))
        return fname

    # -- output ---------------------------------------------------------------------------------
    def html(self) -> str:
        """The page as a string (images are referenced by file name)."""
        sub = f'<p class="subtitle">{_esc(self.subtitle)}</p>' if self.subtitle else ""
        body = "\n".join(b.html for b in self._verdicts + self._blocks)
        return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
                f"<title>{_esc(self.title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
                f"<h1>{_esc(self.title)}</h1>\n{sub}\n{body}\n</body>\n</html>\n")

    def write(self, directory: str | Path) -> Path:
        """Write ``index.html`` and the PNGs into ``directory`` (created); return the HTML path."""
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        for fname, png in self._images.items():
            (out / fname).write_bytes(png)
        index = out / "index.html"
        index.write_text(self.html(), encoding="utf-8")
        return index
