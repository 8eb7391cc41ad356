"""Proximal policy optimisation (Schulman et al. 2017, "Proximal Policy Optimization Algorithms"), one seed's whole
training a single jit-able, vmap-able program, as in purejaxrl (Lu et al. 2022, ``purejaxrl/ppo.py``).

The semantics are Stable-Baselines3's (``stable_baselines3/ppo/ppo.py``, ``common/on_policy_algorithm.py``,
``common/buffers.py``, ``common/policies.py``, ``common/vec_env/vec_normalize.py``): separate actor and critic
MLPs with orthogonal initialisation, Adam with ε = 1e-5, GAE with a time-limit cut bootstrapped from
V(last observation), advantages normalised per minibatch, unclipped value loss, global gradient-norm clipping,
and ``VecNormalize``'s running observation and reward normalisation where rl-baselines3-zoo sets ``normalize``.

Departures from SB3:

* ``total_steps`` is rounded down to whole updates of ``n_envs * n_steps`` transitions (SB3 rounds up: the zoo's
  1e5 CartPole steps are 390 updates here, 391 there), so a linear schedule ends just above 0, never below;
  and to whole rounds of updates between evaluations (390 updates in 20 rounds: 380 run).
* Resets are drawn from JAX's generator (:mod:`rlcompare.deep.envs`), and minibatch permutations too.
* Gradient clipping is optax's ``clip_by_global_norm`` (PyTorch's ``clip_grad_norm_`` divides by norm + 1e-6).
* Not implemented: ``clip_range_vf``, ``target_kl`` (both off in SB3's defaults and in the zoo presets here),
  gSDE, continuous actions.

MinAtar's images (``(10, 10, channels)`` booleans) go through MinAtar's convolution, in the actor and in the
critic each, as purejaxql's ``ppo_minatar.py`` (Gallici et al. 2024's PPO baseline, from purejaxrl), and its loss
is available: ``value_loss="purejaxrl"``. Its settings are :data:`MINATAR`; where they still depart from that
source is listed there.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import optax

from rlcompare.deep.envs import Environment, learning_reward, observe_all, reset_all, step_autoreset_all
from rlcompare.deep.networks import Network, is_image
from rlcompare.deep.ppo_networks import network
from rlcompare.deep.presets.ppo import ADAM_EPSILON, NORMALIZE_CLIP, NORMALIZE_EPSILON, PRESETS, PPOConfig
from rlcompare.deep.rollout import Act, Episodes, Finished, TrainOutput, track, train_in_rounds
from rlcompare.validation import COUNT, check, require

Config = PPOConfig
"""The method's settings (:class:`~rlcompare.deep.methods.MethodModule`)."""
__all__ = ["PRESETS", "Config", "act", "make_train", "network", "scores"]


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class RunningMeanStd:
    """Running mean and (population) variance of a stream of batches (Chan et al.'s parallel update). A pytree of
    its three arrays, named as SB3 names them (a tuple's ``count`` would hide ``tuple.count``)."""

    mean: jax.Array
    var: jax.Array
    count: jax.Array

    @classmethod
    def start(cls, shape: tuple[int, ...]) -> RunningMeanStd:
        """SB3's start: mean 0, variance 1, count 1e-4."""
        return cls(jnp.zeros(shape, jnp.float64), jnp.ones(shape, jnp.float64), jnp.asarray(1e-4, jnp.float64))


def update_running(stats: RunningMeanStd, batch: jax.Array) -> RunningMeanStd:
    """Add a batch (leading axis) to the statistics (SB3's ``RunningMeanStd.update``)."""
    batch = batch.astype(jnp.float64)
    batch_mean, batch_var, batch_count = batch.mean(axis=0), batch.var(axis=0), batch.shape[0]
    delta = batch_mean - stats.mean
    count = stats.count + batch_count
    m2 = stats.var * stats.count + batch_var * batch_count + delta**2 * stats.count * batch_count / count
    return RunningMeanStd(stats.mean + delta * batch_count / count, m2 / count, count)


def normalize_observation(observation: jax.Array, stats: RunningMeanStd) -> jax.Array:
    """``VecNormalize.normalize_obs``: standardised, clipped to ±10, float32."""
    scaled = (observation - stats.mean) / jnp.sqrt(stats.var + NORMALIZE_EPSILON)
    return jnp.clip(scaled, -NORMALIZE_CLIP, NORMALIZE_CLIP).astype(jnp.float32)


