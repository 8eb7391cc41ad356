"""``rlcompare reproduce deep``: the paper's question asked again with neural networks, as its future work asks.

On CartPole-v1, Acrobot-v1 and MountainCar-v0 (Gymnasium's limits), every deep method trains on paired seeds:
Q(λ), SARSA(λ) and Expected SARSA(λ) in one PQN-style engine whose only switch is the bootstrap, DQN and Double
DQN, PPO. Beside them, the tabular pair (Q-Learning, SARSA) on the same environments with the paper's settings.
The report draws learning curves against environment steps and against seconds, tabulates the final greedy
return and the area under the curve (mean and IQM with 95% intervals), the probability of improvement on paired
seeds, and judges "on-policy against off-policy target" per environment, with and without a network. Over two or
more environments it adds rliable's aggregates of the deep methods (Agarwal et al. 2021): scores normalised per
environment between a uniformly random policy and the best method here, their median, IQM, mean and optimality gap
with stratified bootstrap intervals, performance profiles, the probability of improvement between the methods and
IQM sample-efficiency curves.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.deep import float64
from rlcompare.deep.agent import gymnasium_returns
from rlcompare.deep.config import DeepConfig
from rlcompare.deep.envs import jax_env
from rlcompare.deep.methods import DEEP_METHODS
from rlcompare.deep.results import DeepResults
from rlcompare.deep.rollout import evaluate
from rlcompare.experiment import store
from rlcompare.experiment.engines import load_run
from rlcompare.experiment.runner import run_or_load
from rlcompare.report.aggregate_plots import draw_aggregates
from rlcompare.report.page import Section, plain_number, save_figure, write_report, write_table
from rlcompare.report.plots import plot_return_curves
from rlcompare.stats import intervals as stats
from rlcompare.stats.aggregates import by_method, score_scales
from rlcompare.stats.compare import Paired, compare_paired, judge_family
from rlcompare.stats.metrics import returns_per_seed
from rlcompare.studies.interface import UI, Report, listed
from rlcompare.studies.margins import margin
from rlcompare.studies.measures import per_seed_metrics
from rlcompare.studies.registry import DeepOptions
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.results import Results
from rlcompare.validation import ConfigError

STUDY = "deep"
ENVS = ("CartPole-v1", "Acrobot-v1", "MountainCar-v0")
DEFAULT_SEEDS = DeepOptions.seeds
SCORE = {"CartPole-v1": 475.0, "Acrobot-v1": -100.0, "MountainCar-v0": -130.0}
"""The score whose first reaching, in environment steps and seconds, the report times."""
GOAL = {"CartPole-v1": 490.0, "Acrobot-v1": -85.0, "MountainCar-v0": -115.0}
"""The greedy return in Gymnasium's own environment that the study sets out to reach with the best method."""
GYMNASIUM_EPISODES = 10
"""Episodes of each seed's final greedy policy in Gymnasium's own environment, from the same start states."""
MARGIN = {env: margin("deep", f"{env} (final greedy return)")
          for env in ("CartPole-v1", "Acrobot-v1", "MountainCar-v0")}
"""Differences of mean return smaller than this count as no difference (5% of each environment's return range,
:data:`rlcompare.studies.margins.MARGINS`), declared before any run."""
TABULAR_EPISODES = DeepOptions.episodes
RANDOM_EPISODES = 200
"""Episodes of the uniformly random policy per environment, in the port: the floor (0) of the normalised scores."""
DEFAULT_WORKERS = max(1, min(4, os.cpu_count() or 1))
PAIR = ("pqn_sarsa_lambda", "pqn_q_lambda")
"""The on-policy and the off-policy target in one engine: the only switch is the bootstrap."""
TABULAR_PAIR = ("sarsa", "q_learning")
METRIC_NAMES = {"greedy_return": "final greedy return", "greedy_auc": "area under the greedy curve"}


@dataclass(frozen=True)
class Anchor:
    """A published number to read ours against, with what it is."""

    env: str
    method: str
    value: float
    source: str


