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
adds 1e-6); the training runs whole rounds of updates (:func:`updates_per_round`).

On MinAtar's images (Young and Tian 2019, arXiv 1903.03176) the Q-network is MinAtar's (:class:`ConvNet`, no
LayerNorm), the buffer keeps the observations as booleans, and the ``default`` preset is the MinAtar paper's DQN
(:data:`MINATAR`): centered RMSProp, no gradient clipping, ε decaying after the random start. Where it departs from
the reference's ``examples/dqn.py``: batches are drawn with replacement (``random.sample`` draws without); the
first training comes one step earlier (after ``learning_starts`` + 1 transitions are stored, the reference's
``t > REPLAY_START_SIZE`` after + 2); the target interval counts environment steps from the start (the reference
counts gradient steps, so its refreshes land one step later); flax's initialisation, not torch's.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import optax

from rlcompare.deep import rollout
from rlcompare.deep.atari import NatureCNN, is_frames
from rlcompare.deep.envs import DeepEnv, EnvState, learning_reward, observe_all, reset_all, step_autoreset_all
from rlcompare.deep.networks import MLP, ConvNet, is_image
from rlcompare.envs import atari, minatar
from rlcompare.validation import ConfigError

Params = Any
Apply = Callable[[Params, jax.Array], jax.Array]
"""``(params, observations) -> Q-values``, one per action."""

OPTIMIZERS = ("adam", "rmsprop")
"""``adam``: SB3's DQN (torch's Adam, ε 1e-8). ``rmsprop``: MinAtar's DQN, torch's centered RMSProp with the
reference's settings (:data:`RMSPROP_DECAY`, :data:`RMSPROP_EPS`)."""
RMSPROP_DECAY = 0.95
"""Decay of RMSProp's averages of the gradient and its square (MinAtar ``examples/dqn.py``,
``SQUARED_GRAD_MOMENTUM``, torch's ``alpha``; the DQN paper's gradient and squared-gradient momentum)."""
RMSPROP_EPS = 0.01
"""Added to RMSProp's denominator outside the square root, as torch does (MinAtar ``examples/dqn.py``,
``MIN_SQUARED_GRAD`` passed as torch's ``eps``): the update is ``g / (sqrt(E[g^2] - E[g]^2) + 0.01)``."""


