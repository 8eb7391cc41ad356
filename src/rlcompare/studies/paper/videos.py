"""The paper study's videos: which seeds of each configuration are shown (the median, the lowest and the highest by
final greedy return), at which stages, with their captions, and what each is drawn from."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from rlcompare.report.drawn import Drawn
from rlcompare.report.video import VideoJob, plan_stage_videos
from rlcompare.studies.paper.figures import label
from rlcompare.tabular.results import Results

CONFIGURATIONS = ("random", "q_learning-decay", "q_learning-constant", "sarsa-decay", "sarsa-constant")
"""The paper's five configurations, in the order of its tables."""


def video_seeds(results: Results) -> dict[str, int]:
    """The seeds whose final greedy return is the median, the lowest and the highest (the lower middle one of an
    even count; ties to the earlier seed), in that order and each once."""
    final = results.records.eval_returns[:, -1].mean(axis=-1) if results.records.eval_returns.shape[1] else \
        results.records.returns[:, -1]
    order = np.argsort(final, kind="stable")
    chosen: dict[str, int] = {}
    for role, index in (("median", order[(len(order) - 1) // 2]), ("lowest", order[0]), ("highest", order[-1])):
        seed = int(results.seeds[index])
        if seed not in chosen.values():
            chosen[role] = seed
    return chosen


WATCH_FOR = ("Watch the first seconds: the car must back up the left hill to gain the momentum it lacks; the paper "
             "says SARSA with ε constant learns to push left first and Q-Learning to push forward first.")


def video_plan(study_dir: Path, runs: dict[str, Results], video_seed: int | None) -> list[tuple[str, VideoJob]]:
    """Each video of the paper's configurations with its caption in the report, in the report's order: the median
    seed (by its final greedy return) at every stage of learning, then the lowest and highest seeds' final
    policies; only ``video_seed`` where one is asked for. The random baseline once."""
    plan = []
    for name, results in ((n, r) for n, r in runs.items() if n in CONFIGURATIONS):
        if video_seed is not None or results.config.algorithm == "random":
            chosen = {"": results.seeds[0] if video_seed is None else video_seed}
        else:
            chosen = video_seeds(results)
        for role, seed in chosen.items():
            stages = None if role in ("", "median") else ["final"]
            for job in plan_stage_videos(study_dir / name, study_dir / "videos", seed=seed, stages=stages,
                                         config=results.config):
                stage = "random policy" if results.config.algorithm == "random" else job.stage
                plan.append((f"{label(results)}, {f'{role} ' if role else ''}seed {seed}: {stage}", job))
    return plan


def video_key(runs: dict[str, Results], job: VideoJob) -> str | None:
    """What a video is drawn from (:mod:`rlcompare.report.drawn`): its run and everything the job says but where
    the files go."""
    shown = {field.name: getattr(job, field.name) for field in dataclasses.fields(job)
             if field.name not in ("run_dir", "mp4", "gif")}
    return Drawn.key([runs[job.run_dir.name]], shown | {"files": [path.name for path in job.outputs]})
