"""The paper's pair with a network: Q(λ), SARSA(λ) and Expected SARSA(λ) in one online engine.

The engine is PQN's (Gallici et al. 2024, "Simplifying Deep Temporal Difference Learning"; purejaxql
``pqn_gymnax.py``): many environments stepped in parallel, a LayerNorm MLP, no replay buffer and no target
network, and λ-returns computed backwards over each rollout. The only switch between the three methods is the
value the return bootstraps from at the next state, which is what separates Algorithm 1 from Algorithm 2:

| target     | method                 | bootstrap at ``s'``                            | policy     |
|------------|------------------------|------------------------------------------------|------------|
| ``max``      | Peng's Q(λ)            | ``max_a Q(s', a)``                             | off-policy |
| ``sample``   | SARSA(λ)               | ``Q(s', a')``, ``a'`` the action taken next     | on-policy  |
| ``expected`` | Expected SARSA(λ)      | ``Σ_a π_ε(a|s') Q(s', a)``                      | on-policy  |
| ``watkins``  | Watkins's Q(λ)         | ``max_a Q(s', a)``; the trace cut where ``a'`` is not greedy | off-policy |

Peng's Q(λ) (``max``, purejaxql's) never cuts its trace: the λ-weighted part of its return follows the actions
taken, exploratory ones included, so at λ = 0.65 it differs from SARSA(λ) only in the 0.35-weighted bootstrap.
Watkins's Q(λ) (Sutton and Barto 12.10) bootstraps from ``max_a Q(s', a)`` alone after an exploratory action:
off-policy learning of Q* in full. At ``lam = 0`` all of ``max``, ``watkins`` are one-step Q-learning.

In a two-player game whose sides alternate (chess, :mod:`rlcompare.deep.chess_games`) one network plays both sides
(self-play): every choice, ε-greedy, max and expectation, is over the legal moves alone, and the value at ``s'`` is
the opponent's, so the return negates it (negamax): ``G_t = r_t - γ [(1 - λ) v(s') + λ G_{t+1}]``, the λ-return
above with a discount of ``-γ``. Q(λ) then bootstraps from the opponent's best legal reply, SARSA(λ) from the reply
played, Expected SARSA(λ) from the ε-greedy expectation over the replies.

With ``lam = 0`` the return is the one-step target of the paper's Algorithms 1 and 2. ``next_action`` is the
tabular engine's option of the same name, at the only place where it changes anything here, the end of a
rollout: the action the return bootstraps from there (SARSA's) is drawn before the update and taken at the start
of the next rollout (``before_update``, Algorithm 2's order), or every environment's next action is drawn again
from the updated network (``after_update``, Algorithm 1's). ``docs/deep.md`` lists where this departs from
purejaxql.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import optax
from flax.training.train_state import TrainState

from rlcompare.algorithms.registry import AFTER_UPDATE, BEFORE_UPDATE
from rlcompare.deep.atari import NatureCNN, is_frames
from rlcompare.deep.envs import (
    Environment,
    is_game,
    learning_reward,
    legal_all,
    observe_all,
    reset_all,
    step_autoreset_all,
)
from rlcompare.deep.networks import MLP, ConvNet, Network, is_image
from rlcompare.deep.rollout import Episodes, Finished, TrainOutput, track, train_in_rounds
from rlcompare.envs import acrobot, atari, chess_games, minatar, mountain_car
from rlcompare.validation import (
    COUNT,
    POSITIVE,
    STEP_SIZE,
    UNIT,
    Choice,
    Flag,
    Rule,
    Widths,
    check_fields,
    plain_fields,
    require,
)

TARGETS = ("max", "sample", "expected", "watkins")
NEXT_ACTIONS = (BEFORE_UPDATE, AFTER_UPDATE)
OBSERVATION_BOXES = {
    "MountainCar-v0": (tuple(mountain_car.OBSERVATION_LOW.tolist()), tuple(mountain_car.OBSERVATION_HIGH.tolist())),
    "Acrobot-v1": (tuple(acrobot.OBSERVATION_LOW.tolist()), tuple(acrobot.OBSERVATION_HIGH.tolist())),
}
"""Gymnasium's observation boxes where every bound is finite."""


