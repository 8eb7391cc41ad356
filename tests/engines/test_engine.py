"""The engine in the paper's setting (Mountain Car on a 20 x 20 grid): reproducibility, common random numbers,
truncation, and one episode by hand."""

from __future__ import annotations

import gymnasium as gym
import numba
import numpy as np
import pytest

from rlcompare.algorithms.policies import RandomActions, epsilon_greedy_action, uniform_action
from rlcompare.algorithms.registry import METHODS
from rlcompare.algorithms.schedules import linear_decay_epsilon
from rlcompare.algorithms.td import QLearning, Sarsa
from rlcompare.envs import mountain_car
from rlcompare.envs.discretize import cell_of, make_grid
from rlcompare.rng import stream_state
from rlcompare.tabular import state as streams
from rlcompare.tabular.runs import train_block, train_runs
from rlcompare.tabular.state import Records, Settings, allocate_records, initial_state

SEEDS = [0, 1, 2, 3, 4]
EPISODES = 300
MAX_STEPS = 1000
BINS = 20
ALPHA = 0.05
GAMMA = 0.9
EVAL_EVERY = 50
EVAL_EPISODES = 5
SNAPSHOT_EPISODES = (100, 300)
ENV = mountain_car.MountainCar()
GRID = make_grid(mountain_car.OBSERVATION_LOW, mountain_car.OBSERVATION_HIGH, BINS)
RULES = {
    "random": RandomActions(mountain_car.N_ACTIONS),
    "q_learning": QLearning(draw_before=False),  # Algorithm 1: A' drawn after the update
    "sarsa": Sarsa(draw_before=True),  # Algorithm 2: A' drawn before the update
}
EPSILONS = linear_decay_epsilon(EPISODES, 1.0, 0.01, 0.5)
TRAINING_FIELDS = ("returns", "lengths", "terminated", "snapshots", "visits")
EVAL_FIELDS = ("eval_returns", "eval_lengths", "eval_terminated")


def make_settings(
    *,
    max_steps: int = MAX_STEPS,
    truncation_as_terminal: bool = False,
    eval_every: int = EVAL_EVERY,
    alpha: float = ALPHA,
    gamma: float = GAMMA,
) -> Settings:
    """Settings with the scalar types the engine is compiled for (another type would compile anew)."""
    return Settings(
        alpha=float(alpha),
        gamma=float(gamma),
        max_steps=int(max_steps),
        truncation_as_terminal=bool(truncation_as_terminal),
        eval_every=int(eval_every),
    )


def train(
    algorithm: str = "q_learning",
    *,
    seeds=SEEDS,
    episodes: int = EPISODES,
    chunks=None,
    eval_every: int = EVAL_EVERY,
    eval_episodes: int = EVAL_EPISODES,
    max_steps: int = MAX_STEPS,
    truncation_as_terminal: bool = False,
    epsilons: np.ndarray = EPSILONS,
):
    """Train every seed with ``train_runs``, over ``chunks`` of episodes (one call by default)."""
    settings = make_settings(max_steps=max_steps, truncation_as_terminal=truncation_as_terminal, eval_every=eval_every)
    state = initial_state(list(seeds), GRID.n_cells, mountain_car.N_ACTIONS)
    rounds = episodes // eval_every if eval_every else 0
    snapshots = np.array([e for e in SNAPSHOT_EPISODES if e <= episodes], dtype=np.int64)
    records = allocate_records(len(seeds), episodes, rounds, eval_episodes, snapshots, state.w.shape[1:])
    for first, stop in chunks or [(0, episodes)]:
        train_runs(RULES[algorithm], settings, ENV, GRID, state, epsilons, first, stop, records)
    return state, records


def assert_records_equal(a: Records, b: Records, fields=Records._fields) -> None:
    for field in fields:
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)


def assert_results_equal(a, b) -> None:
    (state_a, records_a), (state_b, records_b) = a, b
    np.testing.assert_array_equal(state_a.w, state_b.w)
    np.testing.assert_array_equal(state_a.rng, state_b.rng)
    assert_records_equal(records_a, records_b)