@dataclass(frozen=True)
class DQNConfig:
    """One DQN or Double DQN training, per seed. Defaults are SB3's ``DQN`` defaults (its MlpPolicy's 64 x 64
    network); frozen and validated on creation."""

    double: bool = False
    """Double DQN (van Hasselt et al. 2016): the online network picks the next action, the target network
    values it. False: DQN's max over the target network (Mnih et al. 2015)."""
    n_envs: int = 1
    """Environments stepped side by side, >= 1; each environment step counts ``n_envs`` steps."""
    total_steps: int = 1_000_000
    """Environment steps of the training (over all environments; the zoo's ``n_timesteps``), >= 1. The
    exploration schedule spans it; the training runs whole updates, so it may take a little more."""
    learning_rate: float = 1e-4
    """The optimizer's step size, > 0."""
    optimizer: str = "adam"
    """``adam`` (SB3's) or ``rmsprop`` (MinAtar's centered RMSProp, :data:`OPTIMIZERS`)."""
    buffer_size: int = 1_000_000
    """Transitions the replay buffer holds (over all environments), >= ``n_envs``; the oldest go first."""
    learning_starts: int = 100
    """Environment steps of uniformly random actions before learning; training starts once more are stored."""
    batch_size: int = 32
    """Transitions per gradient step, drawn uniformly (with replacement) from the buffer, >= 1."""
    gamma: float = 0.99
    """Discount γ, in [0, 1]."""
    train_freq: int = 4
    """Steps of every environment collected between two trainings, >= 1."""
    gradient_steps: int = 1
    """Gradient steps per training, >= 1 (SB3's ``-1`` is ``train_freq * n_envs``)."""
    target_update_interval: int = 10_000
    """Environment steps between copies of the online network into the target network, >= 1 (with several
    environments, SB3's ``max(target_update_interval // n_envs, 1)`` steps of all of them)."""
    epsilon_start: float = 1.0
    """ε of the ε-greedy exploration at the start (SB3's ``exploration_initial_eps``), in [0, 1]."""
    epsilon_end: float = 0.05
    """ε once the decay has run its course (SB3's ``exploration_final_eps``), in [0, 1]."""
    decay_fraction: float = 0.1
    """Share of ``total_steps`` over which ε goes linearly from start to end (SB3's ``exploration_fraction``),
    in (0, 1]."""
    decay_after_learning_starts: bool = False
    """ε's decay begins once ``learning_starts`` steps are taken (MinAtar's reference); False: at the first step
    (SB3's)."""
    max_grad_norm: float = 10.0
    """Gradients are scaled down to this global norm, >= 0; 0: not clipped (MinAtar's reference)."""
    hidden: tuple[int, ...] = (64, 64)
    """Widths of the Q-network's hidden layers (ReLU), each >= 1."""

    def __post_init__(self) -> None:
        for name in ("double", "decay_after_learning_starts"):
            _require(name, isinstance(getattr(self, name), bool), getattr(self, name), "True or False")
        _require("optimizer", isinstance(self.optimizer, str) and self.optimizer in OPTIMIZERS, self.optimizer,
                 ", ".join(OPTIMIZERS))
        for name, low in _INTEGER_MINIMUMS.items():
            value = getattr(self, name)
            _require(name, _is_integer(value) and value >= low, value, f"an integer >= {low}")
        _require("buffer_size", _is_integer(self.buffer_size) and self.buffer_size >= self.n_envs,
                 self.buffer_size, f"an integer >= n_envs ({self.n_envs})")
        for name, (low, high, low_open) in _NUMBER_RANGES.items():
            value = getattr(self, name)
            ok = _is_number(value) and (low < value if low_open else low <= value) and value <= high
            allowed = (f"a number in {'(' if low_open else '['}{low}, {high}]" if math.isfinite(high)
                       else f"a finite number {'>' if low_open else '>='} {low}")
            _require(name, ok, value, allowed)
        _require("hidden", isinstance(self.hidden, tuple) and all(_is_integer(w) and w >= 1 for w in self.hidden),
                 self.hidden, "a tuple of integers >= 1")


_INTEGER_MINIMUMS = {"n_envs": 1, "total_steps": 1, "learning_starts": 0, "batch_size": 1, "train_freq": 1,
                     "gradient_steps": 1, "target_update_interval": 1}
_NUMBER_RANGES = {"learning_rate": (0, math.inf, True), "gamma": (0, 1, False), "epsilon_start": (0, 1, False),
                  "epsilon_end": (0, 1, False), "decay_fraction": (0, 1, True), "max_grad_norm": (0, math.inf, False)}
"""``name: (low, high, low excluded)``; ``high`` is included (infinity excluded by finiteness)."""