@dataclass(frozen=True)
class PQNConfig:
    """One PQN-style configuration (defaults: purejaxql's ``pqn_cartpole.yaml``, but a 2 x 128 network)."""

    target: str = "max"
    """What the return bootstraps from: ``max`` (Q(λ)), ``sample`` (SARSA(λ)), ``expected`` (Expected SARSA(λ))."""
    lam: float = 0.95
    """λ of the λ-return; 0 gives the one-step target."""
    gamma: float = 0.99
    """Discount."""
    total_steps: int = 500_000
    """Environment steps over all parallel environments."""
    n_envs: int = 32
    """Environments stepped in parallel."""
    n_steps: int = 64
    """Steps of each environment per rollout (one update)."""
    n_epochs: int = 4
    """Passes over each rollout."""
    n_minibatches: int = 16
    """Minibatches per pass."""
    learning_rate: float = 1e-4
    """RAdam's step size."""
    anneal_lr: bool = True
    """Decay the step size linearly to zero over the training."""
    max_grad_norm: float = 10.0
    """Gradients clipped to this global norm."""
    epsilon_start: float = 1.0
    """ε of the first rollout."""
    epsilon_end: float = 0.05
    """ε after the decay."""
    decay_fraction: float = 0.2
    """Fraction of the updates over which ε decays linearly."""
    reward_scale: float = 0.1
    """Rewards are multiplied by this in the return (the recorded returns are the environment's own)."""
    hidden: tuple[int, ...] = (128, 128)
    """Widths of the hidden layers, each followed by LayerNorm and ReLU."""
    next_action: str = BEFORE_UPDATE
    """When the action after a rollout's last step is drawn: ``before_update`` (Algorithm 2's order: the one the
    return bootstraps from is taken next) or ``after_update`` (Algorithm 1's: drawn again from the updated
    network)."""
    scale_observations: bool = False
    """Map a bounded observation box onto [-1, 1] before the network (Mountain Car's velocity spans ±0.07)."""

    def __post_init__(self) -> None:
        plain_fields(self)
        check_fields(self, RULES)
        rollout = self.n_envs * self.n_steps
        require(rollout % self.n_minibatches == 0, "n_minibatches", self.n_minibatches,
                f"a divisor of n_envs x n_steps = {rollout}")
        require(self.total_steps >= rollout, "total_steps", self.total_steps,
                f"at least one rollout, n_envs x n_steps = {rollout}")

    @property
    def updates(self) -> int:
        return self.total_steps // (self.n_envs * self.n_steps)


RULES: dict[str, Rule] = {
    "target": Choice(TARGETS), "next_action": Choice(NEXT_ACTIONS), "lam": UNIT, "gamma": STEP_SIZE,
    "learning_rate": POSITIVE, "max_grad_norm": POSITIVE, "reward_scale": POSITIVE, "epsilon_start": UNIT,
    "epsilon_end": UNIT, "decay_fraction": STEP_SIZE, "n_envs": COUNT, "n_steps": COUNT, "n_epochs": COUNT,
    "n_minibatches": COUNT, "total_steps": COUNT, "anneal_lr": Flag(), "scale_observations": Flag(),
    "hidden": Widths(),
}
"""What each setting may hold (:mod:`rlcompare.validation`), checked in this order."""


_SMALL = PQNConfig(total_steps=500_000, n_envs=16, n_steps=128, n_epochs=4, n_minibatches=4, hidden=(64, 64),
                   learning_rate=1e-3)
_MINATAR = PQNConfig(total_steps=10_000_000, n_envs=128, n_steps=32, n_epochs=2, n_minibatches=32,
                     learning_rate=5e-4, lam=0.65, decay_fraction=0.1, reward_scale=1.0, hidden=(128,))
_ATARI = PQNConfig(total_steps=10_000_000, n_envs=128, n_steps=32, n_epochs=2, n_minibatches=32,
                   learning_rate=2.5e-4, anneal_lr=False, lam=0.65, epsilon_end=0.001, decay_fraction=0.1,
                   reward_scale=1.0, hidden=(512,))
