"""``rlcompare reproduce atari``: the paper's question on the Atari 2600 itself, through Gymnasium's ALE.

A configuration of the paired study (:mod:`rlcompare.studies.paired`), as MinAtar's is: SARSA(λ) against Q(λ) in
one PQN-style engine (the bootstrap the only switch), with Mnih et al. (2015)'s network and purejaxql's Atari
settings, on paired seeds, under Machado et al. (2018)'s protocol (``docs/atari.md``), on named sets of games and
budgets. Scores are human-normalised from the published random and human scores
(:mod:`rlcompare.envs.atari.scores`), pooled over games as rliable does, and, where the five games of Atari-5 ran,
read through Aitchison et al. (2023)'s estimate of the median over 57 games. Each agent, loaded by
:func:`rlcompare.load_agent`, plays Gymnasium's own ``ALE/<Game>-v5`` at three stages of learning, in the game's
own pixels.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rlcompare.deep.methods import DEEP_METHODS
from rlcompare.deep.playback import stage_titles
from rlcompare.deep.results import DeepResults
from rlcompare.envs.atari import games as atari
from rlcompare.envs.atari import scores as atari_scores
from rlcompare.experiment import store
from rlcompare.formatting import number
from rlcompare.report.aggregate_plots import across_section
from rlcompare.report.page import Section, write_report, write_table
from rlcompare.report.stage_video import render_stages
from rlcompare.stats import intervals as stats
from rlcompare.studies import paired_report
from rlcompare.studies.atari import play as atari_play
from rlcompare.studies.atari import random_policy
from rlcompare.studies.atari.plan import (
    ATARI,
    BUDGETS,
    EPSILON,
    LEARNT,
    MARGIN,
    OVERALL_MARGIN,
    STUDY,
    plan_of,
    plumbing,
    title,
)
from rlcompare.studies.atari.plan import study_plan as study_plan
from rlcompare.studies.atari.play import play_stages, upscaled
from rlcompare.studies.interface import UI, Report
from rlcompare.studies.paired import cluster, final_returns, train
from rlcompare.studies.registry import AtariOptions

OVER_GAMES = "the games (each seed's interquartile mean: the middle half of its games)"
"""What the overall row is taken over, in the report's words."""


def run(out: Path, options: AtariOptions, ui: UI, *, study: str = STUDY, force: bool = False) -> dict[str, Any]:
    """Every training of the plan, one after another on this machine (its emulators are the process's), or as
    tasks of the Ray cluster at ``options.address`` (each a process of its own)."""
    plan = plan_of(options)
    backend = cluster(options.address)
    where = f"on Ray at {options.address}" if backend else "on this machine, one after another"
    ui.say(f"Atari 2600, {atari.PROTOCOL.summary}: {len(plan.configs())} trainings x {len(plan.seeds)} seeds x "
           f"{plan.steps_text()} (budget '{options.budget}': {BUDGETS[options.budget].takes}) {where}.")
    return train(out, STUDY, plan, ui, force=force, backend=backend)


# --- what the report adds to the paired study's --------------------------------------------------------------

def human_normalised(results: DeepResults) -> np.ndarray:
    """Each seed's final return, human-normalised (random 0, human 1)."""
    return np.asarray(atari_scores.human_normalised(title(results.config.env), final_returns(results)))


MACHADO_EPISODES = 100
"""Machado et al. (2018, section 5.2)'s measure of a training: the mean return of its last 100 training episodes."""


def last_training_episodes(results: DeepResults, count: int = MACHADO_EPISODES) -> np.ndarray:
    """Each seed's mean return over its last ``count`` training episodes (Machado et al.'s measure, ε-greedy as
    they were played; all of them where a seed finished fewer, NaN where it finished none)."""
    by_seed = results.episodes.groupby("seed")["return"]
    return np.array([by_seed.get_group(seed).to_numpy()[-count:].mean() if seed in by_seed.groups else np.nan
                     for seed in results.seeds])


def cut_episodes(results: DeepResults) -> tuple[int, int]:
    """``(cut, all)``: the evaluation episodes that reached the protocol's 108,000 frames, of all played."""
    cut = ~results.evaluations["terminated"].to_numpy()
    return int(cut.sum()), int(cut.size)


def summary_table(runs: dict[str, DeepResults]) -> pd.DataFrame:
    """Per game and method: the final return (mean and IQM, 95% intervals), Machado et al.'s measure (the last 100
    training episodes, with the fewest training episodes a seed finished), human-normalised, the published random
    and human scores, and the evaluation episodes cut."""
    rows = []
    for results in runs.values():
        game = atari_scores.GAMES[title(results.config.env)]
        cut, played = cut_episodes(results)
        finished = results.episodes.groupby("seed").size().reindex(list(results.seeds), fill_value=0)
        rows.append({"game": game.title, "method": DEEP_METHODS[results.config.algorithm].label,
                     "final return, mean": stats.interval(final_returns(results)).format(1),
                     "final return, IQM": stats.interval(final_returns(results), "iqm").format(1),
                     "last 100 training episodes, mean": stats.interval(last_training_episodes(results)).format(1),
                     "training episodes, fewest a seed": int(finished.min()),
                     "human-normalised, mean": stats.interval(human_normalised(results)).format(3),
                     "random": game.random, "human": game.human, "seeds": len(results.seeds),
                     "evaluation episodes cut at 108,000 frames": f"{cut} of {played}",
                     "steps/s": round(results.meta["timings"]["steps_per_second"])})
    return pd.DataFrame(rows)