def _is_integer(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    """A finite int or float, not a bool."""
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _require(name: str, ok: bool, value: Any, allowed: str) -> None:
    if not ok:
        raise ConfigError(name, value, allowed)


ZOO = ("rl-baselines3-zoo, hyperparams/dqn.yml (github.com/DLR-RM/rl-baselines3-zoo, commit 22e3ff2, "
       "file last changed in eec15dc, 2026-04-01)")
"""Where the ``default`` presets come from."""
_ZOO_SETTINGS = {
    # "Almost Tuned"
    "CartPole-v1": DQNConfig(total_steps=50_000, learning_rate=2.3e-3, batch_size=64, buffer_size=100_000,
                             learning_starts=1000, gamma=0.99, target_update_interval=10, train_freq=256,
                             gradient_steps=128, decay_fraction=0.16, epsilon_end=0.04, hidden=(256, 256)),
    # "Tuned"
    "MountainCar-v0": DQNConfig(total_steps=120_000, learning_rate=4e-3, batch_size=128, buffer_size=10_000,
                                learning_starts=1000, gamma=0.98, target_update_interval=600, train_freq=16,
                                gradient_steps=8, decay_fraction=0.2, epsilon_end=0.07, hidden=(256, 256)),
    # "Tuned"; the zoo's gradient_steps -1 is SB3's "as many as steps collected": train_freq * n_envs = 4.
    "Acrobot-v1": DQNConfig(total_steps=100_000, learning_rate=6.3e-4, batch_size=128, buffer_size=50_000,
                            learning_starts=0, gamma=0.99, target_update_interval=250, train_freq=4,
                            gradient_steps=4, decay_fraction=0.12, epsilon_end=0.1, hidden=(256, 256)),
}


def small(config: DQNConfig) -> DQNConfig:
    """The same settings with a 2 x 64 network (SB3's default MlpPolicy): about a fifteenth of the 256 x 256's
    multiply-adds."""
    return dataclasses.replace(config, hidden=(64, 64))


MINATAR_SOURCE = ("Young and Tian 2019 (arXiv 1903.03176) and its reference code, examples/dqn.py in "
                  "github.com/kenjyoung/MinAtar (commit 4241f24, 2024-12-19)")
"""Where the MinAtar preset comes from."""
MINATAR = DQNConfig(total_steps=5_000_000, n_envs=1, learning_rate=2.5e-4, optimizer="rmsprop", buffer_size=100_000,
                    learning_starts=5_000, batch_size=32, gamma=0.99, train_freq=1, gradient_steps=1,
                    target_update_interval=1_000, epsilon_start=1.0, epsilon_end=0.1, decay_fraction=0.02,
                    decay_after_learning_starts=True, max_grad_norm=0.0, hidden=(128,))
"""MinAtar's DQN (:data:`MINATAR_SOURCE`): ``NUM_FRAMES`` 5 M, ``REPLAY_BUFFER_SIZE`` 100,000, ``BATCH_SIZE`` 32,
``TARGET_NETWORK_UPDATE_FREQ`` 1,000, ``TRAINING_FREQ`` 1, centered RMSProp (``STEP_SIZE`` 0.00025,
``SQUARED_GRAD_MOMENTUM`` 0.95, ``MIN_SQUARED_GRAD`` 0.01), ``GAMMA`` 0.99, ``REPLAY_START_SIZE`` 5,000 uniformly
random steps, then ε from 1 to ``END_EPSILON`` 0.1 over ``FIRST_N_FRAMES`` 100,000 (0.02 of 5 M), Huber loss, no
gradient clipping; MinAtar's network (a 3 x 3 convolution of 16, a dense layer of 128). Double DQN takes the same
settings (van Hasselt et al. 2016 keep DQN's); MinAtar's paper ran only DQN."""

ATARI = DQNConfig(total_steps=10_000_000, buffer_size=100_000, learning_rate=1e-4, batch_size=32,
                  learning_starts=100_000, target_update_interval=1_000, train_freq=4, gradient_steps=1,
                  decay_fraction=0.1, epsilon_end=0.01, hidden=(512,))
"""Atari: rl-baselines3-zoo's ``atari`` entry of ``hyperparams/dqn.yml`` (10 M steps, replay 100,000, Adam at 1e-4,
batch 32, 100,000 random steps first, target every 1,000, a gradient step every 4, ε 1 -> 0.01 over the first
tenth; SB3's Huber loss and gradients clipped at 10) with Mnih et al. (2015)'s network, learning from the score's
sign as SB3's Atari wrapper does."""

PRESETS = {"default": {**{env: small(config) for env, config in _ZOO_SETTINGS.items()},
                       **dict.fromkeys(minatar.NAMES, MINATAR), **dict.fromkeys(atari.NAMES, ATARI)},
           "zoo": {**_ZOO_SETTINGS, **dict.fromkeys(atari.NAMES, ATARI)}}
"""Preset name -> environment -> config, with ``double=False`` (the registry fixes it per method). ``zoo``: the
zoo's DQN settings (:data:`ZOO`), SB3's defaults elsewhere (``exploration_initial_eps`` 1.0, ``max_grad_norm``
10); ``default``: the same on a 2 x 64 network, which trains many seeds in minutes on a CPU, and on every MinAtar
name (both protocols) the MinAtar paper's DQN, :data:`MINATAR` (:data:`MINATAR_SOURCE`)."""


# --- the replay buffer ---

class Transitions(NamedTuple):
    """Transitions along a leading axis, as the buffer stores them."""

    observations: jax.Array
    """(n, *observation shape) in the environment's dtype: float32 vectors (classic control), booleans (MinAtar)"""
    actions: jax.Array
    """(n,) int32"""
    rewards: jax.Array
    """(n,) float32"""
    next_observations: jax.Array
    """(n, *observation shape), as ``observations``: the observation the action led to, before any reset (a
    time-limit cut bootstraps from it)."""
    terminated: jax.Array
    """(n,) bool: a terminal state, whose value is zero; a time-limit cut is not one."""


class Buffer(NamedTuple):
    """A circular replay buffer (Mnih et al. 2015; Lin 1992): the newest transitions overwrite the oldest."""

    data: Transitions
    """``capacity`` rows; those past ``size`` are zeros."""
    position: jax.Array
    """int32, the slot the next transition goes to."""
    size: jax.Array
    """int32, filled slots."""


def buffer_init(capacity: int, observation_shape: int | tuple[int, ...], dtype: jnp.dtype = jnp.float32) -> Buffer:
    """An empty buffer of ``capacity`` transitions whose observations have ``observation_shape`` (a size: a vector)
    and ``dtype`` (MinAtar's booleans take a byte a cell: 100,000 x 10 x 10 x 10 is 10 MB a copy, not 40)."""
    shape = (capacity, observation_shape) if isinstance(observation_shape, int) else (capacity, *observation_shape)
    data = Transitions(jnp.zeros(shape, dtype), jnp.zeros(capacity, jnp.int32), jnp.zeros(capacity, jnp.float32),
                       jnp.zeros(shape, dtype), jnp.zeros(capacity, bool))
    return Buffer(data, jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32))


