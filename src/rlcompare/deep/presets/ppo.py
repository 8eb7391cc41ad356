"""PPO's settings (:mod:`rlcompare.deep.ppo`): SB3's defaults, validated on creation, and the named presets with
their sources."""

from __future__ import annotations

from dataclasses import dataclass

from rlcompare.deep.networks import ACTIVATIONS
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
    check_settings,
    require,
    setting,
)

NORMALIZE_EPSILON = 1e-8
"""``VecNormalize``'s ε under the square root, and the advantage normalisation's (SB3)."""
NORMALIZE_CLIP = 10.0
"""``VecNormalize``'s ``clip_obs`` and ``clip_reward``."""
ADAM_EPSILON = 1e-5
"""SB3's Adam ε for its actor-critic policies (``ActorCriticPolicy.__init__``)."""
VALUE_LOSSES = ("sb3", "purejaxrl")
"""``sb3``: ``mean((R - V)²)`` (SB3's ``F.mse_loss``, no ½); ``purejaxrl``: ``½ mean(max((R - V)², (R - V_clip)²))``,
``V_clip = V_old + clip(V - V_old, ±clip_range)`` (purejaxrl's ``_loss_fn``, as CleanRL's ``clip_vloss``)."""


@dataclass(frozen=True)
class PPOConfig:
    """PPO's settings; the defaults are SB3's ``PPO`` and ``MlpPolicy`` defaults (zoo's ``n_envs: 1`` and
    ``n_timesteps: 1e6``). Frozen and validated on creation."""

    n_envs: int = setting(1, COUNT)
    """Environments stepped side by side."""
    n_steps: int = setting(2048, COUNT)
    """Steps per environment collected for each update."""
    batch_size: int = setting(64, COUNT)
    """Minibatch size (SB3's meaning); must divide ``n_envs * n_steps``."""
    n_epochs: int = setting(10, COUNT)
    """Passes over each update's transitions, each in a fresh random order."""
    learning_rate: float = setting(3e-4, POSITIVE)
    """Adam's step size (at the start, where ``anneal_lr``)."""
    anneal_lr: bool = setting(False, FLAG)
    """Decay the learning rate linearly to 0 over training (the zoo's ``lin_``)."""
    gamma: float = setting(0.99, STEP_SIZE)
    """Discount factor."""
    gae_lambda: float = setting(0.95, UNIT)
    """GAE's λ (Schulman et al. 2016)."""
    clip_range: float = setting(0.2, POSITIVE)
    """The surrogate's ε: the probability ratio is clipped to [1 - ε, 1 + ε] (at the start, where annealed)."""
    anneal_clip_range: bool = setting(False, FLAG)
    """Decay ``clip_range`` linearly to 0 over training (the zoo's ``lin_``)."""
    ent_coef: float = setting(0.0, NON_NEGATIVE)
    """Weight of the entropy bonus in the loss."""
    vf_coef: float = setting(0.5, NON_NEGATIVE)
    """Weight of the value loss in the loss."""
    max_grad_norm: float = setting(0.5, POSITIVE)
    """The gradient's global norm is clipped to this."""
    normalize_advantage: bool = setting(True, FLAG)
    """Normalise the advantages within each minibatch (to zero mean, unit sample standard deviation)."""
    normalize_observations: bool = setting(False, FLAG)
    """Normalise observations by running mean and variance, clipped to ±10 (``VecNormalize(norm_obs=True)``)."""
    normalize_rewards: bool = setting(False, FLAG)
    """Divide rewards by the running standard deviation of the discounted return, clipped to ±10
    (``VecNormalize(norm_reward=True)``)."""
    hidden: tuple[int, ...] = setting((64, 64), WIDTHS)
    """Widths of the hidden layers of each of the two networks, actor and critic (SB3's ``net_arch``)."""
    activation: str = setting("tanh", Choice(tuple(ACTIVATIONS)))
    """Hidden activation: ``tanh`` (SB3's default) or ``relu``; also after the convolution, for images."""
    total_steps: int = setting(1_000_000, COUNT)
    """Environment steps of training in all, rounded down to whole updates."""
    value_loss: str = setting("sb3", Choice(VALUE_LOSSES))
    """The critic's loss: ``sb3`` or ``purejaxrl`` (:data:`VALUE_LOSSES`)."""

    def __post_init__(self) -> None:
        check_settings(self)
        require(self.batch % self.batch_size == 0, "batch_size", self.batch_size,
                "an integer >= 1 dividing n_envs * n_steps")
        require(self.total_steps >= self.batch, "total_steps", self.total_steps,
                "an integer >= n_envs * n_steps (one update)")

    @property
    def batch(self) -> int:
        """Transitions collected per update."""
        return self.n_envs * self.n_steps

    @property
    def updates(self) -> int:
        """Updates in the whole training."""
        return self.total_steps // self.batch

    def steps_trained(self, rounds: int) -> int:
        """Environment steps the training runs over ``rounds`` rounds: ``updates // rounds`` whole updates a
        round (the remainder is not run)."""
        return self.updates // rounds * rounds * self.batch

    @property
    def minibatches(self) -> int:
        """Minibatches per epoch."""
        return self.batch // self.batch_size