@pytest.fixture(scope="module")
def q_learning_result():
    """Q-Learning, 5 seeds x 300 episodes, trained once for the module."""
    return train("q_learning")


@pytest.fixture(scope="module")
def sarsa_result():
    return train("sarsa")


@pytest.fixture(scope="module")
def random_result():
    return train("random")


@pytest.fixture
def results(request, q_learning_result, sarsa_result, random_result):
    """The module's result of the algorithm named by the test's parameter."""
    return {"q_learning": q_learning_result, "sarsa": sarsa_result, "random": random_result}[request.param]


ALGORITHMS = ["random", "q_learning", "sarsa"]


# --- reproducibility --------------------------------------------------------------------------------


@pytest.mark.parametrize(("algorithm", "results"), [(a, a) for a in ALGORITHMS], indirect=["results"])
def test_repeated_calls_are_identical(algorithm, results):
    """A second training from the same seeds reproduces every record, Q-table and stream."""
    assert_results_equal(train(algorithm), results)


@pytest.fixture
def restore_threads():
    """Put numba's thread count back after the test."""
    threads = numba.get_num_threads()
    yield
    numba.set_num_threads(threads)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs at least two numba threads")
@pytest.mark.usefixtures("restore_threads")
@pytest.mark.parametrize("algorithm", ["q_learning", "sarsa"])
def test_thread_count_does_not_change_results(algorithm):
    """One thread and two threads give the same results, bit for bit."""
    numba.set_num_threads(1)
    one = train(algorithm)
    numba.set_num_threads(2)
    two = train(algorithm)
    assert_results_equal(one, two)


@pytest.mark.parametrize(
    "chunks",
    [[(0, 100), (100, 300)], [(0, 77), (77, 150), (150, 151), (151, 300)]],
    ids=["two-chunks", "uneven-chunks"],
)
@pytest.mark.parametrize(("algorithm", "results"), [(a, a) for a in ALGORITHMS], indirect=["results"])
def test_chunked_training_equals_one_call(algorithm, results, chunks):
    """Episodes split over several calls give what one call gives, evaluations and snapshots included."""
    assert_results_equal(train(algorithm, chunks=chunks), results)


@pytest.mark.parametrize(("algorithm", "results"), [(a, a) for a in ALGORITHMS], indirect=["results"])
def test_different_seeds_differ(algorithm, results):
    """Every pair of seeds visits states differently; the learners' returns and tables differ too (the
    random baseline never reaches the goal in 1000 steps, so its returns are all -1000)."""
    state, records = results
    for i in range(len(SEEDS)):
        for j in range(i + 1, len(SEEDS)):
            assert not np.array_equal(records.visits[i], records.visits[j]), (i, j)
            if algorithm != "random":
                assert not np.array_equal(records.returns[i], records.returns[j]), (i, j)
                assert not np.array_equal(state.w[i], state.w[j]), (i, j)


def test_sarsa_and_q_learning_differ(q_learning_result, sarsa_result):
    """Same seeds, same start states, different rules: different tables and returns for every seed."""
    (q_state, q_records), (s_state, s_records) = q_learning_result, sarsa_result
    for run in range(len(SEEDS)):
        assert not np.array_equal(q_state.w[run], s_state.w[run])
        assert not np.array_equal(q_records.returns[run], s_records.returns[run])


def test_learners_reach_the_goal_random_does_not_learn(q_learning_result, sarsa_result, random_result):
    """A sanity check that the comparison is meaningful: the learners reach the goal, the baseline
    never touches its table."""
    for state, records in (q_learning_result, sarsa_result):
        assert records.terminated.sum() > 0
        assert np.all(state.w <= 0.0)  # every reward is -1 and the table starts at 0
        assert np.any(state.w < 0.0)
    random_state, random_records = random_result
    assert np.all(random_state.w == 0.0)
    assert np.all(random_records.snapshots == 0.0)


# --- record consistency ------------------------------------------------------------------------------