def buffer_add(buffer: Buffer, batch: Transitions) -> Buffer:
    """``batch`` (at most ``capacity`` rows, cast to the buffer's dtypes) written after the newest, wrapping."""
    capacity, n = buffer.data.actions.shape[0], batch.actions.shape[0]
    slots = (buffer.position + jnp.arange(n, dtype=jnp.int32)) % capacity
    data = jax.tree.map(lambda store, new: store.at[slots].set(new.astype(store.dtype)), buffer.data, batch)
    return Buffer(data, (buffer.position + n) % capacity, jnp.minimum(buffer.size + n, capacity))


def buffer_sample(buffer: Buffer, key: jax.Array, batch_size: int) -> Transitions:
    """``batch_size`` filled transitions drawn uniformly with replacement (SB3's ``ReplayBuffer.sample``)."""
    index = jax.random.randint(key, (batch_size,), 0, buffer.size)
    return jax.tree.map(lambda store: store[index], buffer.data)


# --- the learning rule ---

def td_target(reward: jax.Array, next_q_online: jax.Array | None, next_q_target: jax.Array,
              terminated: jax.Array, gamma: float, double: bool) -> jax.Array:
    """``r + γ V(s')``, ``V(s') = 0`` where terminated. DQN (Mnih et al. 2015): ``V = max_a Q_target(s', a)``.
    Double DQN (van Hasselt et al. 2016, eq. 4): ``V = Q_target(s', argmax_a Q_online(s', a))``;
    ``next_q_online`` is read only there (it may be None for DQN). Q-values have the actions last."""
    if double:
        best = jnp.argmax(next_q_online, axis=-1)
        next_value = jnp.take_along_axis(next_q_target, best[..., None], axis=-1)[..., 0]
    else:
        next_value = jnp.max(next_q_target, axis=-1)
    return reward + gamma * jnp.where(terminated, 0.0, next_value)