ANCHORS = (
    Anchor("CartPole-v1", "dqn", 500.0, "rl-baselines3-zoo benchmark: one trained agent"),
    Anchor("CartPole-v1", "ppo", 500.0, "rl-baselines3-zoo benchmark: one trained agent"),
    Anchor("Acrobot-v1", "dqn", -76.6, "rl-baselines3-zoo benchmark: one trained agent"),
    Anchor("Acrobot-v1", "ppo", -73.5, "rl-baselines3-zoo benchmark: one trained agent"),
    Anchor("MountainCar-v0", "dqn", -100.8, "rl-baselines3-zoo benchmark: one trained agent"),
    Anchor("MountainCar-v0", "ppo", -110.4, "rl-baselines3-zoo benchmark: one trained agent"),
    *(Anchor(env, method, value, f"cleanrl {method}.py docs: episodic return at the end of training, 3 seeds")
      for env, method, value in (("CartPole-v1", "dqn", 488.69), ("Acrobot-v1", "dqn", -91.54),
                                 ("MountainCar-v0", "dqn", -194.95), ("CartPole-v1", "ppo", 490.04),
                                 ("Acrobot-v1", "ppo", -86.36), ("MountainCar-v0", "ppo", -200.0))),
)


@dataclass(frozen=True)
class Plan:
    """What the study trains: the seeds, the deep methods and the environments, and how long."""

    seeds: tuple[int, ...] = tuple(range(DEFAULT_SEEDS))
    methods: tuple[str, ...] = tuple(DEEP_METHODS)
    envs: tuple[str, ...] = ENVS
    steps: int | None = None
    """Environment steps of every deep training in place of each preset's (None: the presets')."""
    tabular_episodes: int = TABULAR_EPISODES
    workers: int = DEFAULT_WORKERS
    """Deep configurations trained at once: one compiled program keeps about 1.3 of 2 cores busy, and two at a
    time finish a study in about half the time here (each one's results depend on its configuration alone)."""

    def deep_configs(self) -> dict[str, DeepConfig]:
        """Each deep method on each environment with its default preset."""
        overrides = {} if self.steps is None else {"total_steps": self.steps}
        return {f"{method}-{env}": DeepConfig(algorithm=method, env=env, seeds=self.seeds, hyperparameters=overrides,
                                              vmap_width=min(len(self.seeds), DEFAULT_SEEDS))
                for env in self.envs for method in self.methods}

    def tabular_configs(self) -> dict[str, ExperimentConfig]:
        """The paper's pair, ε decaying, on each environment with the paper's settings and that environment's
        grid and limit."""
        return {f"tabular-{algorithm}-{env}": ExperimentConfig(algorithm=algorithm, env=env, seeds=self.seeds,
                                                               episodes=self.tabular_episodes)
                for env in self.envs for algorithm in TABULAR_PAIR}


def plan_of(options: DeepOptions) -> Plan:
    """The study's plan from its options; an unknown method or environment, or steps no method can train in, is a
    :class:`ConfigError` naming the option."""
    plan = Plan(seeds=options.seed_range, methods=listed("methods", options.methods, tuple(DEEP_METHODS)),
                envs=listed("envs", options.envs, ENVS), steps=options.steps, tabular_episodes=options.episodes,
                workers=options.workers or DEFAULT_WORKERS)
    built_with_steps_option(plan.deep_configs)
    return plan


def built_with_steps_option(configs: Callable[[], object]) -> None:
    """Build a study's deep configurations once, to check them; a method's ``total_steps`` refused is named as the
    study's ``steps`` option, the one its user gave."""
    try:
        configs()
    except ConfigError as error:
        raise ConfigError("steps" if error.field_name == "total_steps" else error.field_name, error.value,
                          error.allowed) from None


def reproduce(out: Path, plan: Plan, *, progress: Callable[[str, int], None] | None = None, force: bool = False
              ) -> Iterator[tuple[str, DeepResults | Results, bool]]:
    """Train (or load, where finished) the tabular pair, then every deep configuration, into ``out``."""
    def advance(kind: str) -> Callable[[int], None] | None:
        return None if progress is None else (lambda n: progress(kind, n))

    yield from run_or_load(Path(out), plan.tabular_configs(), study=STUDY, progress=advance("tabular"), force=force)
    yield from run_or_load(Path(out), plan.deep_configs(), study=STUDY, progress=advance("deep"), force=force,
                           workers=plan.workers)