def normalize_reward(reward: jax.Array, stats: RunningMeanStd) -> jax.Array:
    """``VecNormalize.normalize_reward``: divided by the discounted return's standard deviation, clipped to ±10."""
    return jnp.clip(reward / jnp.sqrt(stats.var + NORMALIZE_EPSILON), -NORMALIZE_CLIP, NORMALIZE_CLIP
                    ).astype(jnp.float32)


class PolicyParams(NamedTuple):
    """What the greedy policy needs: the network's variables and the observation statistics (left at their
    start, and unused, without ``normalize_observations``; always so for images)."""

    network: Any
    observations: RunningMeanStd


def init_params(config: PPOConfig, env: Environment, key: jax.Array) -> PolicyParams:
    """Fresh parameters; also the template to restore saved ones into."""
    variables = network(config, env).init(key, jnp.zeros((1, *env.observation_shape), jnp.float32))
    return PolicyParams(variables, RunningMeanStd.start(env.observation_shape))


def _observe(config: PPOConfig, params: PolicyParams, observation: jax.Array) -> jax.Array:
    """What the network and the rollout buffer see: normalised where ``normalize_observations``; images stay
    booleans (the network casts them); vectors float32."""
    if config.normalize_observations:
        return normalize_observation(observation, params.observations)
    return observation if observation.dtype == jnp.bool_ else observation.astype(jnp.float32)


def scores(config: PPOConfig, env: Environment) -> Callable[[PolicyParams, jax.Array], jax.Array]:
    """``(params, raw observations) -> (batch, n_actions)`` the policy's logits, observations normalised with the
    frozen statistics where trained so (the zoo's evaluation)."""
    module: Network = network(config, env)

    def logits(params: PolicyParams, observation: jax.Array) -> jax.Array:
        return jnp.asarray(module.apply(params.network, _observe(config, params, observation), method="logits"))

    return logits


def act(config: PPOConfig, env: Environment) -> Act:
    """``(params, raw observations) -> greedy actions``: the argmax of the logits (SB3's ``deterministic=True``)."""
    logits = scores(config, env)
    return lambda params, observation: jnp.argmax(logits(params, observation), axis=-1)


# --- the pieces of the objective ---

def gae(rewards: jax.Array, values: jax.Array, next_values: jax.Array, terminated: jax.Array, dones: jax.Array,
        gamma: float, lam: float) -> jax.Array:
    """Generalised advantage estimates (Schulman et al. 2016), time-major ``(steps, envs)``.

    ``next_values[t]`` is V of the observation step ``t`` led to (before any reset); it counts unless the episode
    terminated, so a time-limit cut bootstraps from it, as SB3's ``rewards += gamma * V(terminal_observation)``;
    the trace stops where an episode ended either way (``dones``).
    """
    continues = 1.0 - terminated.astype(values.dtype)
    deltas = rewards + gamma * next_values * continues - values
    carries = gamma * lam * (1.0 - dones.astype(values.dtype))

    def backward(later: jax.Array, step: tuple[jax.Array, jax.Array]) -> tuple[jax.Array, jax.Array]:
        delta, carry = step
        advantage = delta + carry * later
        return advantage, advantage

    _, advantages = jax.lax.scan(backward, jnp.zeros_like(values[0]), (deltas, carries), reverse=True)
    return advantages


def normalize_advantages(advantages: jax.Array) -> jax.Array:
    """Zero mean, unit sample standard deviation (``ddof=1``, PyTorch's ``std``), as SB3 per minibatch."""
    return (advantages - advantages.mean()) / (advantages.std(ddof=1) + NORMALIZE_EPSILON)


def clipped_surrogate_loss(log_prob: jax.Array, old_log_prob: jax.Array, advantages: jax.Array,
                           clip_range: float | jax.Array) -> jax.Array:
    """``-mean(min(r A, clip(r, 1 - ε, 1 + ε) A))`` with ``r = π(a|s) / π_old(a|s)`` (Schulman et al. 2017, eq. 7)."""
    ratio = jnp.exp(log_prob - old_log_prob)
    clipped = jnp.clip(ratio, 1.0 - clip_range, 1.0 + clip_range)
    return -jnp.minimum(ratio * advantages, clipped * advantages).mean()


def value_loss(values: jax.Array, returns: jax.Array) -> jax.Array:
    """Mean squared error to the TD(λ) returns, unclipped and without a ½ (SB3's ``F.mse_loss``)."""
    return jnp.mean((returns - values) ** 2)


