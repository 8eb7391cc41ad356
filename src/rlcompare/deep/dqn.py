"""DQN (Mnih et al. 2015, Nature 518) and Double DQN (van Hasselt, Guez & Silver 2016, AAAI) in the deep engine.

The semantics are Stable-Baselines3's ``DQN`` (``stable_baselines3/dqn/dqn.py`` and ``common/off_policy_algorithm.py``):
an update collects ``train_freq`` steps of every environment into a replay buffer, then, once more than
``learning_starts`` environment steps are stored, takes ``gradient_steps`` Adam steps on the Huber (smooth L1)
TD error of uniformly sampled batches, gradients clipped to a global norm of ``max_grad_norm``. The target
network is a copy of the online one, refreshed every ``target_update_interval`` environment steps (SB3 counts
``_n_calls`` while collecting, so a refresh lands before the gradient steps that follow). Before
``learning_starts`` actions are uniformly random; after, ε-greedy with SB3's linear schedule. A time-limit cut
bootstraps from the true last observation; a termination does not (SB3's ``handle_timeout_termination``).

Departures from SB3: each environment draws its own ε coin (SB3 draws one per vector step); the network has
flax's initialisation (lecun normal, zero biases), not torch's; gradients are clipped exactly to the norm (torch
adds 1e-6); the training runs whole rounds of updates (``DQNConfig.updates_per_round``).

On MinAtar's images (Young and Tian 2019, arXiv 1903.03176) the Q-network is MinAtar's (:class:`ConvNet`, no
LayerNorm), the buffer keeps the observations as booleans, and the ``default`` preset is the MinAtar paper's DQN
(:data:`MINATAR`): centered RMSProp, no gradient clipping, ε decaying after the random start. Where it departs from
the reference's ``examples/dqn.py``: batches are drawn with replacement (``random.sample`` draws without); the
first training comes one step earlier (after ``learning_starts`` + 1 transitions are stored, the reference's
``t > REPLAY_START_SIZE`` after + 2); the target interval counts environment steps from the start (the reference
counts gradient steps, so its refreshes land one step later); flax's initialisation, not torch's.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import optax

from rlcompare.deep import rollout
from rlcompare.deep.atari import NatureCNN, is_frames
from rlcompare.deep.envs import Environment, learning_reward, observe_all, reset_all, step_autoreset_all
from rlcompare.deep.networks import MLP, ConvNet, Network, is_image
from rlcompare.deep.presets.dqn import OPTIMIZERS, PRESETS, RMSPROP_DECAY, RMSPROP_EPS, DQNConfig
from rlcompare.deep.replay import Buffer, Transitions, buffer_add, buffer_init, buffer_sample
from rlcompare.validation import (
    COUNT,
    check,
)

Params = Any
Apply = Callable[[Params, jax.Array], jax.Array]
"""``(params, observations) -> Q-values``, one per action."""


Config = DQNConfig
"""The method's settings (:class:`~rlcompare.deep.methods.MethodModule`)."""
__all__ = ["OPTIMIZERS", "PRESETS", "Apply", "Config", "Params", "Targets", "act", "dqn_targets", "make_train",
           "network", "scores"]


# --- the learning rule ---

def td_target(reward: jax.Array, next_q_online: jax.Array | None, next_q_target: jax.Array,
              terminated: jax.Array, gamma: float, double: bool) -> jax.Array:
    """``r + γ V(s')``, ``V(s') = 0`` where terminated. DQN (Mnih et al. 2015): ``V = max_a Q_target(s', a)``.
    Double DQN (van Hasselt et al. 2016, eq. 4): ``V = Q_target(s', argmax_a Q_online(s', a))``;
    ``next_q_online`` is read only there (it may be None for DQN). Q-values have the actions last."""
    if double:
        if next_q_online is None:
            raise ValueError("Double DQN's target reads the online network's Q-values at the next states")
        best = jnp.argmax(next_q_online, axis=-1)
        next_value = jnp.take_along_axis(next_q_target, best[..., None], axis=-1)[..., 0]
    else:
        next_value = jnp.max(next_q_target, axis=-1)
    return reward + gamma * jnp.where(terminated, 0.0, next_value)


