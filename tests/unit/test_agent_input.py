"""``agent.act`` checks its observation at the Python boundary: a Box environment's agent takes a real array of
exactly the environment's shape with finite entries, a finite environment's an integer state in range; anything
else is a ``ValueError`` naming what was expected, before compiled code reads it."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.wrappers import DiscretizeObservation
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from rlcompare import ExperimentConfig, load_agent, run
from rlcompare.tabular.agent import GreedyAgent, RandomAgent

BOX_EXPECTED = r"expected shape \(2,\) of finite numbers, as MountainCar-v0's env\.step returns"
STATE_EXPECTED = r"expected an integer state in \[0, 16\), as FrozenLake-v1's env\.step returns"
TINY = {"seeds": (0,), "episodes": 3, "eval_every": 0}


def _train(root: Path, name: str, **config) -> GreedyAgent | RandomAgent:
    run(ExperimentConfig(**TINY, **config), out=root / name)
    return load_agent(root / name, seed=0)


@pytest.fixture(scope="module")
def box_agents(tmp_path_factory: pytest.TempPathFactory) -> dict[str, GreedyAgent | RandomAgent]:
    """Mountain Car agents (observations of shape ``(2,)``) on the grid, on tiles, and the random baseline."""
    root = tmp_path_factory.mktemp("box")
    return {"grid": _train(root, "grid", algorithm="q_learning"),
            "tiles": _train(root, "tiles", algorithm="sarsa", features="tiles"),
            "random": _train(root, "random", algorithm="random")}


@pytest.fixture(scope="module")
def state_agents(tmp_path_factory: pytest.TempPathFactory) -> dict[str, GreedyAgent | RandomAgent]:
    """FrozenLake agents (16 states), greedy and random."""
    root = tmp_path_factory.mktemp("states")
    return {"greedy": _train(root, "greedy", env="FrozenLake-v1", algorithm="q_learning"),
            "random": _train(root, "random", env="FrozenLake-v1", algorithm="random")}


BAD_BOX = {
    "empty": np.empty(0),
    "one element": np.array([-0.5]),
    "three elements": np.array([-0.5, 0.0, 0.01]),
    "nan": np.array([np.nan, 0.0]),
    "inf": np.array([-0.5, np.inf]),
    "-inf in float32": np.array([-np.inf, 0.0], dtype=np.float32),
    "python float": 0.3,
    "numpy scalar": np.float64(-0.5),
    "0-d array": np.array(-0.5),
    "2-D row": np.array([[-0.5, 0.0]]),
    "2-D column": np.array([[-0.5], [0.0]]),
    "2-D square": np.zeros((2, 2)),
    "string": "-0.5 0.0",
    "strings of the right length": ["-0.5", "0.0"],
    "complex": np.array([-0.5 + 0j, 0.0]),
    "bool": np.array([True, False]),
    "object": np.array([-0.5, None], dtype=object),
    "none": None,
    "ragged": [[-0.5], [0.0, 1.0]],
    "dict": {"position": -0.5, "velocity": 0.0},
}


@pytest.mark.parametrize("kind", ["grid", "tiles", "random"])
@pytest.mark.parametrize("case", list(BAD_BOX))
def test_box_agent_refuses_what_is_not_one_observation(box_agents, kind: str, case: str) -> None:
    with pytest.raises(ValueError, match=BOX_EXPECTED) as error:
        box_agents[kind].act(BAD_BOX[case])
    assert len(str(error.value)) < 200


def test_the_message_says_what_came() -> None:
    agent = RandomAgent(seed=0, stage="final")  # Mountain Car's contract by default
    for observation, given_ in [(np.zeros(3), r"got shape \(3,\) float64;"), (np.zeros((2, 1)), r"shape \(2, 1\)"),
                                (np.array([np.nan, 0.0]), r"got \[nan, 0\.0\];"), (None, "got NoneType None;"),
                                (np.array([1j, 0]), "complex128"),
                                ("x" * 1000, r"got str 'xxx+… \(1,002 characters\);")]:
        with pytest.raises(ValueError, match=given_):
            agent.act(observation)


@pytest.mark.parametrize("kind", ["grid", "tiles"])
def test_float32_observations_from_gymnasium_act_as_their_float64_copies(box_agents, kind: str) -> None:
    agent = box_agents[kind]
    agent = dataclasses.replace(agent, weights=np.random.default_rng(0).standard_normal(agent.weights.shape))
    env = gym.make("MountainCar-v0")
    observation, _ = env.reset(seed=1)
    actions = []
    for step in range(200):
        assert observation.dtype == np.float32
        action = agent.act(observation)
        assert action == agent.act(observation.astype(np.float64)) == agent.act(observation.tolist())
        actions.append(action)
        observation, *_ = env.step(action if step % 3 else 2)
    env.close()
    assert len(set(actions)) > 1  # the weights tell the cells apart


def test_the_grid_agent_reads_the_cell_of_gymnasiums_discretize_observation(box_agents) -> None:
    agent = box_agents["grid"]
    weights = np.random.default_rng(1).standard_normal(agent.weights.shape)
    agent = dataclasses.replace(agent, weights=weights)
    wrapper = DiscretizeObservation(gym.make("MountainCar-v0"), bins=20)
    inside = np.random.default_rng(2).uniform(wrapper.env.observation_space.low, wrapper.env.observation_space.high,
                                              (200, 2)).astype(np.float32)
    for observation in inside:
        assert agent.act(observation) == int(np.argmax(weights[wrapper.observation(observation)]))
    wrapper.close()


def test_finite_observations_beyond_the_box_land_in_the_edge_cells(box_agents) -> None:
    """Gymnasium's grid clips; so do ours and the tiles."""
    for kind in ("grid", "tiles"):
        agent = box_agents[kind]
        agent = dataclasses.replace(agent, weights=np.random.default_rng(3).standard_normal(agent.weights.shape))
        assert agent.act(np.array([5.0, 1.0])) == agent.act(np.array([0.6, 0.07]))
        assert agent.act(np.array([-1e300, -1e300])) == agent.act(np.array([-1.2, -0.07]))
        assert agent.act(np.array([3, 0], dtype=np.int8)) == agent.act(np.array([3.0, 0.0]))