def clipped_value_loss(values: jax.Array, old_values: jax.Array, returns: jax.Array,
                       clip_range: float | jax.Array) -> jax.Array:
    """purejaxrl's: ``½ mean(max((V - R)², (V_old + clip(V - V_old, ±ε) - R)²))``, the pessimistic of the value and
    the value kept within ``ε`` of the one the rollout recorded (``purejaxrl/ppo.py``, ``_loss_fn``)."""
    clipped = old_values + jnp.clip(values - old_values, -clip_range, clip_range)
    return 0.5 * jnp.maximum((values - returns) ** 2, (clipped - returns) ** 2).mean()


def entropy(logits: jax.Array) -> jax.Array:
    """Entropy of each categorical distribution given by ``logits`` (last axis)."""
    log_p = jax.nn.log_softmax(logits)
    return -jnp.sum(jnp.exp(log_p) * log_p, axis=-1)


def log_probability(logits: jax.Array, actions: jax.Array) -> jax.Array:
    """``log π(a|s)`` of each action under the categorical ``logits``."""
    return jnp.take_along_axis(jax.nn.log_softmax(logits), actions[..., None], axis=-1)[..., 0]


class Batch(NamedTuple):
    """Transitions to learn from, with what the policy said when it acted."""

    observations: jax.Array
    actions: jax.Array
    log_probs: jax.Array
    advantages: jax.Array
    returns: jax.Array
    values: jax.Array
    """V(s) when the action was taken (for ``value_loss="purejaxrl"``)."""


def ppo_loss(module: Network, variables: Any, batch: Batch, clip_range: jax.Array, config: PPOConfig
             ) -> jax.Array:
    """SB3's loss: ``policy_loss - ent_coef * entropy + vf_coef * value_loss`` on one minibatch, the value loss
    SB3's or purejaxrl's (``config.value_loss``)."""
    logits, values = module.apply(variables, batch.observations)
    advantages = batch.advantages
    if config.normalize_advantage and config.batch_size > 1:
        advantages = normalize_advantages(advantages)
    policy = clipped_surrogate_loss(log_probability(logits, batch.actions), batch.log_probs, advantages, clip_range)
    critic = (clipped_value_loss(values, batch.values, batch.returns, clip_range) if config.value_loss == "purejaxrl"
              else value_loss(values, batch.returns))
    return policy - config.ent_coef * entropy(logits).mean() + config.vf_coef * critic


def progress_remaining(config: PPOConfig, update: jax.Array) -> jax.Array:
    """SB3's ``1 - num_timesteps / total_timesteps`` during update ``update`` (from 0), its rollout counted."""
    return 1.0 - (update + 1) * config.batch / config.total_steps


