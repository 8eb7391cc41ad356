"""Videos of MinAtar agents: MinAtar's own colours (the reference's ``rgb_array``), the episode that a greedy
evaluation plays from the same key, and the frames the stages make side by side."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jax")
pytest.importorskip("minatar")

import jax
from minatar.gym import BaseEnv

from rlcompare.deep import float64
from rlcompare.deep.config import DeepConfig
from rlcompare.deep.methods import deep_method
from rlcompare.deep.playback import EPISODE_KEY, play_stages, stage_steps, stage_titles
from rlcompare.deep.results import DeepResults
from rlcompare.deep.rollout import evaluate
from rlcompare.deep.train import params_template
from rlcompare.envs import minatar
from rlcompare.envs.minatar import CELL, palette, picture
from rlcompare.experiment.runner import run
from rlcompare.report import frames
from rlcompare.report.stage_video import frames_of, render_stages


@pytest.mark.parametrize("game", list(minatar.GAMES))
def test_pictures_are_in_the_reference_s_own_colours(game: str) -> None:
    reference = BaseEnv(game, render_mode="rgb_array")
    reference.reset(seed=3)
    rng = np.random.default_rng(3)
    colours = palette(reference.game.state_shape()[-1])
    for _ in range(60):
        expected = np.round(np.asarray(reference.render()) * 255).astype(np.uint8)
        np.testing.assert_array_equal(picture(reference.game.state(), colours, cell=1), expected)
        if reference.step(int(rng.integers(6)))[2]:
            reference.reset()


def test_a_cell_is_drawn_as_a_square_of_its_colour() -> None:
    observation = np.zeros((10, 10, 4), bool)
    observation[2, 7, [0, 3]] = True  # two channels in one cell: the higher one's colour
    image = picture(observation, palette(4))
    assert image.shape == (10 * CELL, 10 * CELL, 3)
    cell = image[2 * CELL:3 * CELL, 7 * CELL:8 * CELL]
    np.testing.assert_array_equal(cell, np.broadcast_to(palette(4)[4], (CELL, CELL, 3)))
    assert not image[:2 * CELL].any()
    assert not image[3 * CELL:].any()


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> DeepResults:
    config = DeepConfig(algorithm="pqn_q_lambda", env="MinAtar/Breakout-v0", seeds=(0, 1), eval_rounds=10,
                        eval_episodes=2, vmap_width=2,
                        hyperparameters={"total_steps": 10 * 4 * 16 * 8, "n_envs": 16, "n_steps": 8})
    return run(config, out=tmp_path_factory.mktemp("minatar-video") / "run")


@float64
def evaluated_episode(results: DeepResults, seed: int, stage: str) -> tuple[float, int]:
    config = results.config
    act = deep_method(config.algorithm).module.act(config.method_config(), config.environment)
    params = results.seed_params(seed, params_template(config), stage)
    returns, lengths, _ = evaluate(config.environment, act, params, jax.random.key(EPISODE_KEY), 1)
    return float(returns[0]), int(lengths[0])


@pytest.mark.slow("trains a network and renders its stages")
def test_each_stage_plays_the_episode_its_evaluation_would(results: DeepResults) -> None:
    played = play_stages(results, seed=1)
    for index, stage in enumerate(results.stages):
        length = int(played.lengths[index])
        assert played.ended[index]  # Breakout's greedy episodes are short
        assert (played.returns[index, length], length) == evaluated_episode(results, 1, stage)
        assert np.all(played.observations[index, length:] == played.observations[index, length])


@pytest.mark.slow("trains a network and renders its stages")
def test_the_frames_show_every_stage_side_by_side_until_the_longest_ends(results: DeepResults) -> None:
    played = play_stages(results, seed=0)
    colours = palette(played.observations.shape[-1])
    video = list(frames_of(played, stage_titles(results), lambda state: picture(state, colours)))
    assert len(video) == played.lengths.max() + 1
    last = frames.unpack(video[-1])
    height = 10 * CELL
    for index in range(3):
        left = index * (10 * CELL + 6)
        panel = last[-height:, left:left + 10 * CELL]
        np.testing.assert_array_equal(panel, picture(played.observations[index, -1], colours))
    assert stage_steps(results) == {"early": 512, "middle": 2_560, "final": 5_120}


@pytest.mark.slow("trains a network and renders its stages")
def test_a_video_and_its_preview_are_written(results: DeepResults, tmp_path) -> None:
    played = play_stages(results, 0, max_steps=30)
    colours = palette(played.observations.shape[-1])
    paths = render_stages(played, stage_titles(results), lambda state: picture(state, colours),
                          tmp_path / "breakout.mp4", tmp_path / "breakout.gif")
    assert [p.name for p in paths] == ["breakout.mp4", "breakout.gif"]
    assert all(p.stat().st_size > 1_000 for p in paths)
