"""The paper report's videos: each learner's median seed at every stage, then its lowest and highest seeds' final
policies, so that a reader sees more than one seed and knows which one is typical."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from rlcompare.studies.paper.videos import video_plan, video_seeds


def runs_with_final_returns(final: list[float]) -> SimpleNamespace:
    eval_returns = np.zeros((len(final), 3, 2))
    eval_returns[:, -1, :] = np.asarray(final)[:, None]
    return SimpleNamespace(seeds=(10, 11, 12, 13, 14)[:len(final)],
                           records=SimpleNamespace(eval_returns=eval_returns, returns=np.zeros((len(final), 5))))


def test_the_median_lowest_and_highest_seeds_by_final_greedy_return() -> None:
    assert video_seeds(runs_with_final_returns([-150.0, -300.0, -120.0, -200.0, -160.0])) == {
        "median": 14, "lowest": 11, "highest": 12}
    assert video_seeds(runs_with_final_returns([-150.0, -300.0, -120.0, -200.0])) == {
        "median": 13, "lowest": 11, "highest": 12}  # even: the lower middle one
    assert video_seeds(runs_with_final_returns([-150.0, -150.0])) == {"median": 10, "highest": 11}
    assert video_seeds(runs_with_final_returns([-150.0])) == {"median": 10}


def test_the_plan_shows_the_median_seed_at_every_stage_and_the_extremes_at_the_end(tmp_path) -> None:
    from rlcompare.studies.paper.report import load_study
    from rlcompare.studies.paper.study import paper_configs, reproduce

    configs = [c for c in paper_configs((0, 1, 2), episodes=60, max_steps=200, eval_every=20, eval_episodes=2)
               if c.name in ("random", "sarsa-constant")]
    list(reproduce(tmp_path, configs))
    runs, _ = load_study(tmp_path)
    plan = video_plan(tmp_path, runs, None)
    chosen = video_seeds(runs["sarsa-constant"])
    expected = [f"median seed {chosen['median']}: {stage}" for stage in ("early", "middle", "final")]
    expected += [f"{role} seed {seed}: final" for role, seed in chosen.items() if role != "median"]
    assert [caption.rsplit(", ", 1)[1] for caption, _ in plan] == ["seed 0: random policy", *expected]
    assert video_plan(tmp_path, runs, 2)[1][0].endswith("seed 2: early")  # a seed asked for: that seed alone
