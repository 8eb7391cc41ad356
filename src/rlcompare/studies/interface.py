"""What every study shares: its options, what it tells its user while it runs, and the report it ends with.

A study's runner (named by its record in :mod:`rlcompare.studies.registry`) offers two calls:

    study_plan(options) -> StudyPlan                 what it would train and whether it can decide (--plan)
    run(out, options, ui, *, study, force) -> runs     train what ``out`` lacks, load what it holds
    report(out, ui, *, runs=None, videos=True) -> Report   tables, figures and report.html, without training

``options`` is the study's own :class:`Options`; ``ui`` is a :class:`UI`, silent unless the command line gives
one that draws progress bars.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rlcompare.validation import ConfigError, Integer, check, check_seed_range, plain_fields

if TYPE_CHECKING:
    import pandas as pd

Advance = Callable[[str, int], None]
"""``advance(task, n)``: ``n`` more units of one task of a progress display done."""


def option(default: Any, *, minimum: int | None = None, spellings: tuple[str, ...] = ()) -> Any:
    """A field of an :class:`Options` class: its default, the smallest integer it takes, and other spellings of
    its command-line option (``--runs`` beside ``--seeds``)."""
    return field(default=default, metadata={"minimum": minimum, "spellings": spellings})


@dataclass(frozen=True)
class Options:
    """A study's options, one field each, with its docstring as help. Frozen and checked on creation: an
    integer below its field's ``minimum``, or what :meth:`check` refuses, is a
    :class:`~rlcompare.validation.ConfigError` naming the field."""

    def __post_init__(self) -> None:
        plain_fields(self)
        for item in dataclasses.fields(self):
            minimum, value = item.metadata.get("minimum"), getattr(self, item.name)
            if minimum is not None and value is not None:
                check(item.name, value, Integer(minimum))
        seeds = getattr(self, "seeds", None)
        if isinstance(seeds, int):  # every study's count of seeds, read before any is built
            check_seed_range(seeds, getattr(self, "first_seed", 0))
        self.check()

    def check(self) -> None:
        """Checks beyond a minimum; a study's options override it."""


@dataclass(frozen=True)
class Seeded(Options):
    """Options of a study trained on consecutive seeds."""

    seeds: int = option(30, minimum=1, spellings=("--runs",))
    """Number of seeds (runs); the seeds are first-seed, first-seed + 1, ..."""
    first_seed: int = option(0, minimum=0)
    """First seed. Seed s starts episodes as env.reset(seed=s) does."""

    @property
    def seed_range(self) -> tuple[int, ...]:
        return tuple(range(self.first_seed, self.first_seed + self.seeds))


def listed(field_name: str, spec: str | None, allowed: tuple[str, ...], *, every: str = "",
           groups: dict[str, tuple[str, ...]] | None = None) -> tuple[str, ...]:
    """A comma-separated choice among ``allowed``; ``None`` (or ``every``, where given): all of them; a name of
    ``groups``: its members."""
    groups = groups or {}
    if spec is None or (every and spec.strip() == every):
        return allowed
    if spec.strip() in groups:
        return groups[spec.strip()]
    chosen = tuple(name.strip() for name in spec.split(",") if name.strip())
    if not chosen or any(name not in allowed for name in chosen):
        named = ", ".join(f"'{name}'" for name in (every, *groups) if name)
        prefix = f"{named} or " if named else ""
        raise ConfigError(field_name, spec, f"{prefix}a comma-separated list of {', '.join(allowed)}")
    return chosen


@dataclass
class Report:
    """What a study's report produced: the page, the sentences to print, what could not be built, and how long
    each part took."""

    path: Path
    lines: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)


class UI:
    """What a study tells its user while it runs. This one is silent; the command line's draws progress bars."""

    @contextlib.contextmanager
    def tasks(self, totals: dict[str, int], *, eta: bool = False) -> Iterator[Advance]:
        """A progress display of the named tasks, each counting to its total, while the block runs."""
        yield lambda task, n: None

    def done(self, name: str, results: Any, reused: bool) -> None:
        """One configuration finished: trained now, or ``reused`` from the study's directory."""

    def say(self, text: str) -> None:
        """A line of information."""

    def table(self, frame: pd.DataFrame, title: str, caption: str = "") -> None:
        """A small table of results."""

    @contextlib.contextmanager
    def working(self, text: str) -> Iterator[None]:
        """A long step without a count (building a report)."""
        yield


def run_each(out: Path, configs: dict[str, Any], ui: UI, *, study: str, force: bool = False,
             **options: Any) -> dict[str, Any]:
    """Each configuration into ``out / name``, or loaded where it is complete there
    (:func:`~rlcompare.experiment.runner.run_or_load`, given ``options``), under one count of their episodes,
    telling ``ui`` of each as it finishes."""
    from rlcompare.experiment.runner import run_or_load

    runs = {}
    with ui.tasks({study: sum(c.episodes for c in configs.values())}) as advance:
        for name, results, reused in run_or_load(Path(out), configs, study=study, force=force,
                                                 progress=lambda n: advance(study, n), **options):
            runs[name] = results
            ui.done(name, results, reused)
    return runs


def run_trials(sweep: Any, backend: str, workers: int | None, address: str | None, where: str, ui: UI,
               run: Callable[[Any, Callable[[Any], None]], tuple[int, int]]) -> tuple[int, int]:
    """Connect ``backend`` before anything is written (a :class:`~rlcompare.experiment.backends.BackendError`
    where it cannot run), then ``run(executor, progress)`` with a progress display over ``sweep``'s trials;
    ``run`` returns (trials already finished, trials run now)."""
    from rlcompare.experiment.backends import make_backend

    executor = make_backend(backend, workers=workers, address=address)
    executor.connect()
    trials = len(sweep.trials())
    ui.say(f"{sweep.name}: {len(sweep.configs)} configurations x {len(sweep.seeds)} seeds = {trials} trials {where}")
    with ui.tasks({"trials": trials}, eta=True) as advance:
        return run(executor, lambda trial: advance("trials", 1))
