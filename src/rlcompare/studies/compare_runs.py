"""``rlcompare compare``: rlcompare's verdicts and report for runs other libraries made (read by
:mod:`rlcompare.experiment.outside` into one tidy table).

Each environment's common range runs from the step where every run has begun to the step where the shortest has
ended. Two numbers a run are compared, each read from the run's own points (episode returns, or evaluations), so
that no point weighs more for the steps it spans: the mean of the points recorded in the last tenth of the range
(the final window; where a run has none there, the value in force at its end), and the mean over the range of the
value in force at each step, each point holding until the next (a zero-order hold: the area under the curve as
plotted, divided by its length). Curves are interpolated onto a common grid for the pictures alone. Seeds of two
libraries' runs share no randomness, so methods are compared as independent samples
(:func:`~rlcompare.stats.compare.compare_independent`: an exact rank-sum test on small samples, ties included)
unless the user says the seeds are paired; every comparison of a report is one Holm family. A margin of no
difference is the user's, declared on the command line before the report is read; without one, no claim of
equivalence is made.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from itertools import combinations
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from rlcompare.experiment import store
from rlcompare.formatting import cut as cut_text
from rlcompare.report.findings import gap_and_interval
from rlcompare.report.page import Section, save_figure, write_report, write_table
from rlcompare.stats.aggregates import by_method
from rlcompare.stats.compare import Judged, Paired, compare_independent, compare_paired, judge_family
from rlcompare.stats.design import RANK_SUM, SIGNED_RANK, detectable_difference, reach
from rlcompare.studies.compare_numbers import (
    GRID_POINTS,
    METRICS,
    PRIMARY,
    Curves,
    Numbers,
    checked,
    curves,
    numbers,
)
from rlcompare.studies.interface import Report
from rlcompare.studies.plans import Question, StudyPlan
from rlcompare.validation import ConfigError

if TYPE_CHECKING:  # matplotlib loads where a report draws, not for --plan
    from matplotlib.figure import Figure

    from rlcompare.report.aggregate_plots import Aggregates

COMPARISON = store.Owner("comparison")
"""What ``rlcompare compare`` writes its directory as."""


@dataclass(frozen=True)
class Comparison:
    """One row of the verdict table: method ``a`` against ``b`` on an environment, by a metric (:data:`METRICS`)."""

    env: str
    metric: str
    a: str
    b: str


def compared(found: list[Numbers], paired: bool, margin: float | None, metrics: tuple[str, ...] = PRIMARY
             ) -> dict[Comparison, Paired]:
    """Each pair of methods on each environment, on each of ``metrics``; seeds matched by label where ``paired``."""
    result = {}
    for env in found:
        for a, b in combinations(sorted(env.values), 2):
            for metric in metrics:
                x, y = env.values[a][metric], env.values[b][metric]
                if paired:
                    y = y[[env.seeds[b].index(seed) for seed in env.seeds[a]]]
                result[Comparison(env.env, metric, a, b)] = (compare_paired(x, y, margin) if paired
                                                             else compare_independent(x, y, margin))
    return result


def judged(found: dict[Comparison, Paired]) -> dict[Comparison, tuple[Judged, str]]:
    """The comparisons as one Holm family, each with its label in the methods' own names."""
    family: dict[Hashable, Paired] = {key: paired for key, paired in found.items()}
    judgements = judge_family(family, ("A", "B"))
    return {key: (judgements[key], {"A better": f"{key.a} better", "B better": f"{key.b} better"}.get(
        judgements[key].label, judgements[key].label)) for key in found}


def verdicts(found: dict[Comparison, tuple[Judged, str]]) -> pd.DataFrame:
    """A row per comparison."""
    return pd.DataFrame([{
        "environment": key.env, "metric": key.metric, "A": key.a, "B": key.b, "A mean": j.paired.a_mean,
        "B mean": j.paired.b_mean, "A - B (95% CI)": j.paired.difference.format(3),
        "P(A > B)": j.paired.improvement.format(2), "p (Holm)": j.p, "p equivalent (Holm)": j.p_equivalence,
        "seeds": j.paired.seeds, "verdict": label,
    } for key, (j, label) in found.items()])


def answer(found: dict[Comparison, tuple[Judged, str]], paired: bool) -> list[str]:
    """The answer in words: each environment's final-window comparisons, and how they were tested."""
    test = ("paired seeds (Wilcoxon signed-rank)" if paired
            else "seeds as independent samples (Mann-Whitney, exact with ties at their mid-ranks, its normal "
                 "approximation from some 64 seeds a side on; the runs share no randomness)")
    lines = []
    for key, (j, label) in found.items():
        if key.metric == "final":
            gap, interval = gap_and_interval(j.paired.difference)
            lines.append(f"On {key.env}, {key.a} against {key.b} over the final tenth of the steps: {key.a} scores "
                         f"{gap} ({interval}; {label}).")
    return [*lines, f"Tested as {test}; p-values Holm-adjusted over every row of the verdict table. "
                    + design_sentence(found, paired)]


