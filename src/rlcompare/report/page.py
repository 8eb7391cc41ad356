"""``report.html``: one offline page that gathers a study's tables, verdicts, figures and videos.

The page links files by relative paths inside the study directory, so the directory can be copied or
archived as a whole and opened without a server or a network.
"""

from __future__ import annotations

import html
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from rlcompare.experiment.store import write_atomic
from rlcompare.formatting import NO_DATA, number

if TYPE_CHECKING:  # a study's module imports this page, and its plan draws nothing
    from matplotlib.figure import Figure

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2rem auto; max-width: 1200px; color: #222; line-height: 1.45; }
h1 { font-size: 1.6rem; } h2 { border-bottom: 1px solid #ddd; padding-bottom: .2rem; margin-top: 2.2rem; }
table { border-collapse: collapse; margin: .8rem 0; font-size: .9rem; max-width: 100%; }
th, td { border: 1px solid #ccc; padding: .3rem .6rem; text-align: right; overflow-wrap: anywhere; }
td:first-child { min-width: 8rem; }
.table-wrap { max-width: 100%; overflow-x: auto; }
h3 .files { font-size: .8rem; font-weight: normal; margin-left: .6rem; }
nav.contents { background: #f6f8fa; padding: .4rem 1rem; margin: 1.5rem 0; }
nav.contents ol { margin: .3rem 0; columns: 2; }
th:first-child, td:first-child { text-align: left; }
th { background: #f3f3f3; }
figure { margin: 1rem 0; } figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { font-size: .9rem; color: #555; }
.videos { display: grid; grid-template-columns: repeat(auto-fill, minmax(520px, 1fr)); gap: 1rem; }
.videos video { width: 100%; }
.problems { background: #fff4e5; border: 1px solid #f0b45b; padding: .6rem 1rem; }
.verdict-supported { color: #1a7f37; font-weight: 600; } .verdict-contradicted { color: #c62828; font-weight: 600; }
.verdict-not-resolved { color: #555; } .verdict-undecidable-here { color: #8a5a00; font-style: italic; }
.verdict-no-data { color: #999; } .verdict-fragile { text-decoration: underline dotted; }
code, pre { background: #f6f8fa; padding: .1rem .3rem; }
"""


@dataclass
class Section:
    """A heading with paragraphs, tables, figures and videos, in that order."""

    title: str
    paragraphs: list[str] = field(default_factory=list)
    tables: list[tuple[str, pd.DataFrame] | tuple[str, pd.DataFrame, str]] = field(default_factory=list)
    """(caption, table) or (caption, table, relative path of its CSV file)"""
    figures: list[tuple[str, str]] = field(default_factory=list)
    """(relative path, caption)"""
    videos: list[tuple[str, str, str]] = field(default_factory=list)
    """(relative MP4 path, relative GIF path or "", caption)"""


_VERDICT_CELL = re.compile(r"<td>(supported|contradicted|not resolved|undecidable here|no data)( \(fragile\))?</td>")


def _verdict_cell(match: re.Match[str]) -> str:
    label, fragile = match.group(1), match.group(2)
    classes = f"verdict-{label.replace(' ', '-')}" + (" verdict-fragile" if fragile else "")
    return f'<td class="{classes}">{label}{fragile or ""}</td>'


def shown(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` as a reader sees it: numbers plain (:func:`~rlcompare.formatting.number`), missing values
    :data:`~rlcompare.formatting.NO_DATA`."""
    def cell(value: object) -> object:
        if isinstance(value, bool | np.bool_):
            return value
        if isinstance(value, int | float | np.integer | np.floating):
            return number(float(value))
        return NO_DATA if value is None or value is pd.NA else value

    return frame.map(cell) if not frame.empty else frame


def _table_html(caption: str, frame: pd.DataFrame, csv: str = "") -> str:
    body = shown(frame).to_html(index=False, escape=True, border=0, na_rep=NO_DATA)
    link = f' <a class="files" href="{html.escape(csv)}">CSV</a>' if csv else ""
    return (f"<h3>{html.escape(caption)}{link}</h3>\n"
            f'<div class="table-wrap">{_VERDICT_CELL.sub(_verdict_cell, body)}</div>')


def anchor(title: str) -> str:
    """The id of a section's heading: its title in lower case, words joined by hyphens."""
    return re.sub(r"[^a-z0-9]+", "-", title.lower()).strip("-") or "section"


def _section_html(section: Section) -> str:
    parts = [f'<h2 id="{anchor(section.title)}">{html.escape(section.title)}</h2>']
    parts += [f"<p>{html.escape(text)}</p>" for text in section.paragraphs]
    parts += [_table_html(*table) for table in section.tables]
    parts += [
        f'<figure><img src="{html.escape(path)}" alt="{html.escape(caption)}">'
        f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        for path, caption in section.figures
    ]
    if section.videos:
        cells = []
        for mp4, gif, caption in section.videos:
            fallback = f' <a href="{html.escape(gif)}">GIF</a>' if gif else ""
            cells.append(f'<figure><video controls muted preload="auto" src="{html.escape(mp4)}"></video>'
                         f"<figcaption>{html.escape(caption)}{fallback}</figcaption></figure>")
        parts.append('<div class="videos">' + "\n".join(cells) + "</div>")
    return "\n".join(parts)


def render_report(title: str, sections: list[Section], problems: list[str]) -> str:
    """The whole page as a string."""
    warning = ""
    if problems:
        items = "".join(f"<li>{html.escape(p)}</li>" for p in problems)
        warning = f'<div class="problems"><strong>Read with care:</strong><ul>{items}</ul></div>'
    parts = [_section_html(s) for s in sections]
    if len(sections) > 2:  # the answer first, then what the page holds
        parts.insert(1, _contents(sections[1:]))
    body = "\n".join(parts)
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
            f"<style>{_STYLE}</style></head>\n<body><h1>{html.escape(title)}</h1>\n{warning}\n{body}\n</body></html>\n")


def _contents(sections: list[Section]) -> str:
    items = "".join(f'<li><a href="#{anchor(s.title)}">{html.escape(s.title)}</a></li>' for s in sections)
    return f'<nav class="contents"><strong>On this page</strong><ol>{items}</ol></nav>'


def save_figure(figure: Figure, path: Path, dpi: int = 100) -> str:
    """Write ``figure`` as a PNG at ``path``; its path relative to the study directory, for the page.

    zlib's fastest level: a fifth of the compression's time for 7% more bytes."""
    write_atomic(path, lambda handle: figure.savefig(handle, format="png", dpi=dpi,
                                                     pil_kwargs={"compress_level": 1}))
    return f"{path.parent.name}/{path.name}"


def write_table(frame: pd.DataFrame, directory: Path, name: str) -> str:
    """``name.csv`` (every digit) and ``name.md`` (as the page shows it) of ``frame`` in ``directory``; the CSV's
    path relative to the study directory, for the page's link."""
    write_atomic(directory / f"{name}.csv", lambda handle: handle.write(frame.to_csv(index=False).encode()))
    markdown = shown(frame).to_markdown(index=False) + "\n"
    write_atomic(directory / f"{name}.md", lambda handle: handle.write(markdown.encode()))
    return f"{directory.name}/{name}.csv"


def write_report(path: Path, title: str, sections: list[Section], problems: list[str]) -> Path:
    page = render_report(title, sections, problems).encode()
    write_atomic(Path(path), lambda handle: handle.write(page))
    return Path(path)