def run(out: Path, options: DeepOptions, ui: UI, *, study: str = STUDY, force: bool = False) -> dict[str, Any]:
    """:func:`reproduce` with the study's options, telling ``ui`` of each configuration."""
    plan = plan_of(options)
    deep = plan.deep_configs()
    ui.say(f"Training {len(deep)} deep configurations x {len(plan.seeds)} seeds; each compiles its program first "
           "(10-40 s, once per machine).")
    totals = {"tabular": sum(c.progress_total for c in plan.tabular_configs().values()),
              "deep": sum(c.progress_total for c in deep.values())}
    runs = {}
    with ui.tasks(totals) as advance:
        for name, results, reused in reproduce(out, plan, force=force, progress=advance):
            runs[name] = results
            ui.done(name, results, reused)
    return runs


# --- what the report computes from the run directories ----------------------------------------------------

def load_runs(out: Path) -> tuple[dict[str, DeepResults], dict[str, Results], list[str]]:
    """The finished runs of a deep study directory, deep and tabular, and what is missing or broken."""
    deep, tabular, problems = {}, {}, []
    for run_dir in sorted(p for p in Path(out).iterdir() if p.is_dir() and store.owner_of(p) == store.RUN):
        try:
            results = load_run(run_dir)
            (tabular if isinstance(results, Results) else deep)[run_dir.name] = results
        except (store.StoreError, ValueError) as error:
            problems.append(str(error))
    return deep, tabular, problems


def eval_curves(results: DeepResults) -> tuple[np.ndarray, np.ndarray]:
    """``(after_step, (seeds, rounds) mean greedy return)``."""
    frame = results.evaluations.groupby(["seed", "round"], sort=True)["return"].mean()
    curves = frame.to_numpy().reshape(len(results.seeds), -1)
    steps = np.sort(results.evaluations["after_step"].unique())
    return steps, curves


def per_seed(results: DeepResults) -> pd.DataFrame:
    """One row per seed: its returns (:func:`~rlcompare.stats.metrics.returns_per_seed`: behaviour, final
    greedy return, area under the greedy curve), and the environment steps and seconds at which the greedy curve
    first reached the environment's score."""
    steps, curves = eval_curves(results)
    reached = curves >= SCORE[results.config.env]
    first = np.where(reached.any(axis=1), steps[reached.argmax(axis=1)], np.nan)
    training = results.episodes.groupby("seed", sort=False)["return"]
    return returns_per_seed(results.seeds, [training.get_group(seed).to_numpy() for seed in results.seeds],
                            curves).assign(steps_to_score=first, seconds_to_score=first * seconds_per_step(results))