MINATAR = PPOConfig(n_envs=64, n_steps=128, batch_size=64 * 128 // 8, n_epochs=4, learning_rate=5e-3, anneal_lr=True,
                    gamma=0.99, gae_lambda=0.95, clip_range=0.2, ent_coef=1e-4, vf_coef=0.5, max_grad_norm=0.5,
                    hidden=(128,), activation="relu", total_steps=10_000_000, value_loss="purejaxrl")
"""MinAtar: purejaxql's ``config/alg/ppo_minatar.yaml`` with its ``ppo_minatar.py`` (mttga/purejaxql at 0436c80):
64 environments x 128 steps, 4 epochs x 8 minibatches (of 1,024), Adam at 5e-3 decayed linearly, γ 0.99,
GAE λ 0.95, clip 0.2 (not annealed), entropy 1e-4, value coefficient 0.5 on its clipped, halved value loss,
gradients clipped at 0.5, ReLU, 10 M steps; separate actor and critic, each MinAtar's convolution (16 channels,
flax's default initialisation) and a dense layer of 128 (orthogonal √2), heads orthogonal 0.01 and 1. The same
numbers as purejaxrl's MinAtar notebook (``examples/brax_minatar.ipynb``) but for its entropy 0.01 on a flattened
64 x 64 MLP. Departures: the schedule is SB3's, one update ahead of purejaxrl's (its ``frac`` counts the updates
done, SB3's progress the steps after this rollout); advantages are normalised with ``ddof=1`` (purejaxrl 0: a
factor √(1024/1023)); a time-limit cut (gymnax's protocol) bootstraps from V(last observation), where purejaxrl's
auto-reset treats it as termination; no observation normalisation (booleans)."""

ATARI = PPOConfig(n_envs=8, n_steps=128, batch_size=256, n_epochs=4, learning_rate=2.5e-4, anneal_lr=True,
                  clip_range=0.1, anneal_clip_range=True, ent_coef=0.01, vf_coef=0.5, hidden=(512,), activation="relu",
                  total_steps=10_000_000)
"""Atari: rl-baselines3-zoo's ``atari`` entry of ``hyperparams/ppo.yml`` (8 environments x 128 steps, 4 epochs of
minibatches of 256, Adam at 2.5e-4 and clip 0.1 both decayed linearly, entropy 0.01, value 0.5, 10 M steps), on
SB3's ``CnnPolicy``: one network of Mnih et al. (2015) shared by the policy and the value (orthogonal √2), heads
orthogonal 0.01 and 1; it learns from the score's sign, as SB3's Atari wrapper does."""

ZOO: dict[str, PPOConfig] = {
    "CartPole-v1": PPOConfig(n_envs=8, n_steps=32, batch_size=256, gae_lambda=0.8, gamma=0.98, n_epochs=20,
                             ent_coef=0.0, learning_rate=1e-3, anneal_lr=True, clip_range=0.2,
                             anneal_clip_range=True, total_steps=100_000),
    "Acrobot-v1": PPOConfig(n_envs=16, n_steps=256, gae_lambda=0.94, gamma=0.99, n_epochs=4, ent_coef=0.0,
                            normalize_observations=True, normalize_rewards=True, total_steps=1_000_000),
    "MountainCar-v0": PPOConfig(n_envs=16, n_steps=16, gae_lambda=0.98, gamma=0.99, n_epochs=4, ent_coef=0.0,
                                normalize_observations=True, normalize_rewards=True, total_steps=1_000_000),
    **dict.fromkeys(minatar.NAMES, MINATAR),
    **dict.fromkeys(atari.NAMES, ATARI),
}
"""Environment -> rl-baselines3-zoo's tuned PPO settings, ``hyperparams/ppo.yml`` (DLR-RM/rl-baselines3-zoo at
22e3ff2, 2026-04): ``lin_x`` is ``x`` with the matching ``anneal_*``; ``normalize: true`` is ``VecNormalize`` of
observations and rewards (with the algorithm's γ); fields the file leaves out keep SB3's defaults. The zoo has no
MinAtar: every MinAtar name, both protocols, has purejaxql's settings (:data:`MINATAR`)."""

PRESETS: dict[str, dict[str, PPOConfig]] = {"default": ZOO}
"""Preset name -> environment -> config. ``default``: the zoo's for classic control, purejaxql's for MinAtar
(:data:`ZOO`)."""