def design_sentence(found: dict[Comparison, tuple[Judged, str]], paired: bool) -> str:
    """What the seeds and the family allowed: the smallest p the fewest seeds' test can give, against the level
    Holm asks of it over the family (each comparison's direction test, and its equivalence test where a margin was
    declared)."""
    seeds = min((j.paired.seeds for j, _ in found.values()), default=0)
    family = sum(1 + (j.paired.equivalence is not None) for j, _ in found.values())
    reached = reach(SIGNED_RANK if paired else RANK_SUM, seeds, max(family, 1))
    side = "pairs" if paired else "seeds a side"
    verb = "can" if reached.can_decide else "cannot"
    tests = "the one test" if family == 1 else f"the {family} tests"
    return (f"With {seeds} {side} the test cannot give a p below {reached.smallest_p:.3g}; Holm asks "
            f"{reached.level:.3g} of the smallest over {tests}: this design {verb} decide"
            + ("." if reached.can_decide else f" (with {reached.needed} {side} it can)."))


def spread(x: np.ndarray, y: np.ndarray, paired: bool) -> float:
    """The standard deviation a test of ``x`` against ``y`` meets: of the paired differences, or pooled over the two
    sides; NaN with too few seeds to say."""
    if paired:
        return float(np.std(x - y, ddof=1)) if len(x) > 1 else np.nan
    freedom = len(x) + len(y) - 2
    if freedom < 1:
        return np.nan
    return float(np.sqrt(((len(x) - 1) * np.var(x, ddof=1 if len(x) > 1 else 0)
                          + (len(y) - 1) * np.var(y, ddof=1 if len(y) > 1 else 0)) / freedom))


def plan(frame: pd.DataFrame, *, paired: bool, margin: float | None, cut: bool = False,
         metrics: tuple[str, ...] = PRIMARY) -> list[str]:
    """``compare --plan``: the design the report would test, read from the runs without testing them: the family,
    whether the fewest seeds can decide in it, and each comparison's difference detectable at 80% power from its
    seeds' spread (:func:`~rlcompare.stats.design.detectable_difference`), in the values' units."""
    checked(frame, cut, paired)
    test = SIGNED_RANK if paired else RANK_SUM
    rows = [(env, a, b, metric, env.values[a][metric], env.values[b][metric])
            for env in numbers(frame) for a, b in combinations(sorted(env.values), 2) for metric in metrics]
    family = len(rows) * (1 if margin is None else 2)
    fewest = min(rows, key=lambda row: (min(len(row[4]), len(row[5])), max(len(row[4]), len(row[5]))))
    seeds, other = sorted((len(fewest[4]), len(fewest[5])))
    tests = "one comparison" if len(rows) == 1 else f"{len(rows)} comparisons"
    tests += ("" if margin is None else ", a direction and an equivalence test" if len(rows) == 1
              else ", each a direction and an equivalence test")
    question = Question(f"each pair of methods on each environment ({tests})", test, seeds, family,
                        other_seeds=None if paired else other)
    lines = StudyPlan((), (question,)).lines()
    lines += ["", "Detectable at 80% power at Holm's strictest level, from these runs' spread (the values' units):"]
    for env, a, b, metric, x, y in rows:
        if paired:
            y = y[[env.seeds[b].index(seed) for seed in env.seeds[a]]]
        found = detectable_difference(test, spread(x, y, paired), len(x), family, None if paired else len(y))
        lines.append(f"  {env.env}, {a} against {b} ({metric}): " + (
            f"{found:.4g}" if np.isfinite(found) else "none (these seeds cannot pass the level)"))
    return lines


ATARI_NAME = re.compile(r"(?:ALE/)?(?P<title>[A-Za-z]+?)(?:NoFrameskip|Deterministic)?(?:-v\d+|-Atari)")
"""An Atari game's name as Gymnasium, its older ``NoFrameskip`` spellings and rlcompare spell it."""


