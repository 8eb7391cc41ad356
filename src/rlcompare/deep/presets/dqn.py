"""DQN's settings (:mod:`rlcompare.deep.dqn`): SB3's defaults, validated on creation, and the named presets with
their sources (rl-baselines3-zoo; the MinAtar paper; Mnih et al. 2015 on the Atari 2600)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from rlcompare.envs import minatar
from rlcompare.envs.atari import games as atari
from rlcompare.validation import (
    COUNT,
    FLAG,
    NON_NEGATIVE,
    POSITIVE,
    STEP_SIZE,
    UNIT,
    WIDTHS,
    Choice,
    Integer,
    check_settings,
    require,
    setting,
)

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

    double: bool = setting(False, FLAG)
    """Double DQN (van Hasselt et al. 2016): the online network picks the next action, the target network
    values it. False: DQN's max over the target network (Mnih et al. 2015)."""
    n_envs: int = setting(1, COUNT)
    """Environments stepped side by side, >= 1; each environment step counts ``n_envs`` steps."""
    total_steps: int = setting(1_000_000, COUNT)
    """Environment steps of the training (over all environments; the zoo's ``n_timesteps``), >= 1. The
    exploration schedule spans it; the training runs whole updates, so it may take a little more."""
    learning_rate: float = setting(1e-4, POSITIVE)
    """The optimizer's step size, > 0."""
    optimizer: str = setting("adam", Choice(OPTIMIZERS))
    """``adam`` (SB3's) or ``rmsprop`` (MinAtar's centered RMSProp, :data:`OPTIMIZERS`)."""
    buffer_size: int = setting(1_000_000, COUNT)
    """Transitions the replay buffer holds (over all environments), >= ``n_envs``; the oldest go first."""
    learning_starts: int = setting(100, Integer(0))
    """Environment steps of uniformly random actions before learning; training starts once more are stored."""
    batch_size: int = setting(32, COUNT)
    """Transitions per gradient step, drawn uniformly (with replacement) from the buffer, >= 1."""
    gamma: float = setting(0.99, UNIT)
    """Discount γ, in [0, 1]."""
    train_freq: int = setting(4, COUNT)
    """Steps of every environment collected between two trainings, >= 1."""
    gradient_steps: int = setting(1, COUNT)
    """Gradient steps per training, >= 1 (SB3's ``-1`` is ``train_freq * n_envs``)."""
    target_update_interval: int = setting(10_000, COUNT)
    """Environment steps between copies of the online network into the target network, >= 1 (with several
    environments, SB3's ``max(target_update_interval // n_envs, 1)`` steps of all of them)."""
    epsilon_start: float = setting(1.0, UNIT)
    """ε of the ε-greedy exploration at the start (SB3's ``exploration_initial_eps``), in [0, 1]."""
    epsilon_end: float = setting(0.05, UNIT)
    """ε once the decay has run its course (SB3's ``exploration_final_eps``), in [0, 1]."""
    decay_fraction: float = setting(0.1, STEP_SIZE)
    """Share of ``total_steps`` over which ε goes linearly from start to end (SB3's ``exploration_fraction``),
    in (0, 1]."""
    decay_after_learning_starts: bool = setting(False, FLAG)
    """ε's decay begins once ``learning_starts`` steps are taken (MinAtar's reference); False: at the first step
    (SB3's)."""
    max_grad_norm: float = setting(10.0, NON_NEGATIVE)
    """Gradients are scaled down to this global norm, >= 0; 0: not clipped (MinAtar's reference)."""
    hidden: tuple[int, ...] = setting((64, 64), WIDTHS)
    """Widths of the Q-network's hidden layers (ReLU), each >= 1."""

    def __post_init__(self) -> None:
        check_settings(self)
        require(self.buffer_size >= self.n_envs, "buffer_size", self.buffer_size,
                f"an integer >= n_envs ({self.n_envs})")
        require(self.total_steps > self.learning_starts, "total_steps", self.total_steps,
                f"more than learning_starts ({self.learning_starts:,}): a training that never takes a gradient step "
                "learns nothing")

    def updates_per_round(self, rounds: int) -> int:
        """Updates in each of ``rounds`` rounds: the fewest whose steps reach ``total_steps`` (SB3 too ends on a
        whole rollout, so may overshoot)."""
        return math.ceil(self.total_steps / (self.train_freq * self.n_envs * rounds))

    def steps_trained(self, rounds: int) -> int:
        """Environment steps the training runs over ``rounds`` rounds: whole updates of ``train_freq`` steps of
        every environment."""
        return self.updates_per_round(rounds) * rounds * self.train_freq * self.n_envs


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