@pytest.mark.parametrize("results", ALGORITHMS, indirect=True)
def test_records_are_consistent(results):
    """Return = -length; unterminated episodes ran to the limit; visits count every training step;
    the last snapshot is the final table."""
    state, records = results
    np.testing.assert_array_equal(records.returns, -records.lengths.astype(np.float64))
    assert np.all((records.lengths >= 1) & (records.lengths <= MAX_STEPS))
    assert np.all(records.lengths[~records.terminated] == MAX_STEPS)
    np.testing.assert_array_equal(records.visits.sum(axis=1), records.lengths.sum(axis=1))
    np.testing.assert_array_equal(records.eval_returns, -records.eval_lengths.astype(np.float64))
    assert np.all(records.eval_lengths[~records.eval_terminated] == MAX_STEPS)
    assert records.eval_returns.shape == (len(SEEDS), EPISODES // EVAL_EVERY, EVAL_EPISODES)
    assert np.all(records.eval_lengths >= 1)
    np.testing.assert_array_equal(records.snapshots[:, -1], state.w)


@pytest.mark.parametrize("algorithm", ["q_learning", "sarsa"])
def test_snapshot_is_the_table_after_its_episode(algorithm):
    """The snapshot at episode 100 is the table of a training stopped after 100 episodes."""
    state_100, _ = train(algorithm, episodes=100)
    _, records = train(algorithm)
    np.testing.assert_array_equal(records.snapshots[:, 0], state_100.w)
    assert not np.array_equal(records.snapshots[:, 0], records.snapshots[:, 1])


# --- common random numbers ----------------------------------------------------------------------------


def _start_states(seed: int, episodes: int) -> list[tuple[float, float]]:
    """The start states of a run: ``reset`` repeated on the stream ``PCG64(seed)``."""
    state = stream_state(seed)
    return [mountain_car.reset(ENV, state) for _ in range(episodes)]


@pytest.mark.parametrize("seed", [0, 3])
def test_start_states_are_shared_across_algorithms(seed):
    """Episode by episode, every algorithm starts from the state that ``reset(stream_state(seed))``
    draws at that episode: the environment stream draws nothing else."""
    episodes = 120
    expected = _start_states(seed, episodes)
    records = allocate_records(1, episodes, 0, 0, np.zeros(0, dtype=np.int64), (GRID.n_cells, 3))
    for algorithm in ALGORITHMS:
        settings = make_settings(eval_every=0)
        state = initial_state([seed], GRID.n_cells, mountain_car.N_ACTIONS)
        starts = []
        for episode in range(episodes):
            starts.append(mountain_car.reset(ENV, state.rng[0, streams.ENV_STREAM].copy()))
            train_block(0, 1, RULES[algorithm], settings, ENV, GRID, state, EPSILONS, episode, episode + 1, records)
        assert starts == expected, algorithm


def test_environment_streams_end_where_resets_leave_them(q_learning_result, sarsa_result, random_result):
    """After 300 episodes each run's environment stream has drawn exactly 300 start states, for every
    algorithm; the agent streams, which the algorithms use differently, differ."""
    states = [result[0] for result in (random_result, q_learning_result, sarsa_result)]
    for run, seed in enumerate(SEEDS):
        expected = stream_state(seed)
        for _ in range(EPISODES):
            mountain_car.reset(ENV, expected)
        for state in states:
            np.testing.assert_array_equal(state.rng[run, streams.ENV_STREAM], expected)
        agent_streams = {tuple(state.rng[run, streams.AGENT_STREAM].tolist()) for state in states}
        assert len(agent_streams) == len(states)


def test_environment_stream_is_gymnasiums():
    """The first start states of seed ``s`` are Gymnasium's ``env.reset(seed=s)`` then plain resets."""
    env = gym.make(mountain_car.ENV_ID, max_episode_steps=MAX_STEPS)
    try:
        for seed in (0, 4):
            state = initial_state([seed], GRID.n_cells, mountain_car.N_ACTIONS)
            env_stream = state.rng[0, streams.ENV_STREAM].copy()
            for k in range(4):
                env.reset(seed=seed) if k == 0 else env.reset()
                position, velocity = env.unwrapped.state
                assert mountain_car.reset(ENV, env_stream) == (float(position), float(velocity))
    finally:
        env.close()


def test_initial_streams_are_seeded_as_documented():
    """Environment stream ``PCG64(seed)``; agent, evaluation environment, evaluation agent, transition and
    evaluation transition streams the five children of ``SeedSequence(seed)``; all distinct."""
    state = initial_state([7, 8], 4, 3)
    assert state.w.shape == (2, 4, 3)
    assert np.all(state.w == 0.0)
    for run, seed in enumerate([7, 8]):
        agent, eval_env, eval_agent, transition, eval_transition = np.random.SeedSequence(seed).spawn(5)
        np.testing.assert_array_equal(state.rng[run, streams.ENV_STREAM], stream_state(seed))
        np.testing.assert_array_equal(state.rng[run, streams.AGENT_STREAM], stream_state(agent))
        np.testing.assert_array_equal(state.rng[run, streams.EVAL_ENV_STREAM], stream_state(eval_env))
        np.testing.assert_array_equal(state.rng[run, streams.EVAL_AGENT_STREAM], stream_state(eval_agent))
        np.testing.assert_array_equal(state.rng[run, streams.TRANSITION_STREAM], stream_state(transition))
        np.testing.assert_array_equal(state.rng[run, streams.EVAL_TRANSITION_STREAM], stream_state(eval_transition))
    assert len({tuple(row) for row in state.rng.reshape(-1, 4).tolist()}) == 12


# --- evaluation and truncation -------------------------------------------------------------------------


@pytest.mark.parametrize(("algorithm", "results"), [(a, a) for a in ALGORITHMS], indirect=["results"])
@pytest.mark.parametrize(("eval_every", "eval_episodes"), [(0, EVAL_EPISODES), (100, 1), (50, 2)])
def test_evaluation_does_not_change_training(algorithm, results, eval_every, eval_episodes):
    """Evaluating, or not, or with other settings, leaves every training record, table and the
    environment and agent streams unchanged; only the evaluation streams move differently (the evaluation
    agent stream only for the random baseline, whose evaluation draws its actions)."""
    state, records = train(algorithm, eval_every=eval_every, eval_episodes=eval_episodes)
    reference_state, reference_records = results
    assert_records_equal(records, reference_records, TRAINING_FIELDS)
    np.testing.assert_array_equal(state.w, reference_state.w)
    rng, reference_rng = state.rng, reference_state.rng
    np.testing.assert_array_equal(rng[:, :streams.EVAL_ENV_STREAM], reference_rng[:, :streams.EVAL_ENV_STREAM])
    assert not np.array_equal(rng[:, streams.EVAL_ENV_STREAM], reference_rng[:, streams.EVAL_ENV_STREAM])
    moved = not np.array_equal(rng[:, streams.EVAL_AGENT_STREAM], reference_rng[:, streams.EVAL_AGENT_STREAM])
    assert moved == (algorithm == "random")
    if eval_every == 0:
        assert records.eval_returns.shape[1] == 0


def test_first_evaluation_episode_does_not_depend_on_eval_episodes(q_learning_result):
    """The first evaluation episode depends only on the table after 50 episodes and the fresh evaluation
    stream, so it is the same with one or five evaluation episodes per round."""
    _, records = train("q_learning", eval_every=EVAL_EVERY, eval_episodes=1)
    _, reference = q_learning_result
    np.testing.assert_array_equal(records.eval_returns[:, 0, 0], reference.eval_returns[:, 0, 0])
    np.testing.assert_array_equal(records.returns, reference.returns)


def test_truncation_limits_episode_length():
    """With ``max_steps=50`` no episode of the random baseline runs longer than 50 steps."""
    _, records = train("random", max_steps=50, episodes=100, eval_every=EVAL_EVERY)
    assert records.lengths.max() == 50
    assert np.all(records.lengths <= 50)
    assert np.all(records.eval_lengths <= 50)
    assert np.all(records.lengths[~records.terminated] == 50)


@pytest.mark.parametrize("algorithm", ["q_learning", "sarsa"])
def test_truncation_as_terminal_changes_learning_only(algorithm):
    """Treating the cut at 200 steps as terminal changes the learned table and, later, the behaviour, but
    the behaviour is the same up to and including each run's first truncated episode."""
    common = {"max_steps": 200, "eval_every": 0}
    bootstrap_state, bootstrap = train(algorithm, episodes=100, **common)
    terminal_state, terminal = train(algorithm, episodes=100, truncation_as_terminal=True, **common)
    assert not np.array_equal(bootstrap_state.w, terminal_state.w)
    assert not np.array_equal(bootstrap.visits, terminal.visits)
    for run, seed in enumerate(SEEDS):
        assert not np.array_equal(bootstrap.visits[run], terminal.visits[run])
        first_cut = int(np.flatnonzero(~bootstrap.terminated[run])[0])
        before = [
            train(algorithm, seeds=[seed], episodes=first_cut + 1, truncation_as_terminal=flag, **common)[1]
            for flag in (False, True)
        ]
        assert_records_equal(before[0], before[1], TRAINING_FIELDS)
        assert np.array_equal(before[0].lengths[0], bootstrap.lengths[run, : first_cut + 1])


def test_truncation_as_terminal_does_not_affect_the_random_baseline():
    """The baseline learns nothing, so the flag changes nothing."""
    a = train("random", max_steps=50, episodes=60, eval_every=0)
    b = train("random", max_steps=50, episodes=60, eval_every=0, truncation_as_terminal=True)
    assert_results_equal(a, b)


# --- one episode by hand ---------------------------------------------------------------------------


def _python_episode(algorithm, q, epsilon, env_rng, agent_rng, transitions, max_steps, truncation_as_terminal,
                    visits):
    """One training episode written out in plain Python, with the helpers' ``py_func`` versions."""
    reset, step = mountain_car.reset.py_func, mountain_car.step.py_func
    cell, choose, uniform = cell_of.py_func, epsilon_greedy_action.py_func, uniform_action.py_func
    n_actions = q.shape[1]
    position, velocity = reset(ENV, env_rng)
    state = cell(GRID, (position, velocity))
    action = uniform(n_actions, agent_rng) if algorithm == "random" else choose(q[state], epsilon, agent_rng)
    steps, episode_return = 0, 0.0
    while True:
        visits[state] += 1
        (position, velocity), reward, terminated = step(ENV, (position, velocity), action, transitions)
        assert reward == -1.0
        episode_return += reward
        steps += 1
        truncated = not terminated and steps >= max_steps
        terminal = terminated or (truncated and truncation_as_terminal)
        next_state = cell(GRID, (position, velocity))
        if algorithm == "q_learning":
            target = reward if terminal else reward + GAMMA * max(q[next_state])
            q[state, action] += ALPHA * (target - q[state, action])
            if terminated or truncated:
                break
            action = choose(q[next_state], epsilon, agent_rng)
        elif algorithm == "sarsa":
            if terminal:
                target = reward
            else:
                next_action = choose(q[next_state], epsilon, agent_rng)
                target = reward + GAMMA * q[next_state, next_action]
            q[state, action] += ALPHA * (target - q[state, action])
            if terminated or truncated:
                break
            action = next_action
        else:
            if terminated or truncated:
                break
            action = uniform(n_actions, agent_rng)
        state = next_state
    return episode_return, steps, terminated


@pytest.mark.parametrize("q_init", ["zeros", "random", "bang_bang"])
@pytest.mark.parametrize(
    ("max_steps", "truncation_as_terminal"), [(1000, False), (60, False), (60, True)], ids=["1000", "60", "60-cut"]
)
@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_engine_equals_python_episodes(algorithm, max_steps, truncation_as_terminal, q_init):
    """Three training episodes of the engine equal the plain-Python re-implementation exactly: the table,
    the visit counts, the records, where the reset and agent streams end, and the transition stream, which
    the deterministic Mountain Car never draws from."""
    episodes, epsilon, seed = 3, 0.3, 11
    state = initial_state([seed], GRID.n_cells, mountain_car.N_ACTIONS)
    if q_init == "random":  # distinct negative values: few ties, so the max and the taken action matter
        state.w[:] = -np.random.default_rng(1).uniform(0.0, 5.0, size=state.w.shape)
    elif q_init == "bang_bang":  # greedy pushes along the velocity: episodes reach the goal
        q_table = state.w[0].reshape(BINS, BINS, mountain_car.N_ACTIONS)
        q_table[:, : BINS // 2, 1:] = -1.0  # negative velocity: push left
        q_table[:, BINS // 2 :, :2] = -1.0  # positive velocity: push right
    initial_q = state.w[0].copy()
    q = initial_q.copy()
    env_rng, agent_rng = state.rng[0, streams.ENV_STREAM].copy(), state.rng[0, streams.AGENT_STREAM].copy()
    transitions = state.rng[0, streams.TRANSITION_STREAM].copy()
    visits = np.zeros(GRID.n_cells, dtype=np.int64)
    with np.errstate(over="ignore"):
        expected = [
            _python_episode(algorithm, q, epsilon, env_rng, agent_rng, transitions, max_steps, truncation_as_terminal,
                            visits)
            for _ in range(episodes)
        ]

    settings = make_settings(max_steps=max_steps, truncation_as_terminal=truncation_as_terminal, eval_every=0)
    records = allocate_records(1, episodes, 0, 0, np.zeros(0, dtype=np.int64), q.shape)
    train_block(0, 1, RULES[algorithm], settings, ENV, GRID, state, np.full(episodes, epsilon), 0, episodes, records)

    np.testing.assert_array_equal(state.w[0], q)
    np.testing.assert_array_equal(records.visits[0], visits)
    np.testing.assert_array_equal(state.rng[0, streams.ENV_STREAM], env_rng)
    np.testing.assert_array_equal(state.rng[0, streams.AGENT_STREAM], agent_rng)
    np.testing.assert_array_equal(state.rng[0, streams.TRANSITION_STREAM], transitions)
    np.testing.assert_array_equal(transitions, initial_state([seed], 1, 1).rng[0, streams.TRANSITION_STREAM])
    assert [
        (r, n, t) for r, n, t in zip(records.returns[0], records.lengths[0], records.terminated[0], strict=True)
    ] == expected
    assert visits.sum() == sum(n for _, n, _ in expected)
    assert np.array_equal(q, initial_q) == (algorithm == "random")  # the learners' tables moved
    if q_init == "bang_bang" and algorithm != "random" and max_steps == 1000:
        assert any(t for _, _, t in expected)  # the goal transition itself was compared


@pytest.mark.slow("compiles or trains for a second or more")
def test_training_frees_every_array_it_allocates_once() -> None:
    """The episode loops give numba views without owners (``engine/borrowed.py``), so that it counts no references
    on a step; numba's own allocation counters still show every array a training allocates freed, none twice."""
    import os
    import subprocess
    import sys

    script = """
from numba.core.runtime import rtsys
from rlcompare import run
from rlcompare.algorithms.registry import METHODS
from rlcompare.tabular.config import ExperimentConfig
configs = [ExperimentConfig(algorithm=name, seeds=(0, 1, 2), episodes=30, eval_every=10, eval_episodes=2)
           for name in METHODS]
configs.append(ExperimentConfig(algorithm="sarsa_lambda", features="tiles", alpha=0.5 / 8, seeds=(0, 1), episodes=5,
                                eval_every=5, eval_episodes=1))
for config in configs:
    run(config)  # compiled or loaded, and warmed
    before = rtsys.get_allocation_stats()
    run(config)
    after = rtsys.get_allocation_stats()
    print(config.algorithm, *(getattr(after, k) - getattr(before, k) for k in ("alloc", "free", "mi_alloc", "mi_free")))
"""
    done = subprocess.run([sys.executable, "-c", script], env={**os.environ, "NUMBA_NRT_STATS": "1"},
                          capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr
    lines = [line.split() for line in done.stdout.splitlines()]
    assert [line[0] for line in lines] == [*METHODS, "sarsa_lambda"]
    for algorithm, alloc, free, mi_alloc, mi_free in lines:
        assert int(alloc) == int(free) > 0, algorithm
        assert int(mi_alloc) == int(mi_free), algorithm