def q_loss(params: Params, target_params: Params, batch: Transitions, apply: Apply, gamma: float,
           double: bool) -> jax.Array:
    """Mean Huber loss (δ = 1; SB3's ``smooth_l1_loss``, Mnih et al. 2015's error clipping) between the taken
    actions' Q-values and their :func:`td_target`, which is held fixed."""
    next_q_target = apply(target_params, batch.next_observations)
    next_q_online = apply(params, batch.next_observations) if double else None
    target = jax.lax.stop_gradient(td_target(batch.rewards, next_q_online, next_q_target, batch.terminated,
                                             gamma, double))
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


def network(config: DQNConfig, env: DeepEnv) -> MLP | ConvNet | NatureCNN:
    """The Q-network: ``observations -> (..., n_actions)`` Q-values (flax's default initialisation): an MLP of
    ``hidden``, or for images MinAtar's network without LayerNorm (a 3 x 3 convolution of 16, then ``hidden``), or
    for Atari's frames Mnih et al.'s (2015)."""
    if is_frames(env.observation_shape):
        return NatureCNN(env.n_actions, hidden=config.hidden)
    if is_image(env.observation_shape):
        return ConvNet(env.n_actions, hidden=config.hidden, layer_norm=False)
    return MLP(hidden=config.hidden, outputs=env.n_actions)


def act(config: DQNConfig, env: DeepEnv) -> rollout.Act:
    """``(params, observations) -> int32 actions`` greedy in the Q-values (ties: the first)."""
    apply = network(config, env).apply

    def greedy(params: Params, observations: jax.Array) -> jax.Array:
        return jnp.argmax(apply(params, observations), axis=-1).astype(jnp.int32)

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
    env_state: EnvState
    """(n_envs,) environments."""
    observations: jax.Array
    """(n_envs, *observation shape) in the environment's dtype, what the agent sees now."""
    episodes: rollout.Episodes
    steps: jax.Array
    """int64, environment steps so far over all environments (SB3's ``num_timesteps``)."""


def init_runner(config: DQNConfig, env: DeepEnv, key: jax.Array) -> Runner:
    """A fresh network (the target a copy of it), an empty buffer and ``n_envs`` started environments."""
    net_key, env_key = jax.random.split(key)
    params = network(config, env).init(net_key, jnp.zeros((1, *env.observation_shape), jnp.float32))
    env_state = reset_all(env, jax.random.split(env_key, config.n_envs))
    observations = observe_all(env, env_state)
    buffer = buffer_init(config.buffer_size, observations.shape[1:], observations.dtype)
    return Runner(params, params, optimizer(config).init(params), buffer, env_state, observations,
                  rollout.Episodes.start(config.n_envs), jnp.zeros((), jnp.int64))


def _collect_step(config: DQNConfig, env: DeepEnv) -> Callable[[Runner, jax.Array], tuple[Runner, rollout.Finished]]:
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


def _train(config: DQNConfig, env: DeepEnv) -> Callable[[Runner, jax.Array], Runner]:
    """``(runner, key) -> runner`` after ``gradient_steps`` steps of :func:`optimizer` on :func:`q_loss`."""
    apply, tx = network(config, env).apply, optimizer(config)
    gradient = jax.grad(q_loss)

    def train(runner: Runner, key: jax.Array) -> Runner:
        def one_step(carry: tuple[Params, optax.OptState], key: jax.Array) -> tuple[tuple, None]:
            params, opt_state = carry
            batch = buffer_sample(runner.buffer, key, config.batch_size)
            grads = gradient(params, runner.target_params, batch, apply, config.gamma, config.double)
            updates, opt_state = tx.update(grads, opt_state, params)
            return (optax.apply_updates(params, updates), opt_state), None

        (params, opt_state), _ = jax.lax.scan(one_step, (runner.params, runner.opt_state),
                                              jax.random.split(key, config.gradient_steps))
        return runner._replace(params=params, opt_state=opt_state)

    return train