_CHESS = PQNConfig(total_steps=500_000, n_envs=128, n_steps=32, n_epochs=4, n_minibatches=8, learning_rate=1e-3,
                   lam=0.95, decay_fraction=0.2, reward_scale=1.0, hidden=(256, 256))
PRESETS = {"default": {
    "CartPole-v1": _SMALL,
    "Acrobot-v1": _SMALL,
    "MountainCar-v0": dataclasses.replace(_SMALL, total_steps=1_000_000, scale_observations=True),
    **dict.fromkeys(minatar.NAMES, _MINATAR),
    **dict.fromkeys(atari.NAMES, _ATARI),
    **dict.fromkeys(chess_games.GAMES, _CHESS),
}}
"""Preset name -> environment -> config. ``default``: the shape the speed target is set on (16 environments x 128
steps, 4 epochs x 4 minibatches, 2 x 64 LayerNorm MLP), with purejaxql's CartPole settings otherwise
(``pqn_cartpole.yaml``: λ 0.95, γ 0.99, RAdam, gradients clipped at 10, rewards scaled by 0.1, ε from 1 over the
first fifth) but ε ending at 0.05, a step size of 1e-3 for the smaller batches, and twice the steps on
Mountain Car, whose observations are scaled onto [-1, 1]. MinAtar: purejaxql's ``pqn_minatar.yaml`` (128 environments
x 32 steps, 2 epochs x 32 minibatches, RAdam at 5e-4 decayed linearly, λ 0.65, ε 1 -> 0.05 over the first tenth,
rewards unscaled, 10 M steps) with MinAtar's network, LayerNorm after the convolution and the dense layer of 128.
Atari: purejaxql's ``pqn_atari.yaml`` (128 environments x 32 steps, 2 epochs x 32 minibatches, RAdam at 2.5e-4 not
decayed, λ 0.65, ε 1 -> 0.001 over the first tenth, 10 M steps) with Mnih et al.'s network, LayerNorm after each
layer; it learns from the score's sign, as there. Chess and Gardner's minichess (self-play, ``docs/chess-game.md``):
128 environments x 32 plies, 4 epochs x 8 minibatches, RAdam at 1e-3 decayed linearly, λ 0.95, ε 1 -> 0.05 over
the first fifth, a 2 x 256 LayerNorm MLP over the board's planes, 500,000 plies: the settings that took Gardner's
game from a score of 0.57 against the random player (MinAtar's λ 0.65, 2 epochs at 5e-4, 1 M plies) to 0.80 at half
the plies (2 seeds)."""
Config = PQNConfig
"""The method's settings (:class:`~rlcompare.deep.methods.MethodModule`)."""


class Rollout(NamedTuple):
    """One rollout, time-major ``(n_steps, n_envs)``."""

    observations: jax.Array
    actions: jax.Array
    rewards: jax.Array
    terminated: jax.Array
    truncated: jax.Array
    last_observations: jax.Array
    """The observation each action led to (before a reset): the next state the return bootstraps from."""
    next_legal: jax.Array | None
    """In a game, the moves legal after each action (the next state's, where the game went on); else None."""


Collecting = tuple[Any, jax.Array, jax.Array | None, jax.Array, Episodes]
"""A rollout in progress: the environments' states, their observations and legal moves, the actions next taken, the
episodes."""


class Runner(NamedTuple):
    train_state: TrainState
    env_state: Any
    observation: jax.Array
    legal: jax.Array | None
    """In a game, the moves legal in each environment's position; else None."""
    next_action: jax.Array
    """The action each environment takes first in the next rollout (``before_update``; redrawn ``after_update``)."""
    episodes: Episodes
    update: jax.Array


def network(config: PQNConfig, env: Environment) -> MLP | ConvNet | NatureCNN:
    """A LayerNorm MLP, or for images MinAtar's or Mnih et al.'s convolutional network, with LayerNorm; for a board
    game, a LayerNorm MLP over the board's planes."""
    if is_game(env):
        return MLP(hidden=config.hidden, outputs=env.n_actions, activation="relu", layer_norm=True, board=True)
    if is_frames(env.observation_shape):
        return NatureCNN(env.n_actions, hidden=config.hidden, layer_norm=True)
    if is_image(env.observation_shape):
        return ConvNet(env.n_actions, hidden=config.hidden, layer_norm=True)
    box = OBSERVATION_BOXES.get(env.name) if config.scale_observations else None
    return MLP(hidden=config.hidden, outputs=env.n_actions, activation="relu", layer_norm=True, box=box)


