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

In a two-player game whose sides alternate (chess, :mod:`rlcompare.deep.chess.games`) one network plays both sides
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

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import optax
from flax.training.train_state import TrainState

from rlcompare.algorithms.registry import AFTER_UPDATE
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
from rlcompare.deep.presets.pqn import NEXT_ACTIONS, OBSERVATION_BOXES, PRESETS, TARGETS, PQNConfig
from rlcompare.deep.rollout import Episodes, Finished, TrainOutput, track, train_in_rounds
from rlcompare.validation import require

Config = PQNConfig
"""The method's settings (:class:`~rlcompare.deep.methods.MethodModule`)."""

__all__ = ["NEXT_ACTIONS", "PRESETS", "TARGETS", "Config", "PQNConfig", "act", "bootstrap_values", "epsilon_greedy",
           "expected_value", "greedy", "lambda_returns", "make_train", "masked", "network", "sarsa_actions", "scores",
           "uniform_legal"]


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


def scores(config: PQNConfig, env: Environment) -> Callable[..., jax.Array]:
    """``(params, observations) -> (batch, n_actions)`` Q-values, what the greedy policy maximises."""
    net: Network = network(config, env)
    return net.apply


def act(config: PQNConfig, env: Environment) -> Callable[..., jax.Array]:
    """The greedy policy: ``(params, observations) -> argmax_a Q``; in a game ``(params, observations, legal)``, the
    best legal move."""
    values = scores(config, env)
    return lambda params, observations, legal=None: greedy(values(params, observations), legal)


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