def parse_scores(given: list[str]) -> dict[str, tuple[float, float]]:
    """``ENV=LOW:HIGH`` options as ``{env: (low, high)}``; a :class:`~rlcompare.validation.ConfigError` naming
    ``scores`` for one that is not two finite numbers, the low below the high, or an environment given twice."""
    found: dict[str, tuple[float, float]] = {}
    for text in given:
        env, _, pair = text.rpartition("=")
        low, _, high = pair.partition(":")
        try:
            bounds = (float(low), float(high))
        except ValueError:
            bounds = (np.nan, np.nan)
        if not env or env in found or not np.isfinite(bounds).all() or bounds[0] >= bounds[1]:
            raise ConfigError("scores", text, "ENV=LOW:HIGH, two finite numbers, the low below the high, once an "
                                              "environment")
        found[env] = bounds
    return found


def reference_scores(envs: list[str], given: Mapping[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
    """Each environment's ``(low, high)`` reference scores where one is known: given by the user (``--scores``),
    else an Atari game's published random and human scores (:mod:`rlcompare.envs.atari.scores`)."""
    from rlcompare.envs.atari.scores import GAMES

    found = {}
    for env in envs:
        atari = ATARI_NAME.fullmatch(env)
        if env in given:
            found[env] = given[env]
        elif atari is not None and atari["title"] in GAMES:
            game = GAMES[atari["title"]]
            found[env] = (game.random, game.human)
    return found


def across(found: list[Curves], read: list[Numbers], references: Mapping[str, tuple[float, float]], figures: Path,
           tables: Path) -> tuple[Aggregates | None, dict[str, str], str]:
    """rliable's aggregates of the final-window numbers over two or more environments that two or more methods ran,
    each normalised between its reference scores (``references``: low 0, high 1), drawn and written; or none, and
    why: an environment without reference scores (a scale made of the methods' own means moves when a method is
    added or left out), or no two methods that ran every environment on one number of seeds (rliable's matrix of
    seeds by environments)."""
    finals = {n.env: {m: v["final"] for m, v in n.values.items()} for n in read}
    if len(finals) < 2:
        return None, {}, "one environment: nothing to pool."
    unscaled = [env for env in finals if env not in references]
    if unscaled:
        return None, {}, (f"no reference scores for {', '.join(unscaled)} (--scores ENV=LOW:HIGH; an Atari game's "
                          "published random and human scores are known). A scale made of the methods' own means "
                          "would move when a method is added or left out, so none is drawn on one.")
    scales = {env: (low, high - low) for env, (low, high) in references.items() if env in finals}
    scores = by_method(finals, scales)
    if len(scores) < 2:
        return None, {}, ("no two methods ran every environment on one number of seeds. rliable's aggregates "
                          "read each method's seeds by environments as one matrix, with the same seeds on every "
                          "environment; seeds: " + "; ".join(f"{env}: " + ", ".join(
                              f"{m} {len(v)}" for m, v in methods.items()) for env, methods in finals.items()) + ".")
    from rlcompare.report.aggregate_plots import draw_aggregates

    curves = by_method({c.env: c.values for c in found}, scales)
    drawn = draw_aggregates(scores, figures, tasks="environments", curves={m: curves[m] for m in scores},
                            x=np.linspace(0.0, 1.0, GRID_POINTS),
                            curve_xlabel="share of each environment's common steps")
    return drawn, {name: write_table(frame, tables, name) for name, frame in (
        ("aggregates", drawn.intervals), ("improvement", drawn.improvements))}, ""


def curves_figure(curve: Curves) -> Figure:
    from matplotlib.figure import Figure

    from rlcompare.report.plots import plot_return_curves

    figure = Figure(figsize=(7, 4.2))
    ax = figure.subplots()
    plot_return_curves(ax, curve.steps, curve.values, window=1, ylabel="value")
    ax.set_xlabel("environment steps")
    ax.set_title(curve.env)
    return figure


def pairing_table(frame: pd.DataFrame) -> pd.DataFrame:
    """What was read: each source file, what its points are, and the method, environment and seed it was taken
    as."""
    return (frame.groupby(["source", "kind", "method", "env", "seed"], sort=True)
            .agg(points=("step", "size"), first_step=("step", "min"), last_step=("step", "max")).reset_index())


COMPARED_FILE = "compared.json"
"""What a comparison's directory compared: a digest of the runs' points, and their methods and environments."""


def what_was_compared(frame: pd.DataFrame) -> dict[str, Any]:
    """The runs of a comparison: a digest of every point read (method, environment, seed, step, value), and the
    methods and environments by name."""
    points = frame[["method", "env", "seed", "step", "value"]].sort_values(["method", "env", "seed", "step"])
    digest = hashlib.sha256(pd.util.hash_pandas_object(points, index=False).to_numpy().tobytes()).hexdigest()
    return {"points": digest, "methods": sorted(frame["method"].unique().tolist()),
            "environments": sorted(frame["env"].unique().tolist())}


def refuse_another_comparison(out: Path, compared_runs: dict[str, Any]) -> None:
    """A :class:`~rlcompare.experiment.store.StoreError` where ``out`` holds the report of other runs: a report is
    replaced by one of the same runs (another margin, another metric), never by another comparison's without
    ``--force``."""
    path = out / COMPARED_FILE
    if not path.is_file():
        return
    earlier = store.read_json(path)
    if not isinstance(earlier, dict) or earlier.get("points") == compared_runs["points"]:
        return
    what = "; ".join(f"{key} {', '.join(map(str, earlier.get(key, [])))}" for key in ("methods", "environments"))
    raise store.StoreError(f"{out}: holds the comparison of other runs ({cut_text(what, 200)}); choose another "
                           "--out, or --force to replace it")


EARLIER = ("figures/*", "tables/*", "report.html")
"""What an earlier comparison wrote into the directory: removed (the files rlcompare listed there, nothing else)
before a new one is written, so that none of its aggregates or figures passes for the new comparison's."""


def report(out: Path, frame: pd.DataFrame, *, paired: bool, margin: float | None, cut: bool = False,
           force: bool = False, metrics: tuple[str, ...] = PRIMARY,
           scores: Mapping[str, tuple[float, float]] | None = None) -> Report:
    """Verdicts, tables, figures and ``report.html`` of ``frame``'s runs into ``out`` (``force``: beside a user's
    files there); ``cut``: runs that end apart are compared on the steps all of them reached (:func:`checked`)."""
    from rlcompare.report.aggregate_plots import across_section

    checked(frame, cut, paired)
    found, read = curves(frame), numbers(frame)
    comparisons = compared(read, paired, margin, metrics)
    with store.output_directory(out, COMPARISON, force=force):
        compared_runs = what_was_compared(frame)
        if not force:
            refuse_another_comparison(out, compared_runs)
        for pattern in EARLIER:
            store.remove_outputs(out, pattern)
        store.write_json_atomic(out / COMPARED_FILE, compared_runs)
        labelled = judged(comparisons)
        table = verdicts(labelled)
        files = {"verdicts": write_table(table, out / "tables", "verdicts"),
                 "pairing": write_table(pairing_table(frame), out / "tables", "pairing")}
        lines = answer(labelled, paired)
        figures = [(save_figure(curves_figure(c), out / "figures" / f"curves-{i}.png"),
                    f"{c.env}: each method's mean over seeds on the common grid, 95% band")
                   for i, c in enumerate(found)]
        references = reference_scores([n.env for n in read], scores or {})
        aggregates, aggregate_files, why_not = across(found, read, references, out / "figures", out / "tables")
        files |= aggregate_files
        ranges = "; ".join(f"{n.env}: steps {n.start:,.0f} to {n.end:,.0f}" for n in read)
        sections = [
            Section("The answer", lines),
            Section("What was compared", [
                f"Each run's own points (episodes or evaluations) over its environment's common range, from the step "
                f"where every run has begun to where the shortest ends ({ranges})"
                + (" (--cut-to-shortest: runs that ended apart are cut to it)" if cut else "") + ". Metrics: "
                + "; ".join(f"{name}, the {METRICS[name]}" for name in metrics)
                + (" (declared with --metric)" if metrics != PRIMARY else " (the primary metric; --metric adds the "
                   "area, each metric one more test of every comparison)")
                + ". " + ("Seeds paired by their labels (--paired): the user says they share randomness." if paired
                          else "Seeds compared as independent samples: runs of different libraries share no "
                               "randomness (--paired where they do).")
                + (f" Margin of no difference, declared on the command line: ±{margin:g}." if margin is not None
                   else " No margin was declared, so no comparison can be called equivalent.")],
                [("What each file was taken as", pairing_table(frame), files["pairing"])]),
            Section("Verdicts", tables=[("Every comparison, one Holm family", table, files["verdicts"])]),
            across_section(
                "Across environments",
                "The final-window numbers pooled over the environments as rliable does (Agarwal et al. 2021): each "
                "environment normalised between its reference scores, 0 and 1 ("
                + "; ".join(f"{env}: {low:g} to {high:g}" for env, (low, high) in references.items())
                + "; --scores, or an Atari game's published random and human scores); interval estimates, the "
                "probability of improvement, performance profiles and sample-efficiency curves, with 95% stratified "
                "bootstrap intervals.",
                aggregates, files, "Interval estimates", f"Not pooled: {why_not} Each environment's comparisons "
                "are in the verdict table."),
            Section("Curves", figures=figures),
        ]
        page = write_report(out / "report.html", "Runs compared", sections, [])
    return Report(page, lines, [])