def seconds_per_step(results: DeepResults) -> float:
    """Wall-clock seconds per environment step of one seed: its group of ``vmap_width`` seeds trains side by side
    at a steady pace, so a seed reached step ``k`` about ``k`` times this after its group began."""
    groups = -(-len(results.seeds) // results.config.vmap_width)
    return results.meta["timings"]["wall_seconds"] / (groups * results.meta["timings"]["training_steps"])


def summary_table(deep: dict[str, DeepResults], gymnasium: dict[str, np.ndarray]) -> pd.DataFrame:
    """Per environment and method: the final greedy return in Gymnasium's own environment and in the port's
    evaluation, the area under the curve (mean and IQM, 95% intervals), the seeds that reached the score, and
    the median steps and seconds to reach it."""
    rows = []
    for name, results in deep.items():
        metrics = per_seed(results)
        reached = metrics["steps_to_score"].notna()
        in_gymnasium = gymnasium[name].mean(axis=1)
        rows.append({
            "env": results.config.env, "method": DEEP_METHODS[results.config.algorithm].label,
            "Gymnasium, IQM": stats.interval(in_gymnasium, "iqm").format(1),
            "Gymnasium, mean": stats.interval(in_gymnasium).format(1),
            "seeds at the goal": f"{int((in_gymnasium >= GOAL[results.config.env]).sum())}/{len(in_gymnasium)}",
            "final, IQM": stats.interval(metrics["greedy_return"].to_numpy(), "iqm").format(1),
            "AUC, mean": stats.interval(metrics["greedy_auc"].to_numpy()).format(1),
            "reached score": f"{int(reached.sum())}/{len(metrics)}",
            "median steps to score": float(metrics["steps_to_score"].median()) if reached.any() else np.nan,
            "median seconds to score": float(metrics["seconds_to_score"].median()) if reached.any() else np.nan,
            "steps/s": results.meta["timings"]["steps_per_second"],
        })
    return pd.DataFrame(rows)


@dataclass(frozen=True)
class Comparison:
    """On-policy against off-policy target on one environment: one metric on paired seeds."""

    env: str
    engine: str
    metric: str
    paired: Paired


def compare(on_policy: np.ndarray, off_policy: np.ndarray, env: str, engine: str, metric: str) -> Comparison:
    return Comparison(env, engine, metric, compare_paired(on_policy, off_policy, MARGIN[env]))


def comparisons(deep: dict[str, DeepResults], tabular: dict[str, Results]) -> list[Comparison]:
    """The paper's question per environment: SARSA(λ) against Q(λ) with a network (final greedy return and area
    under the curve), SARSA against Q-Learning in a table (final greedy return)."""
    found = []
    for env in ENVS:
        on, off = deep.get(f"{PAIR[0]}-{env}"), deep.get(f"{PAIR[1]}-{env}")
        if on is not None and off is not None and on.seeds == off.seeds:
            a, b = per_seed(on), per_seed(off)
            found += [compare(a[m].to_numpy(), b[m].to_numpy(), env, "network", m) for m in METRIC_NAMES]
        on_t, off_t = (tabular.get(f"tabular-{name}-{env}") for name in TABULAR_PAIR)
        if on_t is not None and off_t is not None and on_t.seeds == off_t.seeds:
            a, b = per_seed_metrics(on_t)["greedy_return"], per_seed_metrics(off_t)["greedy_return"]
            found.append(compare(a.to_numpy(), b.to_numpy(), env, "table", "greedy_return"))
    return found


def verdict_table(found: list[Comparison]) -> pd.DataFrame:
    """One row per comparison, all of them one family (:func:`judge_family`: directions and equivalences
    Holm-adjusted together), with the difference each row's seeds could detect."""
    judged = judge_family({i: c.paired for i, c in enumerate(found)}, ("on-policy", "off-policy"))
    return pd.DataFrame([{
        "env": c.env, "engine": c.engine, "metric": METRIC_NAMES[c.metric],
        "on - off (mean, 95% CI)": c.paired.difference.format(1), "P(on > off)": c.paired.improvement.format(2),
        "p (Holm)": j.p, "p equivalent (Holm)": j.p_equivalence, "detectable (80% power)": plain_number(j.detectable),
        "verdict": j.label,
    } for c, j in zip(found, judged.values(), strict=True)])


def anchor_table(deep: dict[str, DeepResults], gymnasium: dict[str, np.ndarray]) -> pd.DataFrame:
    """The published numbers beside ours: each seed's final greedy policy in Gymnasium, IQM over seeds."""
    rows = []
    for anchor in ANCHORS:
        name = f"{anchor.method}-{anchor.env}"
        results = deep.get(name)
        ours = stats.interval(gymnasium[name].mean(axis=1), "iqm").format(1) if results else "not run"
        hidden = " x ".join(map(str, results.config.method_config().hidden)) if results else ""
        rows.append({"env": anchor.env, "method": DEEP_METHODS[anchor.method].label, "published": anchor.value,
                     "what it is": anchor.source, "ours: greedy in Gymnasium, IQM [95% CI]": ours,
                     "our network": hidden})
    return pd.DataFrame(rows)


def random_returns(env_name: str, episodes: int = RANDOM_EPISODES, seed: int = 0) -> np.ndarray:
    """Returns of the uniformly random policy in the port (``evaluate`` at ε = 1), from ``jax.random.key(seed)``.
    JAX is imported here, after :mod:`rlcompare.deep` has said how to install it where it is missing."""
    import jax
    import jax.numpy as jnp

    env = jax_env(env_name)

    def no_op(params: None, observations: jax.Array) -> jax.Array:
        return jnp.zeros(observations.shape[0], jnp.int32)

    @float64
    def play() -> np.ndarray:
        return np.asarray(jax.jit(lambda key: evaluate(env, no_op, None, key, episodes, epsilon=1.0)[0])(
            jax.random.key(seed)))

    return play()


@dataclass(frozen=True)
class Across:
    """The deep methods over the environments, as rliable's aggregates take them: per method's label,
    ``scores`` ``(envs, seeds)`` final greedy returns and ``curves`` ``(envs, seeds, rounds)`` greedy returns at
    each evaluation round, normalised per environment (random policy 0, best method's mean final return 1), with
    the curves' ``x`` and what it is."""

    envs: list[str]
    scores: dict[str, np.ndarray]
    curves: dict[str, np.ndarray]
    x: np.ndarray
    xlabel: str


def across_environments(deep: dict[str, DeepResults], floors: dict[str, float]) -> Across:
    """Each deep method's runs on every environment that two or more methods ran (a method missing one is left
    out), normalised between ``floors`` (the random policy's mean return) and the best mean final greedy return of
    the methods kept. The curves are drawn against environment steps where every training evaluated at the same
    steps, else against the share of each training's own steps (the presets' budgets differ by method and
    environment)."""
    finals: dict[str, dict[str, np.ndarray]] = {}
    rounds: dict[str, dict[str, np.ndarray]] = {}
    steps: dict[tuple[str, str], np.ndarray] = {}
    for env in ENVS:
        for method in DEEP_METHODS:
            results = deep.get(f"{method}-{env}")
            if results is not None:
                label = DEEP_METHODS[method].label
                steps[env, label], curves = eval_curves(results)
                finals.setdefault(env, {})[label] = curves[:, -1]
                rounds.setdefault(env, {})[label] = curves
    kept = by_method(finals)
    envs = [env for env, methods in finals.items() if len(methods) > 1]
    finals = {env: {method: finals[env][method] for method in kept} for env in envs}  # 1: the best of these
    scales = score_scales(finals, floors)
    scores = by_method(finals, scales)
    curves = {method: values for method, values in by_method(rounds, scales).items() if method in scores}
    drawn = [steps[env, method] for env in envs for method in curves]
    x, xlabel = (drawn[0], "environment steps") if drawn else (np.zeros(0), "")
    if any(not np.array_equal(s, x) for s in drawn):
        x, xlabel = x / x[-1], "share of each training's environment steps"
        if any(s.shape != x.shape or not np.allclose(s / s[-1], x) for s in drawn):
            curves, x, xlabel = {}, np.zeros(0), ""
    return Across(envs, scores, curves, x, xlabel)


def curves_figure(deep: dict[str, DeepResults], env: str, against: str) -> Figure:
    """Greedy return against environment steps (``steps``) or wall-clock seconds (``seconds``), mean over seeds
    with a 95% bootstrap band, one line per method."""
    figure = Figure(figsize=(7, 4.2))
    ax = figure.subplots()
    for results in (r for r in deep.values() if r.config.env == env):
        steps, curves = eval_curves(results)
        x = steps if against == "steps" else steps * seconds_per_step(results)
        plot_return_curves(ax, x, {DEEP_METHODS[results.config.algorithm].label: curves}, window=1,
                           ylabel="greedy return")
    ax.set_xlabel("environment steps" if against == "steps" else "seconds of training")
    ax.set_title(env)
    return figure


def aggregate_section(deep: dict[str, DeepResults], tables: Path, figures: Path) -> Section:
    """rliable's aggregates of the deep methods over the environments (``deep_aggregates.csv``,
    ``deep_improvement.csv`` and the figures), or why there are none: they need two or more environments."""
    title = "Across environments"
    ran = {r.config.env for r in deep.values()}
    if len(ran) < 2:
        return Section(title, [f"The aggregates over environments (rliable's) need two or more; this study ran "
                               f"{', '.join(sorted(ran)) or 'none'}."])
    floors = {env: float(random_returns(env).mean()) for env in ENVS if env in ran}
    across = across_environments(deep, floors)
    if len(across.envs) < 2 or len(across.scores) < 2:
        return Section(title, ["The aggregates need two or more methods run on two or more environments alike."])
    drawn = draw_aggregates(across.scores, figures, xlabel="normalised score", tasks="environments",
                            curves=across.curves, x=across.x, curve_xlabel=across.xlabel)
    files = [write_table(drawn.intervals, tables, "deep_aggregates"),
             write_table(drawn.improvements, tables, "deep_improvement")]
    seeds = next(iter(across.scores.values())).shape[1]
    return Section(title, [
        f"The deep methods over {len(across.envs)} environments ({', '.join(across.envs)}) x {seeds} seeds, as "
        "rliable defines its aggregates (Agarwal et al. 2021, \"Deep Reinforcement Learning at the Edge of the "
        "Statistical Precipice\"), drawn here. Each seed's final greedy return (the last evaluation round, in the "
        "port) is normalised environment by environment between a uniformly random policy's mean return (0; "
        f"{RANDOM_EPISODES} episodes in the port: " + ", ".join(f"{env} {floor:.1f}" for env, floor in floors.items())
        + ") and the best deep method's mean here (1), so 1 is the best this study reached, not the environment's "
        "best. Median and mean are of each environment's mean over seeds; IQM, optimality gap (γ = 1) and the "
        "profiles pool every seed of every environment; intervals and bands are 95% stratified bootstrap ones "
        "(seeds resampled within each environment). The tabular pair is left out: its runs count episodes, not "
        "environment steps. "
        + (f"Sample efficiency: the IQM at each evaluation round, against the {across.xlabel}." if across.curves else
           "No sample-efficiency curves: the trainings were evaluated at different shares of their steps.")],
        [("Aggregates of normalised final returns", drawn.intervals, files[0]),
         ("Probability of improvement", drawn.improvements, files[1])], drawn.figures)


def report(out: Path, ui: UI | None = None, *, runs: dict[str, Any] | None = None, videos: bool = True) -> Report:
    """Tables, verdicts, figures and ``report.html`` of a deep study directory, from its run directories (it draws
    no videos)."""
    with store.rewriting(Path(out), "study"):
        return _build_report(Path(out))


def _build_report(out: Path) -> Report:
    deep, tabular, problems = load_runs(out)
    tables, figures = out / "tables", out / "figures"
    gymnasium = {name: gymnasium_returns(results, GYMNASIUM_EPISODES) for name, results in deep.items()}
    summary = summary_table(deep, gymnasium)
    verdicts = verdict_table(comparisons(deep, tabular))
    anchors = anchor_table(deep, gymnasium)
    for name, frame in (("deep_summary", summary), ("deep_verdicts", verdicts), ("deep_anchors", anchors)):
        write_table(frame, tables, name)
    curve_figures = []
    for env in (e for e in ENVS if any(r.config.env == e for r in deep.values())):
        for against in ("steps", "seconds"):
            path = figures / f"curves-{env}-{against}.png"
            curve_figures.append((save_figure(curves_figure(deep, env, against), path),
                                  f"{env}: greedy return against {against} (mean over seeds, 95% band)"))
    lines = [f"{row.env}, {row.engine}, {row.metric}: {row.verdict}" for row in verdicts.itertuples()]
    sections = [
        Section("On-policy or off-policy target, with a network and in a table",
                [f"SARSA(λ) against Q(λ) in one PQN-style engine (the bootstrap is the only switch), paired seeds; "
                 f"SARSA against Q-Learning in a table with the paper's settings. Margins of no difference, "
                 f"declared before the runs: {', '.join(f'{e} ±{m:g}' for e, m in MARGIN.items())}. "
                 "p-values Holm-adjusted over the whole table."], [("Verdicts", verdicts)]),
        Section("Every method", [
            f"Gymnasium: each seed's final greedy policy in Gymnasium's own environment (gym.make), "
            f"{GYMNASIUM_EPISODES} episodes from the same start states for every seed and method; at the goal: seeds "
            f"whose mean reaches {', '.join(f'{e} {g:g}' for e, g in GOAL.items())}. Final: the greedy return of "
            "the last evaluation round in the port; AUC: its mean over all rounds. Seeds that failed count in "
            "every number."], [("Summary", summary)]),
        aggregate_section(deep, tables, figures),
        Section("Published anchors", ["The zoo's numbers are one trained agent each; ours are IQMs over seeds."],
                [("Anchors", anchors)]),
        Section("Learning curves", figures=curve_figures),
    ]
    path = write_report(out / "report.html", "On- vs off-policy with neural networks", sections, problems)
    return Report(path, lines, problems)