Targets = Callable[[Params, Params, Transitions, Apply, Any], jax.Array]
"""``(params, target_params, batch, apply, config) -> targets``: what the taken actions' Q-values learn toward, one
a transition (DQN's :func:`dqn_targets`; a variant of DQN gives its own to :func:`make_train`)."""


def dqn_targets(params: Params, target_params: Params, batch: Transitions, apply: Apply, config: DQNConfig
                ) -> jax.Array:
    """:func:`td_target` of each transition, from the target network (and the online one for Double DQN)."""
    next_q_target = apply(target_params, batch.next_observations)
    next_q_online = apply(params, batch.next_observations) if config.double else None
    return td_target(batch.rewards, next_q_online, next_q_target, batch.terminated, config.gamma, config.double)


def q_loss(params: Params, target_params: Params, batch: Transitions, apply: Apply, config: DQNConfig,
           targets: Targets = dqn_targets) -> jax.Array:
    """Mean Huber loss (δ = 1; SB3's ``smooth_l1_loss``, Mnih et al. 2015's error clipping) between the taken
    actions' Q-values and their ``targets``, which are held fixed."""
    target = jax.lax.stop_gradient(targets(params, target_params, batch, apply, config))
    q = jnp.take_along_axis(apply(params, batch.observations), batch.actions[:, None], axis=-1)[:, 0]
    return jnp.mean(optax.huber_loss(q, target, delta=1.0))


def epsilon(config: DQNConfig, steps: jax.Array) -> jax.Array:
    """ε after ``steps`` environment steps: SB3's ``LinearSchedule``, from ``epsilon_start`` to ``epsilon_end``
    over the first ``decay_fraction`` of ``total_steps`` (counted from ``learning_starts`` where
    ``decay_after_learning_starts``, as MinAtar's reference), then constant."""
    if config.decay_after_learning_starts:
        steps = jnp.maximum(steps - config.learning_starts, 0)
    progress = jnp.minimum(steps / (config.decay_fraction * config.total_steps), 1.0)
    return (config.epsilon_start + progress * (config.epsilon_end - config.epsilon_start)).astype(jnp.float32)


def network(config: DQNConfig, env: Environment) -> MLP | ConvNet | NatureCNN:
    """The Q-network: ``observations -> (..., n_actions)`` Q-values (flax's default initialisation): an MLP of
    ``hidden``, or for images MinAtar's network without LayerNorm (a 3 x 3 convolution of 16, then ``hidden``), or
    for Atari's frames Mnih et al.'s (2015)."""
    if is_frames(env.observation_shape):
        return NatureCNN(env.n_actions, hidden=config.hidden)
    if is_image(env.observation_shape):
        return ConvNet(env.n_actions, hidden=config.hidden, layer_norm=False)
    return MLP(hidden=config.hidden, outputs=env.n_actions)


def scores(config: DQNConfig, env: Environment) -> Callable[[Params, jax.Array], jax.Array]:
    """``(params, observations) -> (batch, n_actions)`` Q-values, what the greedy policy maximises."""
    net: Network = network(config, env)
    return net.apply


def act(config: DQNConfig, env: Environment) -> rollout.Act:
    """``(params, observations) -> int32 actions`` greedy in the Q-values (ties: the first)."""
    values = scores(config, env)

    def greedy(params: Params, observations: jax.Array) -> jax.Array:
        return jnp.argmax(values(params, observations), axis=-1).astype(jnp.int32)

    return greedy


def optimizer(config: DQNConfig) -> optax.GradientTransformation:
    """Gradients clipped to a global norm of ``max_grad_norm`` (unless 0), then SB3's Adam (ε = 1e-8, as torch's)
    or MinAtar's centered RMSProp (torch's ``RMSprop(alpha=0.95, eps=0.01, centered=True)``, ε outside the root)."""
    if config.optimizer == "rmsprop":
        step = optax.rmsprop(config.learning_rate, decay=RMSPROP_DECAY, eps=RMSPROP_EPS, eps_in_sqrt=False,
                             centered=True)
    else:
        step = optax.adam(config.learning_rate)
    if config.max_grad_norm == 0:
        return optax.chain(step)
    return optax.chain(optax.clip_by_global_norm(config.max_grad_norm), step)