@settings(max_examples=60, deadline=None)
@given(shape=hnp.array_shapes(min_dims=0, max_dims=4, min_side=0, max_side=5).filter(lambda s: s != (2,)),
       kind=st.sampled_from(["grid", "tiles", "random"]))
def test_any_other_shape_is_refused(box_agents, shape: tuple[int, ...], kind: str) -> None:
    with pytest.raises(ValueError, match=BOX_EXPECTED):
        box_agents[kind].act(np.zeros(shape))


@settings(max_examples=60, deadline=None)
@given(observation=hnp.arrays(hnp.floating_dtypes(sizes=(32, 64)), (2,)),
       kind=st.sampled_from(["grid", "tiles", "random"]))
def test_any_finite_pair_gives_an_action_and_any_other_is_refused(box_agents, observation: np.ndarray,
                                                                  kind: str) -> None:
    agent = box_agents[kind]
    if np.isfinite(observation).all():
        assert agent.act(observation) in range(3)
    else:
        with pytest.raises(ValueError, match=BOX_EXPECTED):
            agent.act(observation)


@pytest.mark.parametrize("kind", ["greedy", "random"])
def test_finite_agent_takes_integer_states_in_range(state_agents, kind: str) -> None:
    agent = state_agents[kind]
    for state in (0, 15, np.int64(7), np.uint8(3), np.array(5), np.array(15, dtype=np.int32)):
        assert agent.act(state) in range(4)
    env = gym.make("FrozenLake-v1")
    state, _ = env.reset(seed=0)
    assert agent.act(state) in range(4)  # what Gymnasium returns
    env.close()


BAD_STATES = {"negative": -1, "past the last": 16, "huge": 2**70, "numpy past the last": np.int64(16),
              "float": 3.0, "numpy float": np.float64(3), "0-d float array": np.array(3.0), "bool": True,
              "numpy bool": np.bool_(False), "0-d object array": np.array(3, dtype=object),
              "one-element array": np.array([3]), "empty": np.empty(0, dtype=int),
              "string": "3", "none": None, "complex": 3 + 0j, "list": [3]}


@pytest.mark.parametrize("kind", ["greedy", "random"])
@pytest.mark.parametrize("case", list(BAD_STATES))
def test_finite_agent_refuses_anything_else(state_agents, kind: str, case: str) -> None:
    with pytest.raises(ValueError, match=STATE_EXPECTED):
        state_agents[kind].act(BAD_STATES[case])


@settings(max_examples=60, deadline=None)
@given(state=st.integers().filter(lambda s: not 0 <= s < 16))
def test_any_integer_out_of_range_is_refused(state_agents, state: int) -> None:
    with pytest.raises(ValueError, match=STATE_EXPECTED):
        state_agents["greedy"].act(state)


def test_a_refused_observation_draws_nothing_from_the_random_agent(box_agents) -> None:
    agent = dataclasses.replace(box_agents["random"])  # a fresh generator from the same seed
    fresh = dataclasses.replace(box_agents["random"])
    with pytest.raises(ValueError, match=BOX_EXPECTED):
        agent.act(np.zeros(3))
    assert [agent.act(np.zeros(2)) for _ in range(20)] == [fresh.act(np.zeros(2)) for _ in range(20)]


def test_an_environment_given_to_load_agent_must_have_the_runs_actions(tmp_path: Path) -> None:
    """Mountain Car's agent chooses among 3 actions: CartPole's 2 are refused in one line naming ``env``;
    Mountain Car's own are taken, and ε's random actions are drawn from them."""
    from rlcompare.validation import ConfigError

    run(ExperimentConfig(**TINY, algorithm="q_learning"), out=tmp_path / "run")
    with pytest.raises(ConfigError, match=r"env: got 'an environment with the action space Discrete\(2\)'; allowed: "
                                          r"one of 3 actions, as gymnasium.make\('MountainCar-v0'\) makes"):
        load_agent(tmp_path / "run", env=gym.make("CartPole-v1"))
    env = gym.make("MountainCar-v0")
    assert load_agent(tmp_path / "run", env=env).act(env.reset(seed=0)[0]) in range(3)
    explorer = load_agent(tmp_path / "run", epsilon=1.0, env=env)
    assert {explorer.act(env.reset(seed=0)[0]) for _ in range(100)} == {0, 1, 2}