def optimizer(config: PPOConfig) -> optax.GradientTransformation:
    """Global-norm clipping, then Adam (ε 1e-5), its step size annealed per update where ``anneal_lr``."""
    steps_per_update = config.n_epochs * config.minibatches

    def learning_rate(count: jax.Array) -> jax.Array:
        scale = progress_remaining(config, count // steps_per_update) if config.anneal_lr else 1.0
        return jnp.asarray(config.learning_rate * scale, jnp.float32)

    return optax.chain(optax.clip_by_global_norm(config.max_grad_norm),
                       optax.adam(learning_rate, eps=ADAM_EPSILON))


# --- the training program ---

class Runner(NamedTuple):
    """Everything one seed's training carries from update to update."""

    params: PolicyParams
    opt_state: Any
    rewards: RunningMeanStd
    """Statistics of the discounted return, for ``normalize_rewards``."""
    discounted: jax.Array
    """(envs,) each environment's running discounted return, for ``normalize_rewards``."""
    env_state: Any
    observation: jax.Array
    """(envs, *observation shape): float32, normalised where ``normalize_observations``; images booleans."""
    episodes: Episodes
    update: jax.Array


class Transition(NamedTuple):
    observation: jax.Array
    action: jax.Array
    log_prob: jax.Array
    value: jax.Array
    reward: jax.Array
    """Normalised where ``normalize_rewards``."""
    last_observation: jax.Array
    terminated: jax.Array
    done: jax.Array


def make_train(config: PPOConfig, env: Environment, rounds: int, eval_episodes: int
               ) -> Callable[[jax.Array], TrainOutput]:
    """``key -> TrainOutput``: one seed's training, ``config.updates // rounds`` updates in each of ``rounds``
    rounds (the remainder, fewer than ``rounds`` updates, is not run; the schedules still span ``total_steps``),
    with a greedy evaluation of ``eval_episodes`` episodes after each; ``finished`` is ``(rounds, updates per
    round, n_steps, n_envs)``. Jit-able and vmap-able over keys."""
    check("rounds", rounds, COUNT)
    require(rounds <= config.updates, "total_steps", config.total_steps,
            f"at least {rounds} updates of n_envs x n_steps = {config.batch} steps (one per evaluation round)")
    require(not (config.normalize_observations and is_image(env.observation_shape)), "normalize_observations", True,
            "false for images (MinAtar's are booleans)")
    module: Network = network(config, env)
    tx = optimizer(config)
    greedy = act(config, env)

    def step(runner: Runner, key: jax.Array) -> tuple[Runner, tuple[Transition, Finished]]:
        action_key, reset_key = jax.random.split(key)
        logits, value = module.apply(runner.params.network, runner.observation)
        action = jax.random.categorical(action_key, logits)
        out = step_autoreset_all(env, runner.env_state, action, jax.random.split(reset_key, config.n_envs))
        episodes, finished = track(runner.episodes, out.reward, out.terminated, out.truncated)
        done = out.terminated | out.truncated
        params, reward_stats, discounted = runner.params, runner.rewards, runner.discounted
        reward = learning_reward(env, out.reward)
        if config.normalize_observations:
            params = params._replace(observations=update_running(params.observations, out.observation))
        if config.normalize_rewards:
            discounted = discounted * config.gamma + reward
            reward_stats = update_running(reward_stats, discounted)
            reward = normalize_reward(reward, reward_stats)
            discounted = jnp.where(done, 0.0, discounted)
        transition = Transition(runner.observation, action, log_probability(logits, action), value,
                                reward.astype(jnp.float32), _observe(config, params, out.last_observation),
                                out.terminated, done)
        runner = runner._replace(params=params, rewards=reward_stats, discounted=discounted, env_state=out.state,
                                 observation=_observe(config, params, out.observation), episodes=episodes)
        return runner, (transition, finished)

    def minibatch_step(carry: tuple[Any, Any, jax.Array], batch: Batch) -> tuple[tuple[Any, Any, jax.Array], None]:
        variables, opt_state, clip_range = carry
        grads = jax.grad(lambda v: ppo_loss(module, v, batch, clip_range, config))(variables)
        updates, opt_state = tx.update(grads, opt_state, variables)
        return (optax.apply_updates(variables, updates), opt_state, clip_range), None

    def epoch(carry: tuple[Any, Any, jax.Array], key: jax.Array, batch: Batch
              ) -> tuple[tuple[Any, Any, jax.Array], None]:
        order = jax.random.permutation(key, config.batch)
        shuffled = jax.tree.map(lambda x: x[order].reshape(config.minibatches, config.batch_size, *x.shape[1:]),
                                batch)
        carry, _ = jax.lax.scan(minibatch_step, carry, shuffled)
        return carry, None

    def update(runner: Runner, key: jax.Array) -> tuple[Runner, Finished]:
        rollout_key, epochs_key = jax.random.split(key)
        runner, (transitions, finished) = jax.lax.scan(step, runner, jax.random.split(rollout_key, config.n_steps))
        next_values = module.apply(runner.params.network, transitions.last_observation, method="value")
        advantages = gae(transitions.reward, transitions.value, next_values, transitions.terminated,
                         transitions.done, config.gamma, config.gae_lambda)
        flat = jax.tree.map(lambda x: x.reshape(config.batch, *x.shape[2:]),
                            Batch(transitions.observation, transitions.action, transitions.log_prob, advantages,
                                  advantages + transitions.value, transitions.value))
        clip_range = config.clip_range * (progress_remaining(config, runner.update)
                                          if config.anneal_clip_range else 1.0)
        carry = (runner.params.network, runner.opt_state, jnp.asarray(clip_range, jnp.float32))
        (variables, opt_state, _), _ = jax.lax.scan(lambda c, k: epoch(c, k, flat), carry,
                                                    jax.random.split(epochs_key, config.n_epochs))
        runner = runner._replace(params=runner.params._replace(network=variables), opt_state=opt_state,
                                 update=runner.update + 1)
        return runner, finished

    run = train_in_rounds(update, lambda runner: runner.params, env, greedy, rounds, config.updates // rounds,
                          eval_episodes)

    def train(key: jax.Array) -> TrainOutput:
        init_key, reset_key, train_key = jax.random.split(key, 3)
        params = init_params(config, env, init_key)
        env_state = reset_all(env, jax.random.split(reset_key, config.n_envs))
        observation = observe_all(env, env_state)
        if config.normalize_observations:
            params = params._replace(observations=update_running(params.observations, observation))
        runner = Runner(params, tx.init(params.network), RunningMeanStd.start(()),
                        jnp.zeros(config.n_envs, jnp.float64), env_state, _observe(config, params, observation),
                        Episodes.start(config.n_envs), jnp.zeros((), jnp.int32))
        return run(runner, train_key)

    return train
