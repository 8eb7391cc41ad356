"""A study's design, stated before anything trains (``rlcompare reproduce STUDY --plan``, and the first line of every
study): what it trains, the families of tests its report will make, and whether each can decide at all on these
seeds (:mod:`rlcompare.stats.design`), as a preregistration would state them.

A study's runner offers ``study_plan(options) -> StudyPlan`` beside ``run`` and ``report``
(:mod:`rlcompare.studies.interface`). It builds its configurations as ``run`` does (importing what they need:
JAX for the deep studies), and counts its families with the functions its report uses, so that the plan and the
report cannot disagree. Nothing is trained or compiled, and no file is written.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rlcompare import pace
from rlcompare.formatting import number
from rlcompare.machine import gib
from rlcompare.pace import Pace
from rlcompare.stats.design import INTERVAL, RANK_SUM, SIGNED_RANK, T_TEST, Reach, Test, detectable_difference, reach

SPREAD = "spread of on - off (SD over seeds)"
"""The column of a paired study's verdict table that the next plan reads its detectable differences from."""
ESTIMATE = "on - off (mean, 95% CI)"
"""The first column of a paired study's verdict table after those that name the comparison."""


def duration(seconds: float) -> str:
    """A planned time as a person says it: ``40 s``, ``2.5 min``, ``12 min``, ``3.5 h``."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 10 * 60:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 60:.0f} min" if seconds < 90 * 60 else f"{seconds / 3600:.1f} h"


@dataclass(frozen=True)
class Question:
    """A family of tests the report will make: what they ask, the test, the seeds (paired, or on each side) and the
    family's size under Holm's correction (1: not corrected). A ``headline`` question is the one the study is for: a
    design that cannot decide it cannot decide."""

    asks: str
    test: Test
    seeds: int
    family: int = 1
    headline: bool = True
    other_seeds: int | None = None
    """Seeds on the other side of a rank-sum test, where they differ from ``seeds``."""

    @property
    def reach(self) -> Reach:
        return reach(self.test, self.seeds, self.family, other_seeds=self.other_seeds)

    def reads(self) -> str:
        """How far the test can go: its smallest p against the level it must pass."""
        found = self.reach
        if self.test in (T_TEST, INTERVAL):
            what = "a t test" if self.test == T_TEST else "a 95% bootstrap interval"
            return (f"{what} on {self.seeds} seeds {'can' if found.can_decide else 'cannot'} exclude no difference "
                    f"(it needs {found.needed} seeds or more)")
        level = (f"the {found.level:.2g} Holm asks over {self.family} tests" if self.family > 1 else
                 f"the level {found.level:.2g}")
        seeds = (f"{self.seeds} and {self.other_seeds} seeds" if self.other_seeds not in (None, self.seeds) else
                 f"{self.seeds} seeds{' a side' if self.test == RANK_SUM else ''}")
        test = f"the {self.test} test on {seeds}"
        if found.can_decide:
            return f"{test} can give a p of {found.smallest_p:.2g}, at or below {level}"
        return f"{test} cannot give a p below {found.smallest_p:.2g}, above {level}"


@dataclass(frozen=True)
class Training:
    """One configuration as it will train: its run's name, its seeds, and how long each seed trains, in whole
    batches (what runs, not what was asked); where its pace is kept (:func:`rlcompare.pace.key`) and the threads
    its seeds are spread over."""

    name: str
    seeds: int
    amount: int
    unit: str
    """``episodes``, ``environment steps``, ``agent steps`` or ``plies``."""
    pace_key: str = ""
    threads: int = 1
    memory: int = 0
    """Bytes it holds while it trains, where known before it runs (a tabular training's records and weights)."""

    def seconds(self, paces: Mapping[str, Pace], as_run: bool = False) -> float | None:
        """Its time on this machine from the pace kept for it (:meth:`rlcompare.pace.Pace.seconds`); None where
        none is kept."""
        found = paces.get(self.pace_key)
        return None if found is None else found.seconds(self.seeds, self.amount, self.threads, as_run)


def tabular_training(name: str, config: Any, memory_checked: bool = True) -> Training:
    """A tabular configuration (:class:`~rlcompare.tabular.config.ExperimentConfig`) as a training of so many
    episodes, its seeds spread over this machine's cores; one that would not fit in memory refused now, before
    anything trains (``memory_checked``: where the engine trains it whole, not a study in blocks of seeds)."""
    from rlcompare.tabular.memory import check_memory, training_bytes

    if memory_checked:
        check_memory(config)
    seeds = len(config.seeds)
    return Training(name, seeds, config.episodes, "episodes", pace.key("tabular", config),
                    pace.threads_for(seeds), training_bytes(config))


def deep_training(name: str, config: Any, unit: str = "environment steps") -> Training:
    """A deep configuration (:class:`~rlcompare.deep.config.DeepConfig`) as a training of the steps it runs."""
    return Training(name, len(config.seeds), config.steps_trained, unit, pace.key("deep", config),
                    memory=config.memory_before_running())


def episodic(configs: Mapping[str, Any], memory_checked: bool = True) -> tuple[Training, ...]:
    """Tabular configurations by run name, as trainings of so many episodes (:func:`tabular_training`)."""
    return tuple(tabular_training(name, config, memory_checked) for name, config in configs.items())


def sweep_plan(sweep: Any) -> StudyPlan:
    """A sweep's trials, each configuration (named by its swept values) over the sweep's seeds
    (:class:`~rlcompare.experiment.sweep.Sweep`): its report tabulates them and tests nothing."""
    from rlcompare.experiment.sweep import swept_value

    def named(config: Any) -> str:
        return ", ".join(f"{key}={swept_value(config, key)}" for key in sweep.swept) or config.name

    training = deep_training if sweep.engine == "deep" else tabular_training
    return StudyPlan(tuple(training(named(c), c) for c in sweep.configs))


@dataclass(frozen=True)
class StudyPlan:
    """What a study will train and what its report can decide."""

    trainings: tuple[Training, ...]
    questions: tuple[Question, ...] = ()
    plumbing: str = ""
    """Why this design is a plumbing check (it checks the pipeline, not the question); empty where it asks its
    question."""
    workers: int = 1
    """Trainings run at once on this machine (each one's pace was measured so, beside the others)."""
    detectable: tuple[str, ...] = ()
    """What the headline comparisons could detect, from a spread known before (:func:`with_known_spread`)."""

    @property
    def undecidable(self) -> tuple[Question, ...]:
        """The headline questions these seeds cannot decide (none in a plumbing check)."""
        if self.plumbing:
            return ()
        return tuple(q for q in self.questions if q.headline and not q.reach.can_decide)

    @property
    def seeds_needed(self) -> int:
        """The fewest seeds on which every headline question can be decided."""
        return max((q.reach.needed for q in self.questions if q.headline), default=1)

    def first_line(self) -> str:
        """One line: whether this design can decide, and if not why, and with how many seeds it could."""
        if self.plumbing:
            return f"A plumbing check: no verdict is possible ({self.plumbing})."
        headline = [q for q in self.questions if q.headline]
        if not headline:
            return "This design draws figures and tables; no test decides a question of it."
        if not self.undecidable:
            return f"This design can decide {'; '.join(q.asks for q in headline)}."
        reasons = "; ".join(f"{q.asks}: {q.reads()}" for q in self.undecidable)
        return f"This design cannot decide {reasons}; with --seeds {self.seeds_needed} it can."

    def training_seconds(self, paces: Mapping[str, Pace], finished: Collection[str] = (), as_run: bool = False
                         ) -> float | None:
        """The time of its trainings but those ``finished``, :attr:`workers` at once, from ``paces`` (``as_run``:
        their compiles as they just took); None where none of them has a pace (those without one count nothing)."""
        waiting = [t for t in self.trainings if t.name not in finished]
        known = [seconds for seconds in (t.seconds(paces, as_run) for t in waiting) if seconds is not None]
        return sum(known) / max(1, min(self.workers, len(waiting))) if known else None

    def time_line(self, paces: Mapping[str, Pace], rest: str = "", finished: Collection[str] = ()) -> str:
        """How long it will take on this machine, from the pace each training last ran at here
        (:meth:`rlcompare.pace.Pace.seconds`), :attr:`workers` at once, and the rest of the study's last run (kept
        under ``rest``: starting, saving, the report); the trainings ``finished`` already are read, not trained, and
        not counted; those with no pace kept are named, and those far larger or smaller than any run measured."""
        waiting = [t for t in self.trainings if t.name not in finished]
        unknown = [t.name for t in waiting if t.pace_key not in paces]
        trained = self.training_seconds(paces, finished)
        done = (f"; {len(finished)} training{'s' * (len(finished) != 1)} finished already, read and not counted"
                if finished else "")
        if waiting and trained is None:
            return (f"Time: not known yet; no training of this design has run on this machine (each keeps its pace "
                    f"in {pace.pace_file()} as it runs){done}.")
        total = (trained or 0.0) + (paces[rest].seconds(1, 1, 1) if rest in paces else 0.0)
        if not waiting and rest not in paces:
            return f"Time: not known yet{done}."
        newest = max(paces[key].measured for key in (*(t.pace_key for t in waiting), rest) if key in paces)
        line = (f"Time: about {duration(total)} on this machine, from the pace of its trainings measured here "
                f"(newest {newest}){done}")
        far = [t for t in waiting if t.pace_key in paces and paces[t.pace_key].far(t.amount)]
        if far:
            first = far[0]
            runs = sorted({paces[t.pace_key].nearest(t.amount).units for t in far})
            line += (f"; extrapolated for {len(far)} training{'s' * (len(far) != 1)}, from runs of "
                     f"{'-'.join(f'{units:,}' for units in dict.fromkeys((runs[0], runs[-1])))} {first.unit}: "
                     f"{first.name} trains {first.amount:,}")
        if rest and rest not in paces and waiting:
            line += "; the report not counted (never run here)"
        if unknown:
            more = f" and {len(unknown) - 3} more" if len(unknown) > 3 else ""
            line += f"; not counted, never run here with these settings: {', '.join(unknown[:3])}{more}"
        return line + "."

    def lines(self, paces: Mapping[str, Pace] | None = None, rest: str = "", finished: Collection[str] = ()
              ) -> list[str]:
        """The whole plan: the first line, its time where ``paces`` are given (:meth:`time_line`), every training,
        every family of tests."""
        lines = [self.first_line()]
        if paces is not None:
            lines.append(self.time_line(paces, rest, finished))
        if self.trainings:
            lines += ["", f"Trainings ({len(self.trainings)}):"]
            lines += [f"  {t.name}: {t.seeds} seeds x {t.amount:,} {t.unit}" for t in self.trainings]
            largest = max(self.trainings, key=lambda t: t.memory)
            if largest.memory:
                held = gib(largest.memory) if largest.memory >= 2**30 else f"{largest.memory / 2**20:,.1f} MiB"
                lines.append(f"Memory: the largest training known before it runs holds {held} ({largest.name}: "
                             "its records and any replay buffers; a network's whole figure is checked once it "
                             "compiles)")
        if self.questions:
            lines += ["", "Tests, each family under Holm's correction:"]
            lines += [f"  {'(headline) ' if q.headline else ''}{q.asks}: {q.reads()}" for q in self.questions]
        if self.detectable:
            lines += ["", *self.detectable]
        return lines


def with_known_spread(plan: StudyPlan, out: Path, name: str) -> StudyPlan:
    """``plan`` with the difference each of its paired comparisons detects at 80% power (Holm's strictest level,
    these seeds), read from the spread of the paired differences its previous run in ``out`` showed: the verdict
    table ``tables/<name>_verdicts.csv`` its report wrote, verified against the study's record (a table that is not
    the study's says so instead). Unchanged where ``out`` holds no such table or the plan makes no paired test."""
    table = f"tables/{name}_verdicts.csv"
    question = next((q for q in plan.questions if q.test == SIGNED_RANK and q.headline), None)
    if question is None or not (Path(out) / table).is_file():
        return plan
    import io

    import pandas as pd  # here, where a table is read: not for every command's --help, nor every plan

    from rlcompare.experiment import rundir, store

    try:
        verdicts = pd.read_csv(io.BytesIO(rundir.read_member_file(Path(out), table)))
    except (store.StoreError, ValueError) as error:
        return dataclasses.replace(plan, detectable=(f"No spread read from the previous run: {error}",))
    if SPREAD not in verdicts.columns or ESTIMATE not in verdicts.columns:
        return plan
    naming = list(verdicts.columns[:list(verdicts.columns).index(ESTIMATE)])

    def detectable(spread: float) -> str:
        found = detectable_difference(SIGNED_RANK, spread, question.seeds, question.family)
        return "nothing (the design cannot decide)" if math.isinf(found) else number(found)

    rows = [f"  {', '.join(str(row[c]) for c in naming)}: {detectable(float(row[SPREAD]))}"
            for _, row in verdicts.iterrows() if math.isfinite(float(row[SPREAD]))]
    seeds = sorted({int(s) for s in verdicts.get("seeds", pd.Series(dtype=int)).dropna()})
    ran = f" of {'/'.join(map(str, seeds))} seeds" if seeds else ""
    heading = (f"Detectable at 80% power with {question.seeds} seeds, in each comparison's own units, from the "
               f"spread of on - off in the previous run{ran} ({Path(out) / table}):")
    return dataclasses.replace(plan, detectable=(heading, *rows))