def act(config: PQNConfig, env: Environment) -> Callable[..., jax.Array]:
    """The greedy policy: ``(params, observations) -> argmax_a Q``; in a game ``(params, observations, legal)``, the
    best legal move."""
    net: Network = network(config, env)
    return lambda params, observations, legal=None: greedy(net.apply(params, observations), legal)


def masked(q: jax.Array, legal: jax.Array | None) -> jax.Array:
    """The action values with every illegal move at -inf (as they are where every action is legal)."""
    return q if legal is None else jnp.where(legal, q, -jnp.inf)


def greedy(q: jax.Array, legal: jax.Array | None = None) -> jax.Array:
    """The first of the best (legal) actions."""
    return jnp.argmax(masked(q, legal), axis=-1)


def uniform_legal(key: jax.Array, legal: jax.Array) -> jax.Array:
    """One legal action of each row of ``legal``, uniformly: the largest of a uniform draw over the legal ones."""
    return jnp.argmax(jnp.where(legal, jax.random.uniform(key, legal.shape), -1.0), axis=-1)


def epsilon_greedy(key: jax.Array, q: jax.Array, epsilon: jax.Array, legal: jax.Array | None = None) -> jax.Array:
    """ε-greedy actions for a batch of action values ``(envs, actions)``; ties go to the first greedy action; with
    ``legal``, both the exploring and the greedy choice are among the legal actions."""
    explore_key, action_key = jax.random.split(key)
    explore = jax.random.uniform(explore_key, q.shape[:-1]) < epsilon
    random_actions = (jax.random.randint(action_key, q.shape[:-1], 0, q.shape[-1]) if legal is None
                      else uniform_legal(action_key, legal))
    return jnp.where(explore, random_actions, greedy(q, legal))


def expected_value(q: jax.Array, epsilon: jax.Array, legal: jax.Array | None = None) -> jax.Array:
    """``Σ_a π(a|s) Q(s, a)`` under ε-greedy with the greedy action first among ties (Sutton and Barto 6.6); with
    ``legal``, over the legal actions alone."""
    n_actions = q.shape[-1]
    one_hot = jax.nn.one_hot(greedy(q, legal), n_actions, dtype=q.dtype)
    if legal is None:
        return jnp.sum((epsilon / n_actions + (1.0 - epsilon) * one_hot) * q, axis=-1)
    n_legal = jnp.sum(legal, axis=-1, keepdims=True)
    probabilities = jnp.where(legal, epsilon / n_legal, 0.0) + (1.0 - epsilon) * one_hot
    return jnp.sum(jnp.where(legal, probabilities * q, 0.0), axis=-1)


def lambda_returns(rewards: jax.Array, terminated: jax.Array, truncated: jax.Array, next_values: jax.Array,
                   gamma: float, lam: float, cut: jax.Array | None = None) -> jax.Array:
    """λ-returns over a time-major rollout, computed backwards (Sutton and Barto 12.1, the recursive form):

    ``G_t = r_t + γ (1 - terminated_t) [(1 - λ) v_t + λ G_{t+1}]``, where ``v_t`` is the bootstrap value at the
    state the action led to. An episode's end stops the recursion: termination bootstraps from nothing, a
    time-limit cut from ``v_t`` alone, and so does the rollout's last step, whose ``G_{t+1}`` is not known, and
    every step where ``cut`` is true (Watkins's Q(λ): the next action taken was not greedy; Sutton and Barto 12.10).
    """
    stops = truncated if cut is None else truncated | cut

    def backwards(later_return: jax.Array, step: tuple[jax.Array, jax.Array, jax.Array, jax.Array]
                  ) -> tuple[jax.Array, jax.Array]:
        reward, term, stop, value = step
        continues = (1.0 - lam) * value + lam * later_return
        bootstrap = jnp.where(stop, value, continues)
        g = reward + gamma * jnp.where(term, 0.0, bootstrap)
        return g, g

    last = rewards[-1] + gamma * jnp.where(terminated[-1], 0.0, next_values[-1])
    _, earlier = jax.lax.scan(backwards, last, (rewards[:-1], terminated[:-1], stops[:-1], next_values[:-1]),
                              reverse=True)
    return jnp.concatenate([earlier, last[None]])


