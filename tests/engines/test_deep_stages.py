"""The deep engine keeps its networks at three stages of learning, as the paper shows its agents: the kept
networks are those the evaluations of their rounds played, and a run directory stores and loads them."""

from __future__ import annotations

import dataclasses

import jax
import numpy as np
import pytest

pytest.importorskip("jax")

from rlcompare.deep import pqn, use_compilation_cache
from rlcompare.deep.agent import agent
from rlcompare.deep.classic import CARTPOLE
from rlcompare.deep.config import DeepConfig
from rlcompare.deep.results import DeepResults, merge_seeds
from rlcompare.deep.rollout import STAGES, evaluate, stage_rounds
from rlcompare.deep.train import compiled_training, seed_keys
from rlcompare.experiment import rundir
from rlcompare.experiment.engines import load_run
from rlcompare.experiment.rundir import write_results
from rlcompare.experiment.runner import run

SEEDS = (0, 1)
CONFIG = DeepConfig(algorithm="pqn_q_lambda", env="CartPole-v1", seeds=SEEDS, vmap_width=2,
                    hyperparameters={"total_steps": 41000})
"""The deep study's Q(λ) on CartPole at its tiny size (``tests/studies/test_deep_study.py``): one program, compiled
once for this module and found in JAX's compilation cache where the study's tests compiled it."""
ROUNDS, EPISODES = CONFIG.eval_rounds, CONFIG.eval_episodes


def test_the_stages_are_the_rounds_at_a_tenth_and_half_of_the_training() -> None:
    assert [name for name, _ in STAGES] == ["early", "middle"]
    assert stage_rounds(20) == (1, 9)
    assert stage_rounds(10) == (0, 4)
    assert stage_rounds(1) == (0, 0)  # a one-round training keeps its only round at every stage


@pytest.mark.slow("compiles and trains deep programs")
def test_a_kept_network_plays_its_round_s_evaluation_again() -> None:
    use_compilation_cache()
    assert stage_rounds(ROUNDS) == (1, 9)
    keys = seed_keys(SEEDS)
    output = compiled_training(CONFIG)(keys)  # the program run() trains with
    act = pqn.act(CONFIG.method_config(), CARTPOLE)
    round_keys = jax.vmap(lambda key: jax.random.split(jax.random.split(key)[1], ROUNDS))(keys)
    returns = np.asarray(output.eval_returns)
    for index, after in enumerate(stage_rounds(ROUNDS)):
        params = jax.tree.map(lambda leaf, i=index: leaf[:, i], output.snapshots)
        eval_keys = jax.vmap(lambda key, r=after: jax.random.split(key[r])[1])(round_keys)
        again = jax.vmap(lambda p, k: evaluate(CARTPOLE, act, p, k, EPISODES)[0])(params, eval_keys)
        np.testing.assert_array_equal(np.asarray(again), returns[:, after])
    assert not np.array_equal(returns[:, stage_rounds(ROUNDS)[0]], returns[:, -1])  # the stages differ


@pytest.fixture(scope="module")
def stored(tmp_path_factory: pytest.TempPathFactory) -> tuple[DeepResults, DeepResults]:
    out = tmp_path_factory.mktemp("stages") / "run"
    results = run(CONFIG, out=out)
    return results, load_run(out)


@pytest.mark.slow("compiles and trains deep programs")
def test_a_run_directory_keeps_every_stage(stored: tuple[DeepResults, DeepResults]) -> None:
    results, loaded = stored
    assert results.stages == loaded.stages == ["early", "middle", "final"]
    for stage in ("early", "middle"):
        assert results.snapshots[stage].keys() == results.params.keys()
        for name, array in results.snapshots[stage].items():
            np.testing.assert_array_equal(loaded.snapshots[stage][name], array)
    assert not np.array_equal(next(iter(loaded.snapshots["early"].values())), next(iter(loaded.params.values())))


@pytest.mark.slow("compiles and trains deep programs")
def test_an_agent_acts_with_the_network_of_its_stage(stored: tuple[DeepResults, DeepResults]) -> None:
    _, loaded = stored
    observation = np.array([0.01, 0.5, -0.02, -0.4])
    agents = {stage: agent(loaded, seed=1, stage=stage) for stage in loaded.stages}
    for stage, one in agents.items():
        first_leaf = jax.tree.leaves(one.params)[-1]
        stored_leaf = (loaded.params if stage == "final" else loaded.snapshots[stage])[
            jax.tree_util.keystr(jax.tree_util.tree_flatten_with_path(one.params)[0][-1][0])]
        np.testing.assert_array_equal(np.asarray(first_leaf), stored_leaf[1])
        assert one.act(observation) in (0, 1)
    with pytest.raises(KeyError, match="stages: \\['early', 'middle', 'final'\\]"):
        agent(loaded, seed=1, stage="halfway")


@pytest.mark.slow("compiles and trains deep programs")
def test_merged_seeds_keep_their_stages_in_order(stored: tuple[DeepResults, DeepResults]) -> None:
    _, loaded = stored
    others = dataclasses.replace(loaded, config=dataclasses.replace(loaded.config, seeds=(5, 6)))
    merged = merge_seeds([loaded, others])
    for stage in ("early", "middle"):
        for name, array in loaded.snapshots[stage].items():
            np.testing.assert_array_equal(merged.snapshots[stage][name], np.concatenate([array, array]))


@pytest.mark.slow("compiles and trains deep programs")
def test_a_run_written_before_the_stages_were_kept_offers_its_final_network(
        stored: tuple[DeepResults, DeepResults], tmp_path) -> None:
    results, _ = stored
    older = DeepResults(results.config, results.episodes, results.evaluations, results.params, results.meta)
    write_results(tmp_path / "older", older)
    with np.load(tmp_path / "older" / rundir.PARAMS_FILE) as arrays:
        assert not any(name.startswith(("early", "middle")) for name in arrays.files)
    loaded = load_run(tmp_path / "older")
    assert loaded.stages == ["final"]
    with pytest.raises(KeyError, match="'early' is not in this run"):
        agent(loaded, seed=0, stage="early")