# --- one seed's training ---

class Runner(NamedTuple):
    """Everything one seed's training carries from update to update."""

    params: Params
    target_params: Params
    opt_state: optax.OptState
    buffer: Buffer
    env_state: Any
    """(n_envs,) environments."""
    observations: jax.Array
    """(n_envs, *observation shape) in the environment's dtype, what the agent sees now."""
    episodes: rollout.Episodes
    steps: jax.Array
    """int64, environment steps so far over all environments (SB3's ``num_timesteps``)."""


def init_runner(config: DQNConfig, env: Environment, key: jax.Array) -> Runner:
    """A fresh network (the target a copy of it), an empty buffer and ``n_envs`` started environments."""
    net_key, env_key = jax.random.split(key)
    params = network(config, env).init(net_key, jnp.zeros((1, *env.observation_shape), jnp.float32))
    env_state = reset_all(env, jax.random.split(env_key, config.n_envs))
    observations = observe_all(env, env_state)
    buffer = buffer_init(config.buffer_size, observations.shape[1:], observations.dtype)
    return Runner(params, params, optimizer(config).init(params), buffer, env_state, observations,
                  rollout.Episodes.start(config.n_envs), jnp.zeros((), jnp.int64))


def _collect_step(config: DQNConfig, env: Environment
                  ) -> Callable[[Runner, jax.Array], tuple[Runner, rollout.Finished]]:
    """``(runner, key) -> (runner, finished)``: one step of every environment, stored in the buffer. Actions are
    uniform before ``learning_starts`` steps, then ε-greedy (each environment draws its own explore coin)."""
    greedy = act(config, env)

    def collect(runner: Runner, key: jax.Array) -> tuple[Runner, rollout.Finished]:
        coin_key, action_key, reset_key = jax.random.split(key, 3)
        uniform = jax.random.randint(action_key, (config.n_envs,), 0, env.n_actions, jnp.int32)
        explore = ((runner.steps < config.learning_starts)
                   | (jax.random.uniform(coin_key, (config.n_envs,)) < epsilon(config, runner.steps)))
        actions = jnp.where(explore, uniform, greedy(runner.params, runner.observations))
        step = step_autoreset_all(env, runner.env_state, actions, jax.random.split(reset_key, config.n_envs))
        buffer = buffer_add(runner.buffer, Transitions(runner.observations, actions, learning_reward(env, step.reward),
                                                       step.last_observation, step.terminated))
        episodes, finished = rollout.track(runner.episodes, step.reward, step.terminated, step.truncated)
        return runner._replace(buffer=buffer, env_state=step.state, observations=step.observation,
                               episodes=episodes, steps=runner.steps + config.n_envs), finished

    return collect


def _train(config: DQNConfig, env: Environment, targets: Targets) -> Callable[[Runner, jax.Array], Runner]:
    """``(runner, key) -> runner`` after ``gradient_steps`` steps of :func:`optimizer` on :func:`q_loss`."""
    net: Network = network(config, env)
    apply, tx = net.apply, optimizer(config)
    gradient = jax.grad(q_loss)

    def train(runner: Runner, key: jax.Array) -> Runner:
        def one_step(carry: tuple[Params, optax.OptState], key: jax.Array
                     ) -> tuple[tuple[Params, optax.OptState], None]:
            params, opt_state = carry
            batch = buffer_sample(runner.buffer, key, config.batch_size)
            grads = gradient(params, runner.target_params, batch, apply, config, targets)
            updates, opt_state = tx.update(grads, opt_state, params)
            return (optax.apply_updates(params, updates), opt_state), None

        (params, opt_state), _ = jax.lax.scan(one_step, (runner.params, runner.opt_state),
                                              jax.random.split(key, config.gradient_steps))
        return runner._replace(params=params, opt_state=opt_state)

    return train