def atari5_estimate(normalised: dict[str, np.ndarray]) -> stats.Estimate:
    """Aitchison et al.'s estimate of the 57-game median (:func:`~rlcompare.envs.atari.scores.atari5_median`) of
    each Atari-5 game's human-normalised score averaged over seeds first, as their code takes it of an algorithm's
    scores (the mean of each seed's estimate is another, lower number: the model is concave), with a 95%
    percentile bootstrap interval over seeds resampled together across the five games."""
    games = atari_scores.ATARI_5

    def estimate(*per_game: np.ndarray, axis: int = -1) -> np.ndarray | float:
        means = {t: np.asarray(np.mean(v, axis=axis)) for t, v in zip(games, per_game, strict=True)}
        found: np.ndarray = atari_scores.atari5_median(means)
        return found

    return stats.joint_interval(estimate, tuple(normalised[t] for t in games))


def atari5_table(runs: dict[str, DeepResults]) -> pd.DataFrame | None:
    """Per method that ran every Atari-5 game on the same seeds: the estimate of the median human-normalised score
    over the 57 games from its mean scores (:func:`atari5_estimate`) with its 95% interval; None where no method
    did."""
    rows = []
    for method in sorted({r.config.algorithm for r in runs.values()}):
        ran = {title(r.config.env): r for r in runs.values() if r.config.algorithm == method}
        if not set(atari_scores.ATARI_5) <= set(ran) or len({ran[t].seeds for t in atari_scores.ATARI_5}) != 1:
            continue
        estimate = atari5_estimate({t: human_normalised(ran[t]) for t in atari_scores.ATARI_5})
        rows.append({"method": DEEP_METHODS[method].label,
                     "Atari-5 estimate of the 57-game median": estimate.format(3),
                     "seeds": len(ran[atari_scores.ATARI_5[0]].seeds)})
    return pd.DataFrame(rows) if rows else None


def video_cells(run_dirs: dict[str, Path], runs: dict[str, DeepResults], videos: Path
                ) -> tuple[list[tuple[str, str, str]], pd.DataFrame]:
    """Each training's first seed at its three stages of learning, loaded by ``load_agent`` and playing Gymnasium's
    ``ALE/<Game>-v5``: a video per game and method, and a table of what each stage scored there."""
    cells, rows = [], []
    for name, results in runs.items():
        seed = results.seeds[0]
        played = play_stages(run_dirs[name], results, seed, atari_play.STAGE_STEPS)
        label = f"{title(results.config.env)}, {DEEP_METHODS[results.config.algorithm].label}, seed {seed}"
        mp4, gif = render_stages(played, stage_titles(results), upscaled, videos / f"{name}.mp4",
                                 videos / f"{name}.gif")
        cells.append((f"videos/{mp4.name}", f"videos/{gif.name}", f"{label}: {', '.join(results.stages)}"))
        rows += [{"game": title(results.config.env), "method": DEEP_METHODS[results.config.algorithm].label,
                  "seed": seed, "stage": stage, "return": float(played.returns[i, played.lengths[i]]),
                  "steps": int(played.lengths[i]), "game over": bool(played.ended[i])}
                 for i, stage in enumerate(results.stages)]
    return cells, pd.DataFrame(rows)


def report(out: Path, ui: UI | None = None, *, runs: dict[str, Any] | None = None, videos: bool = True) -> Report:
    """Tables, verdicts, figures, videos and ``report.html`` of an Atari study directory, from its run
    directories."""
    with store.rewriting(Path(out), "study"):
        return _build_report(Path(out), videos)


