"""PQN's settings (:mod:`rlcompare.deep.pqn`): purejaxql's, validated on creation, and the named presets with their
sources (purejaxql's CartPole, MinAtar and Atari configurations; ours for chess)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from rlcompare.algorithms.registry import AFTER_UPDATE, BEFORE_UPDATE
from rlcompare.envs import acrobot, minatar, mountain_car
from rlcompare.envs.atari import games as atari
from rlcompare.envs.chess import games as chess_games
from rlcompare.validation import (
    COUNT,
    FLAG,
    POSITIVE,
    STEP_SIZE,
    UNIT,
    WIDTHS,
    Choice,
    check_settings,
    require,
    setting,
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

    target: str = setting("max", Choice(TARGETS))
    """What the return bootstraps from: ``max`` (Q(λ)), ``sample`` (SARSA(λ)), ``expected`` (Expected SARSA(λ))."""
    lam: float = setting(0.95, UNIT)
    """λ of the λ-return; 0 gives the one-step target."""
    gamma: float = setting(0.99, STEP_SIZE)
    """Discount."""
    total_steps: int = setting(500_000, COUNT)
    """Environment steps over all parallel environments."""
    n_envs: int = setting(32, COUNT)
    """Environments stepped in parallel."""
    n_steps: int = setting(64, COUNT)
    """Steps of each environment per rollout (one update)."""
    n_epochs: int = setting(4, COUNT)
    """Passes over each rollout."""
    n_minibatches: int = setting(16, COUNT)
    """Minibatches per pass."""
    learning_rate: float = setting(1e-4, POSITIVE)
    """RAdam's step size."""
    anneal_lr: bool = setting(True, FLAG)
    """Decay the step size linearly to zero over the training."""
    max_grad_norm: float = setting(10.0, POSITIVE)
    """Gradients clipped to this global norm."""
    epsilon_start: float = setting(1.0, UNIT)
    """ε of the first rollout."""
    epsilon_end: float = setting(0.05, UNIT)
    """ε after the decay."""
    decay_fraction: float = setting(0.2, STEP_SIZE)
    """Fraction of the updates over which ε decays linearly."""
    reward_scale: float = setting(0.1, POSITIVE)
    """Rewards are multiplied by this in the return (the recorded returns are the environment's own)."""
    hidden: tuple[int, ...] = setting((128, 128), WIDTHS)
    """Widths of the hidden layers, each followed by LayerNorm and ReLU."""
    next_action: str = setting(BEFORE_UPDATE, Choice(NEXT_ACTIONS))
    """When the action after a rollout's last step is drawn: ``before_update`` (Algorithm 2's order: the one the
    return bootstraps from is taken next) or ``after_update`` (Algorithm 1's: drawn again from the updated
    network)."""
    scale_observations: bool = setting(False, FLAG)
    """Map a bounded observation box onto [-1, 1] before the network (Mountain Car's velocity spans ±0.07)."""

    def __post_init__(self) -> None:
        check_settings(self)
        rollout = self.n_envs * self.n_steps
        require(rollout % self.n_minibatches == 0, "n_minibatches", self.n_minibatches,
                f"a divisor of n_envs x n_steps = {rollout}")
        require(self.total_steps >= rollout, "total_steps", self.total_steps,
                f"at least one rollout, n_envs x n_steps = {rollout}")

    @property
    def updates(self) -> int:
        return self.total_steps // (self.n_envs * self.n_steps)

    def steps_trained(self, rounds: int) -> int:
        """Environment steps the training runs over ``rounds`` rounds: ``updates // rounds`` whole rollouts a
        round (the remainder is not run)."""
        return self.updates // rounds * rounds * self.n_envs * self.n_steps


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