def bootstrap_values(target: str, q_next: jax.Array, bootstrap_actions: jax.Array, epsilon: jax.Array,
                     legal: jax.Array | None = None) -> jax.Array:
    """The value at each next state that the return bootstraps from (see the module's table), over the ``legal``
    actions where given."""
    if target in ("max", "watkins"):
        return jnp.max(masked(q_next, legal), axis=-1)
    if target == "expected":
        return expected_value(q_next, epsilon, legal)
    return jnp.take_along_axis(q_next, bootstrap_actions[..., None], axis=-1)[..., 0]


def sarsa_actions(actions: jax.Array, done: jax.Array, drawn: jax.Array, carried: jax.Array) -> jax.Array:
    """The action SARSA bootstraps from after each step: the next one taken in the same episode; where the
    episode was cut, one drawn by the policy at the cut state; after the rollout's last step, ``carried``."""
    following = jnp.concatenate([actions[1:], carried[None]])
    return jnp.where(done, drawn, following)


def make_train(config: PQNConfig, env: Environment, rounds: int, eval_episodes: int
               ) -> Callable[[jax.Array], TrainOutput]:
    """One seed's whole training, jittable and vmappable over keys: ``rounds`` x (``updates // rounds``) updates,
    each one rollout of ``n_envs`` x ``n_steps`` steps and ``n_epochs`` x ``n_minibatches`` gradient steps."""
    updates_per_round = config.updates // rounds
    require(updates_per_round >= 1, "total_steps", config.total_steps,
            f"at least {rounds} rollouts of n_envs x n_steps = {config.n_envs * config.n_steps} steps")
    net: Network = network(config, env)
    updates = updates_per_round * rounds
    decay_updates = max(1, int(config.decay_fraction * updates))
    epsilon_at = optax.linear_schedule(config.epsilon_start, config.epsilon_end, decay_updates)
    gradient_steps = updates * config.n_epochs * config.n_minibatches
    learning_rate = (optax.linear_schedule(config.learning_rate, 0.0, gradient_steps) if config.anneal_lr
                     else config.learning_rate)
    optimiser = optax.chain(optax.clip_by_global_norm(config.max_grad_norm), optax.radam(learning_rate))
    q_values = jax.vmap(net.apply, in_axes=(None, 0))  # over time: (steps, envs, obs) -> (steps, envs, actions)
    discount = -config.gamma if is_game(env) else config.gamma  # negamax: the next state's value is the opponent's

    def collect(runner: Runner, key: jax.Array, epsilon: jax.Array) -> tuple[Runner, Rollout, Finished]:
        params = runner.train_state.params

        def one_step(carry: Collecting, step_key: jax.Array
                     ) -> tuple[Collecting, tuple[Rollout, Finished]]:
            env_state, observation, _, action, episodes = carry
            draw_key, reset_key = jax.random.split(step_key)
            step = step_autoreset_all(env, env_state, action, jax.random.split(reset_key, config.n_envs))
            episodes, finished = track(episodes, step.reward, step.terminated, step.truncated)
            legal = legal_all(env, step.state)  # a game's last_observation differs only where it ended
            next_action = epsilon_greedy(draw_key, net.apply(params, step.observation), epsilon, legal)
            transition = Rollout(observation, action, step.reward, step.terminated, step.truncated,
                                 step.last_observation, legal)
            return (step.state, step.observation, legal, next_action, episodes), (transition, finished)

        start = (runner.env_state, runner.observation, runner.legal, runner.next_action, runner.episodes)
        (env_state, observation, legal, next_action, episodes), (rollout, finished) = jax.lax.scan(
            one_step, start, jax.random.split(key, config.n_steps))
        runner = runner._replace(env_state=env_state, observation=observation, legal=legal, next_action=next_action,
                                 episodes=episodes)
        return runner, rollout, finished

    def targets(params: Any, rollout: Rollout, carried: jax.Array, key: jax.Array, epsilon: jax.Array
                ) -> jax.Array:
        q_next = q_values(params, rollout.last_observations)
        done = rollout.terminated | rollout.truncated
        drawn = epsilon_greedy(key, q_next, epsilon, rollout.next_legal)
        next_actions = sarsa_actions(rollout.actions, done, drawn, carried)
        values = bootstrap_values(config.target, q_next, next_actions, epsilon, rollout.next_legal)
        rewards = config.reward_scale * learning_reward(env, rollout.rewards).astype(jnp.float32)
        cut = next_actions != greedy(q_next, rollout.next_legal) if config.target == "watkins" else None
        return lambda_returns(rewards, rollout.terminated, rollout.truncated, values, discount, config.lam, cut)

    def loss(params: Any, observations: jax.Array, actions: jax.Array, returns: jax.Array) -> jax.Array:
        q = net.apply(params, observations)
        taken = jnp.take_along_axis(q, actions[:, None], axis=-1)[:, 0]
        return 0.5 * jnp.mean(jnp.square(taken - returns))

    def learn(train_state: TrainState, rollout: Rollout, returns: jax.Array, key: jax.Array) -> TrainState:
        batch = (rollout.observations.reshape(-1, *env.observation_shape), rollout.actions.reshape(-1),
                 returns.reshape(-1))

        def epoch(state: TrainState, epoch_key: jax.Array) -> tuple[TrainState, None]:
            order = jax.random.permutation(epoch_key, batch[1].shape[0])
            minibatches = jax.tree.map(lambda x: x[order].reshape(config.n_minibatches, -1, *x.shape[1:]), batch)

            def gradient_step(state: TrainState, minibatch: tuple[jax.Array, jax.Array, jax.Array]
                              ) -> tuple[TrainState, None]:
                return state.apply_gradients(grads=jax.grad(loss)(state.params, *minibatch)), None

            return jax.lax.scan(gradient_step, state, minibatches)[0], None

        return jax.lax.scan(epoch, train_state, jax.random.split(key, config.n_epochs))[0]

    def update(runner: Runner, key: jax.Array) -> tuple[Runner, Finished]:
        collect_key, target_key, learn_key, redraw_key = jax.random.split(key, 4)
        epsilon = epsilon_at(runner.update)
        runner, rollout, finished = collect(runner, collect_key, epsilon)
        returns = targets(runner.train_state.params, rollout, runner.next_action, target_key, epsilon)
        train_state = learn(runner.train_state, rollout, returns, learn_key)
        next_action = runner.next_action
        if config.next_action == AFTER_UPDATE:
            q = net.apply(train_state.params, runner.observation)
            next_action = epsilon_greedy(redraw_key, q, epsilon_at(runner.update + 1), runner.legal)
        return runner._replace(train_state=train_state, next_action=next_action, update=runner.update + 1), finished

    def start(key: jax.Array) -> Runner:
        init_key, reset_key, action_key = jax.random.split(key, 3)
        params = net.init(init_key, jnp.zeros((1, *env.observation_shape), jnp.float32))
        train_state = TrainState.create(apply_fn=net.apply, params=params, tx=optimiser)
        env_state = reset_all(env, jax.random.split(reset_key, config.n_envs))
        observation = observe_all(env, env_state)
        legal = legal_all(env, env_state)
        first_action = epsilon_greedy(action_key, net.apply(params, observation), epsilon_at(0), legal)
        return Runner(train_state, env_state, observation, legal, first_action, Episodes.start(config.n_envs),
                      jnp.zeros((), jnp.int32))

    run_rounds = train_in_rounds(update, lambda runner: runner.train_state.params, env, act(config, env), rounds,
                                 updates_per_round, eval_episodes)

    def train(key: jax.Array) -> TrainOutput:
        start_key, train_key = jax.random.split(key)
        return run_rounds(start(start_key), train_key)

    return train