def _build_report(out: Path, videos: bool) -> Report:
    found = paired_report.findings(out, ATARI)
    runs, aggregates, files = found.runs, found.aggregates, found.files
    summary = summary_table(runs)
    files["summary"] = write_table(summary, out / "tables", "atari_summary")
    atari5 = atari5_table(runs)
    if atari5 is not None:
        files["atari5"] = write_table(atari5, out / "tables", "atari_atari5")
    compared = {title(key.env): j for key, j in found.judged.items()}
    steps = max((r.config.steps_trained for r in runs.values()), default=0)
    seeds = min((len(r.seeds) for r in runs.values()), default=0)
    games = [title(env) for env in found.envs]
    floors = {t: atari_scores.GAMES[t].random for t in games}
    humans = {t: atari_scores.GAMES[t].human for t in games}
    randoms = random_policy.random_table(random_policy.random_episodes(out, games, random_policy.EPISODES), MARGIN)
    files["random"] = write_table(randoms, out / "tables", "atari_random")
    lines = paired_report.answer(compared, seeds, over=OVER_GAMES, floors=floors, references=humans,
                                 measure=f"final return at ε = {EPSILON:g}", reference="the human")
    if steps and plumbing(steps):
        lines.insert(0, f"A plumbing check: no verdict is possible ({plumbing(steps)}).")
    unlearnt = paired_report.not_learnt(compared)
    if unlearnt:
        lines.append(f"Not learnt at this budget ({steps:,} steps a training): {', '.join(unlearnt)}; the "
                     "published learning curves of PQN and DQN need millions of steps (docs/atari.md).")
    cells, played = video_cells({name: out / name for name in runs}, runs, out / "videos") if videos else ([], None)
    if played is not None:
        files["gymnasium"] = write_table(played, out / "tables", "atari_gymnasium")
    curve_figures = [paired_report.curves_drawn(runs, env, "frames", out / "figures" / f"curves-{env}.png",
                                                f"frames ({atari.PROTOCOL.frameskip} an agent step)",
                                                atari.PROTOCOL.frameskip) for env in found.envs]
    sections = [
        paired_report.answer_section(lines, runs, found.envs, title, out / "figures"),
        Section("On-policy or off-policy target on the Atari 2600", [
            f"{paired_report.PQN_PAIR}, each seed's mean return in the last evaluation round ({EPSILON:g}-greedy, "
            f"Mnih et al. 2015's evaluation). Protocol: {atari.PROTOCOL.summary}. Training: {steps:,} agent steps "
            f"({4 * steps:,} frames) per seed. "
            "Each game's scale runs from the published random score to the published human score "
            "(human-normalised: random 0, human 1; Mnih et al. 2015's table, as docs/atari.md cites). "
            + paired_report.learnt_rule("the random score", LEARNT, MARGIN,
                                        [f"{t} ±{number(MARGIN * (humans[t] - floors[t]))}" for t in games])
            + f", ±{OVERALL_MARGIN:g} of the human-normalised score over the games (each seed's interquartile "
            "mean). p-values Holm-adjusted over the games and the overall row."],
                [("Verdicts", found.verdicts, files["verdicts"])]),
        Section("Every game", [
            "Final return: each seed's mean over the last evaluation round's episodes; human-normalised against the "
            "published random and human scores. Beside it, Machado et al. (2018)'s measure: each seed's mean over its "
            f"last {MACHADO_EPISODES} training episodes, played ε-greedily as they were (all of them where a seed "
            "finished fewer: the fewest a seed finished is given). Episodes that reached 108,000 frames are cut "
            "there (the protocol's limit) and counted."], [("Summary", summary, files["summary"])]),
        Section("The 57-game median, estimated from Atari-5", [
            "Aitchison, Sweetser and Hutter (2023) estimate the median human-normalised score over the 57 games from "
            "five (Battle Zone, Double Dunk, Name This Game, Phoenix, Q*bert) by a regression on log scores "
            "(about a tenth relative error), taken as their code takes it: of each game's score averaged over the "
            "seeds, with a 95% bootstrap interval over the seeds."
            if atari5 is not None else "Needs a method run on all five Atari-5 games (--games atari5)."],
            [("Atari-5 estimate", atari5, files["atari5"])] if atari5 is not None else []),
        Section("The random policy under this protocol", [
            f"{random_policy.EPISODES} episodes of the uniformly random policy on each game, played here under the "
            "protocol above (the evaluation's loop at ε = 1; every episode in "
            f"{random_policy.TABLE}), beside the published random score, which DQN's protocol measured (no-op "
            "starts, no sticky actions), and the game's margin: where one episode's standard deviation is many "
            "margins, the game's verdict needs the seeds to outnumber that noise."],
            [("Random policy", randoms, files["random"])]),
        across_section(
            "Across games",
            "Human-normalised final scores pooled over the games as rliable does (Agarwal et al. 2021): interval "
            "estimates, the probability of improvement, performance profiles and sample-efficiency curves, with 95% "
            "stratified bootstrap intervals.",
            aggregates, files, "Interval estimates of human-normalised final returns",
            "Across games: needs two or more games and methods."),
        Section("Learning curves", figures=curve_figures),
        Section("The agents at three stages of learning, in Gymnasium", [
            "Each training's first seed, loaded by rlcompare.load_agent at a tenth, half and the end of its training, "
            "playing Gymnasium's own ALE/<Game>-v5 under the same protocol (AtariPreprocessing and "
            f"FrameStackObservation as in training) from the same start, {EPSILON:g}-greedy with the same draws, for "
            f"at most {atari_play.STAGE_STEPS:,} steps, in the game's own pixels." if videos else
            "Videos were not rendered (--no-videos)."],
            [("What each stage scored in Gymnasium", played, files["gymnasium"])] if played is not None else [],
            videos=cells),
    ]
    page = write_report(out / "report.html", "Atari 2600: on- or off-policy target with a network", sections,
                        found.problems)
    return Report(page, lines, found.problems)