def _train_once_started(config: DQNConfig, env: Environment, targets: Targets
                        ) -> Callable[[Runner, jax.Array], Runner]:
    """``(runner, key) -> runner`` after :func:`_train` if more than ``learning_starts`` steps were taken, as it was
    otherwise: a conditional, also under ``vmap``. There ``lax.cond`` on a predicate per seed becomes a select
    that computes the training in one program with the environment step and the buffer's write, which XLA:CPU
    compiles slower (4 seeds of MinAtar's DQN: a fifth fewer steps per second; with the windows cut by slicing it
    even copied the whole buffer twice a step). Here the seeds train together where any of them has started (all
    or none: they count the same steps), and each keeps its own parameters where it has not; the results are the
    same bits."""
    train = _train(config, env, targets)

    def trained(runner: Runner, key: jax.Array) -> tuple[Params, optax.OptState]:
        runner = train(runner, key)
        return runner.params, runner.opt_state

    def kept(runner: Runner, key: jax.Array) -> tuple[Params, optax.OptState]:
        return runner.params, runner.opt_state

    @jax.custom_batching.custom_vmap
    def train_once_started(runner: Runner, key: jax.Array) -> Runner:
        params, opt_state = jax.lax.cond(runner.steps > config.learning_starts, trained, kept, runner, key)
        return runner._replace(params=params, opt_state=opt_state)

    @train_once_started.def_vmap
    def batched(axis_size: int, in_batched: list[Any], runner: Runner, key: jax.Array) -> tuple[Runner, Any]:
        runner, key = jax.tree.map(lambda x, batched: x if batched else jnp.broadcast_to(x, (axis_size, *x.shape)),
                                   (runner, key), tuple(in_batched))
        started = runner.steps > config.learning_starts

        def some(runner: Runner, key: jax.Array) -> tuple[Params, optax.OptState]:
            chosen: tuple[Params, optax.OptState] = jax.tree.map(
                lambda new, old: jnp.where(started.reshape(-1, *(1,) * (new.ndim - 1)), new, old),
                jax.vmap(trained)(runner, key), jax.vmap(kept)(runner, key))
            return chosen

        which = jnp.where(jnp.all(started), 2, jnp.where(jnp.any(started), 1, 0))
        params, opt_state = jax.lax.switch(which, (jax.vmap(kept), some, jax.vmap(trained)), runner, key)
        runner = runner._replace(params=params, opt_state=opt_state)
        return runner, jax.tree.map(lambda _: True, runner)

    return train_once_started


def make_update(config: DQNConfig, env: Environment, targets: Targets = dqn_targets
                ) -> Callable[[Runner, jax.Array], tuple[Runner, rollout.Finished]]:
    """``(runner, key) -> (runner, finished)``, one update: ``train_freq`` steps of every environment
    (``finished`` is ``(train_freq, n_envs)``), the target refreshed if an interval's end was passed, then a
    training once more than ``learning_starts`` steps were taken (SB3's ``learn`` loop)."""
    collect, train = _collect_step(config, env), _train_once_started(config, env, targets)
    interval = max(config.target_update_interval // config.n_envs, 1) * config.n_envs

    def update(runner: Runner, key: jax.Array) -> tuple[Runner, rollout.Finished]:
        collect_key, train_key = jax.random.split(key)
        before = runner.steps
        runner, finished = jax.lax.scan(collect, runner, jax.random.split(collect_key, config.train_freq))
        refresh = runner.steps // interval > before // interval
        runner = runner._replace(target_params=jax.tree.map(lambda target, online: jnp.where(refresh, online, target),
                                                            runner.target_params, runner.params))
        return train(runner, train_key), finished

    return update


def make_train(config: DQNConfig, env: Environment, rounds: int, eval_episodes: int, targets: Targets = dqn_targets
               ) -> Callable[[jax.Array], rollout.TrainOutput]:
    """``key -> TrainOutput``: one seed's whole training, ``rounds`` rounds of ``config.updates_per_round(rounds)``
    updates with a greedy evaluation of ``eval_episodes`` episodes after each, learning toward ``targets``; jit-able and
    vmap-able over keys."""
    check("rounds", rounds, COUNT)
    check("eval_episodes", eval_episodes, COUNT)
    train = rollout.train_in_rounds(make_update(config, env, targets), lambda runner: runner.params, env,
                                    act(config, env), rounds, config.updates_per_round(rounds), eval_episodes)

    def run(key: jax.Array) -> rollout.TrainOutput:
        start_key, train_key = jax.random.split(key)
        return train(init_runner(config, env, start_key), train_key)

    return run
