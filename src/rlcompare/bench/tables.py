"""What a benchmark gives the command line: each stage's measurements as a :class:`BenchTable` to print and as
sections of its JSON file, and that file written and read back (``rlcompare report`` shows its tables again)."""

from __future__ import annotations

import os
import platform
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from rlcompare.bench.harness import all_threads
from rlcompare.experiment import store
from rlcompare.machine import versions

Say = Callable[[str], None]
"""Where a stage says each measurement as it is taken (a line of text)."""


@dataclass(frozen=True)
class BenchTable:
    """Measurements as text for the command line to print: a title, the columns (a label, then numbers), rows of
    cells, and notes on what was left out."""

    title: str
    columns: tuple[str, ...]
    rows: list[tuple[str, ...]]
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Measured:
    """What one stage measured: its table, and the sections its file keeps of the measurements, by name."""

    table: BenchTable
    sections: dict[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class Stage:
    """One measurement of a benchmark: what it measures, in words, and the function that measures it."""

    what: str
    measure: Callable[[Say], Measured]


@dataclass(frozen=True)
class Suite:
    """What one ``rlcompare bench`` command measures, stage by stage, and the file of :data:`BENCH_FILES` it
    writes."""

    file: str
    stages: tuple[Stage, ...]


BENCH_FILES = ("bench.json", "kernels.json", "study.json", "envs.json", "chess.json", "selfplay.json", "atari.json",
               "sweeps.json", "deep.json")
"""What ``rlcompare bench`` writes: the kernels, the study and the ports (``bench`` alone); then each subcommand's
own (``bench kernels``, ``study``, ``envs``, ``chess``, ``selfplay``, ``atari``, ``sweeps``, ``deep``)."""


def bench_document(tables: list[BenchTable], **sections: object) -> dict[str, object]:
    """What ``rlcompare bench`` writes to its file: when and where it measured, every table as printed, and the
    measurements of each section (``kernels``: :func:`~rlcompare.bench.kernels.kernel_rows`)."""
    return {"created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "machine": {"processor": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
                        "numba_threads": all_threads()},
            "versions": versions(),
            "tables": [{"title": t.title, "columns": list(t.columns), "rows": [list(r) for r in t.rows],
                        "notes": list(t.notes)} for t in tables],
            **sections}


def read_bench_document(path: Path) -> tuple[str, list[BenchTable]]:
    """What :func:`bench_document` wrote to ``path``: a line saying when and where it measured, and its tables. A
    file of another shape is a :class:`~rlcompare.experiment.store.StoreError` naming it."""
    document = store.read_json(path)
    try:
        machine = document["machine"]
        said = (f"{path.name}: measured {document['created']} on {machine['processor']}, {machine['cpus']} CPUs, "
                f"{machine['numba_threads']} numba threads")
        tables = [BenchTable(str(t["title"]), tuple(map(str, t["columns"])),
                             [tuple(map(str, row)) for row in t["rows"]], tuple(map(str, t["notes"])))
                  for t in document["tables"]]
    except (KeyError, TypeError) as error:
        raise store.StoreError(f"{path}: not a benchmark rlcompare wrote (no {error})") from None
    return said, tables
