"""The sensitivity study's report (:mod:`rlcompare.studies.sensitivity.study`, whose docstring lists the files it
writes), from the sweep's store alone: the cells in words and in a table, the heatmaps of the cross and of the
schedule block, what is missing, and ``report.html``.

The summary names every region where the conclusion flips (:func:`flip_regions`: a run of neighbouring γ values
at one schedule, α and time limit where Q-Learning is marked better), with SARSA minus Q-Learning and its
interval at each of its cells, and says "never flips" only of a block that has no such cell, naming the axes
that block sweeps (:func:`blocks`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from rlcompare.experiment import rundir, store
from rlcompare.experiment.sweep_store import read_manifest, trial_path
from rlcompare.report.page import Section, save_figure, write_report, write_table
from rlcompare.studies.interface import Report
from rlcompare.studies.sensitivity.figures import heatmap_figure, schedule_figure
from rlcompare.studies.sensitivity.grid import (
    GRID,
    LEVEL,
    METRICS,
    SCHEDULE_BLOCK,
    SWEEP_DIR,
    SYMBOLS,
    compare_cells,
    seed_returns,
)
from rlcompare.studies.sensitivity.words import (
    blocks,
    cross_cells,
    display_table,
    missing,
    schedule_cells,
    setting,
    summary,
    value_text,
)


def build_report(out: Path) -> Report:
    root = out / SWEEP_DIR
    manifest = read_manifest(root)
    seeds = seed_returns(root)
    cells = compare_cells(seeds)
    problems = missing(seeds, manifest)
    lines = summary(cells)
    sections = [Section("Summary", lines)]
    if not cells.empty:
        table = display_table(cells)
        table_file = write_table(table, out / "tables", "cells")
        config = store.read_json(trial_path(root, seeds["config"].iloc[0], seeds["seed"].iloc[0]) / rundir.CONFIG_FILE)
        sections.append(Section("The grid", method_paragraphs(config, cells, len(seeds), manifest)))
        if not cross_cells(cells).empty:
            sections += [Section(METRICS[metric].capitalize(), figures=[(
                save_figure(heatmap_figure(cells, metric), out / "figures" / f"heatmap-{metric}.png", dpi=90),
                f"SARSA - Q-Learning on the {METRICS[metric]}, ε decaying; blue: SARSA returns more")])
                for metric in METRICS]
        if not schedule_cells(cells).empty:
            sections.append(Section("The ε schedule", [
                f"ε's schedule x γ at {setting(SCHEDULE_BLOCK, SCHEDULE_BLOCK)}: SARSA - Q-Learning, the mark under "
                "each value (n.r.: not resolved; bold: resolved, by the family's Holm correction)."], figures=[(
                    save_figure(schedule_figure(cells, metric), out / "figures" / f"schedule-{metric}.png", dpi=90),
                    f"SARSA - Q-Learning on the {METRICS[metric]} by ε schedule and γ; blue: SARSA returns more")
                    for metric in METRICS]))
        sections.append(Section("Cells", tables=[("SARSA against Q-Learning, cell by cell", table, table_file)]))
    path = write_report(out / "report.html", "Sensitivity: SARSA against Q-Learning across settings", sections,
                        problems)
    return Report(path, lines, problems)


def method_paragraphs(config: dict[str, Any], cells: pd.DataFrame, finished: int, manifest: dict[str, Any]
                      ) -> list[str]:
    """What ran (``config``: one trial's ``config.json``) and how the cells are marked."""
    cross = cross_cells(cells)
    grid = "; ".join(f"{SYMBOLS[k]} ∈ {{{', '.join(value_text(k, v) for v in sorted(cross[k].unique()))}}}"
                     for k in GRID)
    block = [words for name, words, _ in blocks(cells) if name == "schedule"]
    schedule = (f" Beside that cross, a block of {block[0]}: ε constant throughout (the paper's constant runs: 0.5) "
                "or decaying as in the cross, the cross's own cells where it holds them.") if block else ""
    return [
        f"{config['env']}, {config['bins']} bins per dimension, a {config['max_steps']}-step limit, "
        f"{config['episodes']} episodes per seed; in the cross, ε decaying linearly from {config['epsilon_start']:g} "
        f"to ε_end over the first {config['decay_fraction']:.0%} of them; greedy evaluation every "
        f"{config['eval_every']} episodes ({config['eval_episodes']} episodes each). The cross: {grid}, each for "
        f"Q-Learning and SARSA.{schedule} Everything else is the paper's setting. Time limit bootstrapped: the "
        "update at the cut bootstraps from the next state's value; terminal: it does not, as old Gym's done made "
        "the paper's agents do.",
        f"{finished} of {len(manifest['trials'])} trials finished (root seed {manifest['root_seed']}; every "
        f"configuration runs the same seeds, so SARSA and Q-Learning meet on the same start states). The sweep's "
        f"store is {SWEEP_DIR}/; 'rlcompare report' on it gives its own sweep report.",
        "Per cell: the mean over seeds of SARSA minus Q-Learning on paired seeds, its 95% BCa bootstrap interval, "
        f"and the two-sided Wilcoxon signed-rank p-value. Each metric's {len(cells)} cells, both blocks, form one "
        "family: p-values adjusted by Holm's step-down method; a cell is marked SARSA better (Q-Learning better) "
        f"when its adjusted p-value is below {LEVEL:g} and its interval lies above (below) 0, and not resolved "
        "otherwise.",
    ]