def _train_once_started(config: DQNConfig, env: DeepEnv) -> Callable[[Runner, jax.Array], Runner]:
    """``(runner, key) -> runner`` after :func:`_train` if more than ``learning_starts`` steps were taken, as it was
    otherwise: a conditional, also under ``vmap``. There ``lax.cond`` on a predicate per seed becomes a select
    that computes the training in one program with the environment step and the buffer's write, which XLA:CPU
    compiles slower (4 seeds of MinAtar's DQN: a fifth fewer steps per second; with the windows cut by slicing it
    even copied the whole buffer twice a step). Here the seeds train together where any of them has started (all
    or none: they count the same steps), and each keeps its own parameters where it has not; the results are the
    same bits."""
    train = _train(config, env)

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
    def batched(axis_size: int, in_batched: list, runner: Runner, key: jax.Array) -> tuple[Runner, Any]:
        runner, key = jax.tree.map(lambda x, batched: x if batched else jnp.broadcast_to(x, (axis_size, *x.shape)),
                                   (runner, key), tuple(in_batched))
        started = runner.steps > config.learning_starts

        def some(runner: Runner, key: jax.Array) -> tuple[Params, optax.OptState]:
            return jax.tree.map(lambda new, old: jnp.where(started.reshape(-1, *(1,) * (new.ndim - 1)), new, old),
                                jax.vmap(trained)(runner, key), jax.vmap(kept)(runner, key))

        which = jnp.where(jnp.all(started), 2, jnp.where(jnp.any(started), 1, 0))
        params, opt_state = jax.lax.switch(which, (jax.vmap(kept), some, jax.vmap(trained)), runner, key)
        runner = runner._replace(params=params, opt_state=opt_state)
        return runner, jax.tree.map(lambda _: True, runner)

    return train_once_started


def make_update(config: DQNConfig, env: DeepEnv) -> Callable[[Runner, jax.Array], tuple[Runner, rollout.Finished]]:
    """``(runner, key) -> (runner, finished)``, one update: ``train_freq`` steps of every environment
    (``finished`` is ``(train_freq, n_envs)``), the target refreshed if an interval's end was passed, then a
    training once more than ``learning_starts`` steps were taken (SB3's ``learn`` loop)."""
    collect, train = _collect_step(config, env), _train_once_started(config, env)
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


def updates_per_round(config: DQNConfig, rounds: int) -> int:
    """Updates in each of ``rounds`` rounds: the fewest whose steps reach ``total_steps`` (SB3 too ends on a
    whole rollout, so may overshoot)."""
    return math.ceil(config.total_steps / (config.train_freq * config.n_envs * rounds))


def make_train(config: DQNConfig, env: DeepEnv, rounds: int, eval_episodes: int
               ) -> Callable[[jax.Array], rollout.TrainOutput]:
    """``key -> TrainOutput``: one seed's whole training, ``rounds`` rounds of :func:`updates_per_round` updates
    with a greedy evaluation of ``eval_episodes`` episodes after each; jit-able and vmap-able over keys."""
    _require("rounds", _is_integer(rounds) and rounds >= 1, rounds, "an integer >= 1")
    _require("eval_episodes", _is_integer(eval_episodes) and eval_episodes >= 1, eval_episodes, "an integer >= 1")
    train = rollout.train_in_rounds(make_update(config, env), lambda runner: runner.params, env, act(config, env),
                                    rounds, updates_per_round(config, rounds), eval_episodes)

    def run(key: jax.Array) -> rollout.TrainOutput:
        start_key, train_key = jax.random.split(key)
        return train(init_runner(config, env, start_key), train_key)

    return run
