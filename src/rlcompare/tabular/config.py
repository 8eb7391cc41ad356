"""The configuration of one experiment: one algorithm and schedule over many seeds.

Defaults are the paper's setting (Section IV): MountainCar-v0, 20 bins per dimension, α = 0.05, γ = 0.9,
a 1000-step limit, Q-tables initialised to zero. What the paper leaves open (episodes, seeds, the decay
rule, evaluation) is documented in ``docs/departures.md``; other environments have their own default grid
and limit (``docs/environments.md``), filled in on creation so that a configuration always says what ran.
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import inspect
import itertools
import json
import math
import re
import textwrap
from dataclasses import dataclass, field
from typing import Any, ClassVar

from rlcompare.algorithms.registry import AFTER_UPDATE, BEFORE_UPDATE, METHODS
from rlcompare.algorithms.schedules import SCHEDULES
from rlcompare.envs.registry import ENDGAMES, PORTS, TABLE_ENVIRONMENTS, Environment, environment
from rlcompare.formatting import cut
from rlcompare.validation import (
    COUNT,
    FLAG,
    STEP_SIZE,
    UNIT,
    ConfigError,
    Integer,
    check_fields,
    field_rules,
    is_integer,
    plain,
    require,
    setting,
)

ENVIRONMENTS = (*PORTS, *TABLE_ENVIRONMENTS, *ENDGAMES)
"""Environments stepped by compiled code; any other registered Gymnasium environment runs through the adapter."""
MAX_WEIGHT_BYTES = 4 * 2**30
"""Weights, second estimates and snapshots of all seeds together may take at most this much memory."""
MAX_COUNT = 2**31 - 1
"""The largest episode count, step limit or layout size: the kernels count in 32 bits."""
KERNEL_COUNT = Integer(1, MAX_COUNT)
"""The rule of a count field."""
FLOAT_FIELDS = ("alpha", "gamma", "epsilon", "epsilon_start", "epsilon_end", "decay_fraction", "lam",
                "baseline_alpha", "target_epsilon")
"""Fields holding a number, kept as floats so that ``1`` and ``1.0`` are one configuration (one hash)."""
ALGORITHMS = tuple(METHODS)
NEXT_ACTION_DEFAULTS = {name: m.next_action for name, m in METHODS.items() if m.one_step}
"""When each one-step learner draws its next action in its book box: SARSA before its update (Algorithm 2),
the others after it (Algorithm 1)."""
FEATURES = ("grid", "tiles")
TRACES = ("replacing", "accumulating")
DEFAULT_STAGES = (("early", 0.1), ("middle", 0.5), ("final", 1.0))


@dataclass(frozen=True)
class ExperimentConfig:
    """One configuration, run once per seed. Frozen and validated on creation."""

    engine: ClassVar[str] = "tabular"
    """The engine that trains it (:mod:`rlcompare.experiment.engines`)."""

    algorithm: str = "q_learning"
    """Learning rule: a method of :data:`rlcompare.algorithms.registry.METHODS`, for example ``q_learning``
    (Algorithm 1), ``sarsa`` (Algorithm 2) or ``random`` (the baseline); ``rlcompare run --help`` lists them all."""
    schedule: str = "decay"
    """Exploration: ``constant`` (ε fixed) or ``decay`` (linear from ``epsilon_start`` to ``epsilon_end``)."""
    env: str = "MountainCar-v0"
    """``MountainCar-v0`` (Gymnasium's, ported exactly), ``MountainCar-book`` (Sutton and Barto's Example
    10.1: the same dynamics with the position bounded at the goal, 0.5), ``CartPole-v1`` and ``Acrobot-v1``
    (ported exactly), a toy-text environment stepped from Gymnasium's own transition table:
    ``CliffWalking-v1`` (Example 6.6), ``FrozenLake-v1`` (4x4, slippery), ``FrozenLake8x8-v1``, ``Taxi-v4``; the
    chess endgames ``KRK`` and ``KQK`` against a defender, with options after the name
    (``KRK:defender=random,starts=hard,symmetries=off``: ``docs/chess.md``); or any other registered Gymnasium
    environment with Discrete actions and Discrete or Box observations, stepped
    through Gymnasium's API at Python speed."""
    adapter: bool = False
    """Step the environment through Gymnasium's own API (the adapter, at Python speed) even where a compiled
    port exists: to check a port against Gymnasium, which gives the same results bit for bit."""
    features: str = "grid"
    """``grid``: one cell of ``bins`` per dimension (the paper); ``tiles``: tile coding (9.5.4)."""
    tilings: int = setting(8, KERNEL_COUNT)
    """Tilings of the tile coder, >= 1."""
    tiles: int = setting(8, KERNEL_COUNT)
    """Tiles per dimension in each tiling, >= 1."""
    hash_size: int = 0
    """Hash the tiles into this many features; 0: no hashing."""
    n: int = setting(4, KERNEL_COUNT)
    """n of n-step SARSA, >= 1."""
    lam: float = setting(0.9, UNIT)
    """λ of SARSA(λ) and Q(λ), in [0, 1]."""
    trace: str = "replacing"
    """Eligibility traces: ``replacing`` or ``accumulating``."""
    target_epsilon: float | None = None
    """ε of the target policy of Expected SARSA and Double Expected SARSA: None for the behaviour's ε (on-policy),
    0 for greedy (off-policy)."""
    next_action: str | None = None
    """When a one-step learner draws its next action A': ``before_update`` (from the values its target
    bootstraps on, before ``Q(S, A)`` moves: SARSA's box, Algorithm 2) or ``after_update`` (from the updated
    values: Q-Learning's box, Algorithm 1). None: the method's own box (:attr:`drawn_next`). Only the
    one-step learners have it (:attr:`rlcompare.algorithms.registry.Method.one_step`; ``docs/why.md``)."""
    baseline_alpha: float = setting(0.01, STEP_SIZE)
    """Step size of REINFORCE's state-value baseline (``reinforce_baseline``), in (0, 1]."""
    alpha: float = setting(0.05, STEP_SIZE)
    """Step size α, in (0, 1]."""
    gamma: float = setting(0.9, UNIT)
    """Discount γ, in [0, 1]."""
    epsilon: float = setting(0.5, UNIT)
    """ε of the ``constant`` schedule, in [0, 1]."""
    epsilon_start: float = setting(1.0, UNIT)
    """ε at the first episode of the ``decay`` schedule, in [0, 1]."""
    epsilon_end: float = setting(0.0, UNIT)
    """ε once the ``decay`` schedule has run its course, in [0, 1]."""
    decay_fraction: float = setting(0.5, STEP_SIZE)
    """Share of the episodes over which ``decay`` goes from start to end, in (0, 1]."""
    bins: int | tuple[int, ...] | None = None
    """Cells per observation dimension of the uniform grid (``DiscretizeObservation(env, bins)``), >= 1; one
    number for every dimension or one per dimension. None: the environment's default (the paper's 20 for
    Mountain Car). Finite environments ignore it: each state is its own feature."""
    bounds: tuple[tuple[float, float], ...] | None = None
    """``(low, high)`` per observation dimension for the grid and the tiles; None: the environment's
    defaults (its observation box, with chosen bounds where the box is unbounded: ``docs/environments.md``)."""
    episodes: int = setting(5000, KERNEL_COUNT)
    """Training episodes per seed, >= 1."""
    max_steps: int | None = setting(None, KERNEL_COUNT)
    """Episode limit; reaching it truncates the episode, >= 1. None: the environment's default (the paper's
    1000 moves for Mountain Car, Gymnasium's registered limit for the others)."""
    truncation_as_terminal: bool = False
    """Treat the time limit as a terminal state (old Gym ``done``) instead of bootstrapping through it."""
    seeds: tuple[int, ...] = tuple(range(30))
    """One run per seed; seed ``s`` draws the start states of ``env.reset(seed=s)``."""
    eval_every: int = 50
    """Evaluate the greedy policy after every this many episodes; 0 turns evaluation off."""
    eval_episodes: int = setting(10, KERNEL_COUNT)
    """Episodes per evaluation, >= 1."""
    stages: tuple[tuple[str, float], ...] = field(default=DEFAULT_STAGES)
    """Named stages of learning, as shares of the episodes, at which the Q-table is kept."""

    def __post_init__(self) -> None:
        for item in dataclasses.fields(self):  # NumPy's scalars as the Python values they hold (seeds below)
            if item.name != "seeds":
                object.__setattr__(self, item.name, plain(getattr(self, item.name)))
        try:
            object.__setattr__(self, "seeds", _plain_seeds(tuple(self.seeds)))
        except (TypeError, ValueError):
            raise ConfigError("seeds", self.seeds, "a list of distinct integers >= 0") from None
        try:
            object.__setattr__(self, "stages", tuple((str(n), float(f)) for n, f in self.stages))
        except (TypeError, ValueError):
            raise ConfigError("stages", self.stages, "pairs of (name, share of the episodes)") from None
        if isinstance(self.bins, list | tuple):
            object.__setattr__(self, "bins", tuple(plain(b) for b in self.bins))
        if self.bounds is not None:
            try:
                object.__setattr__(self, "bounds", tuple((float(low), float(high)) for low, high in self.bounds))
            except (TypeError, ValueError):
                raise ConfigError("bounds", self.bounds, "pairs of numbers (low, high), one per observation "
                                  "dimension") from None
        _check_choices(self)
        env = self.environment
        if self.bins is None:
            object.__setattr__(self, "bins", env.bins)
        if self.max_steps is None:
            object.__setattr__(self, "max_steps", env.max_steps)
        for check in _CHECKS:
            check(self)
        for name, value in _as_floats(self).items():
            object.__setattr__(self, name, value)

    @property
    def environment(self) -> Environment:
        """What is known of ``env``: how it is stepped and its defaults."""
        from rlcompare.envs.gymnasium_env import UnsupportedEnvironment  # Gymnasium: once a config is checked

        try:
            entry = environment(self.env, self.adapter)
        except UnsupportedEnvironment as error:
            raise ConfigError("env", self.env, f"{', '.join(ENVIRONMENTS)}, or a registered Gymnasium "
                              "environment with Discrete actions and Discrete or Box observations "
                              f"({cut(str(error), 200)})") from None
        if entry.moves_vary and METHODS[self.algorithm].family == "policy gradient":
            raise ConfigError("algorithm", self.algorithm, "a value method or the random baseline: "
                              f"{self.env}'s legal moves change with the state, which only they mask")
        if not entry.tabular:
            raise ConfigError("env", self.env, f"an environment the tabular engine plays ({', '.join(ENVIRONMENTS)}, "
                              f"or Gymnasium's); {self.env} has image observations: train it with the deep engine")
        return entry

    @property
    def grid_bins(self) -> int | tuple[int, ...]:
        """``bins``, which creation fills in with the environment's default grid where it was None."""
        return self.environment.bins if self.bins is None else self.bins

    @property
    def step_limit(self) -> int:
        """``max_steps``, which creation fills in with the environment's default limit where it was None."""
        return self.environment.max_steps if self.max_steps is None else self.max_steps

    @property
    def name(self) -> str:
        """Short label, also the run directory's name in a study: ``q_learning-decay``, ``random``; a learner
        drawing its next action off its box says so: ``q_learning-decay-before_update``."""
        if self.algorithm == "random":
            return self.algorithm
        own_box = self.drawn_next == NEXT_ACTION_DEFAULTS.get(self.algorithm)
        return f"{self.algorithm}-{self.schedule}" + ("" if own_box else f"-{self.next_action}")

    @property
    def drawn_next(self) -> str | None:
        """When a one-step learner draws its next action: ``next_action``, or its box's (None for the others)."""
        return self.next_action or NEXT_ACTION_DEFAULTS.get(self.algorithm)

    @property
    def evaluation_rounds(self) -> int:
        return self.episodes // self.eval_every if self.eval_every else 0

    @property
    def progress_total(self) -> int:
        """What a run's ``progress`` callback counts to: episodes (each seed's, trained side by side)."""
        return self.episodes

    def stage_episodes(self) -> dict[str, int]:
        """Episodes completed when each stage's snapshot is taken (at least 1)."""
        return {name: max(1, round(share * self.episodes)) for name, share in self.stages}

    def to_dict(self) -> dict[str, Any]:
        data: dict[str, Any] = json.loads(json.dumps(dataclasses.asdict(self)))  # tuples as lists, as in config.json
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ExperimentConfig:
        """Build from a mapping, rejecting unknown keys by name."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(unknown[0], data[unknown[0]], f"one of {', '.join(sorted(known))}")
        return cls(**data)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, sort_keys=True)


@functools.cache
def field_docs(cls: type | None = None) -> dict[str, str]:
    """Each field of a dataclass (default :class:`ExperimentConfig`) and its docstring (the string under it in
    the class, or in the nearest base class that has one), as plain text on one line: what the command line's
    help and the documentation say of it."""
    docs: dict[str, str] = {}
    for klass in reversed((cls or ExperimentConfig).__mro__):
        if not dataclasses.is_dataclass(klass):
            continue
        definition = ast.parse(textwrap.dedent(inspect.getsource(klass))).body[0]
        body = definition.body if isinstance(definition, ast.ClassDef) else []
        for statement, following in itertools.pairwise(body):
            if (isinstance(statement, ast.AnnAssign) and isinstance(statement.target, ast.Name)
                    and isinstance(following, ast.Expr) and isinstance(following.value, ast.Constant)
                    and isinstance(following.value.value, str)):
                docs[statement.target.id] = _plain(following.value.value)
    return docs


def _plain(text: str) -> str:
    """reST on one line without its markup: ``x`` and :attr:`x` as x."""
    return " ".join(re.sub(r"(:\w+:)?`+([^`]+)`+", r"\2", text).split())


@functools.lru_cache(maxsize=4)
def _plain_seeds(seeds: tuple[Any, ...]) -> tuple[int, ...]:
    """Seeds as Python integers (a :class:`ValueError` for one that is not an integer); the configurations of a
    study share one tuple, read once however many seeds it holds."""
    return tuple(s if type(s) is int else _as_int(s) for s in seeds)


@functools.lru_cache(maxsize=4)
def _seeds_checked(seeds: tuple[int, ...]) -> tuple[bool, bool]:
    """Whether every seed is in [0, 2**63), and whether they are distinct (read once for a study's tuple)."""
    return all(0 <= s < 2**63 for s in seeds), len(set(seeds)) == len(seeds)


def _as_int(value: Any) -> int:
    if not is_integer(value):
        raise ValueError(value)
    return int(value)


def _as_floats(c: ExperimentConfig) -> dict[str, float]:
    """The number fields holding an integer, as floats (after validation, so that errors quote the value
    given)."""
    return {name: float(getattr(c, name)) for name in FLOAT_FIELDS if is_integer(getattr(c, name))}


def _check_choices(c: ExperimentConfig) -> None:
    require(c.algorithm in ALGORITHMS, "algorithm", c.algorithm, ", ".join(ALGORITHMS))
    require(c.schedule in SCHEDULES, "schedule", c.schedule, ", ".join(SCHEDULES))
    require(isinstance(c.env, str) and c.env != "", "env", c.env, ", ".join(ENVIRONMENTS)
            + ", or a registered Gymnasium environment id")
    require(c.features in FEATURES, "features", c.features, ", ".join(FEATURES))
    require(c.trace in TRACES, "trace", c.trace, ", ".join(TRACES))
    check_fields(c, {"adapter": FLAG, "truncation_as_terminal": FLAG})
    if c.algorithm in NEXT_ACTION_DEFAULTS:
        require(c.next_action in (None, BEFORE_UPDATE, AFTER_UPDATE), "next_action", c.next_action,
                f"{BEFORE_UPDATE}, {AFTER_UPDATE}, or none for {c.algorithm}'s own box")
    else:
        require(c.next_action is None, "next_action", c.next_action, f"none for {c.algorithm} (only "
                f"{', '.join(NEXT_ACTION_DEFAULTS)} choose when to draw the next action)")


def _check_numbers(c: ExperimentConfig) -> None:
    """The fields declared with their rules (once the environment's defaults are filled in), then
    ``target_epsilon``, ``hash_size``, ``eval_every`` and the seeds."""
    check_fields(c, field_rules(c))
    require(c.target_epsilon is None or UNIT.holds(c.target_epsilon), "target_epsilon", c.target_epsilon,
            f"none, or {UNIT.allowed}")
    for name, meaning in (("hash_size", "0: no hashing"), ("eval_every", "0: no evaluation")):
        rule = Integer(0, MAX_COUNT)
        require(rule.holds(getattr(c, name)), name, getattr(c, name), f"{rule.allowed} ({meaning})")
    require(len(c.seeds) >= 1, "seeds", c.seeds, "at least one seed")
    in_range, distinct = _seeds_checked(c.seeds)
    require(in_range, "seeds", c.seeds, "integers in [0, 2**63)")
    require(distinct, "seeds", c.seeds, "distinct integers")


def _check_stages(c: ExperimentConfig) -> None:
    names = [n for n, _ in c.stages]
    require(len(set(names)) == len(names) and all(names), "stages", c.stages, "distinct non-empty names")
    require(all(0 < f <= 1 for _, f in c.stages), "stages", c.stages, "shares of the episodes in (0, 1]")


def feature_count_of(c: ExperimentConfig) -> int:
    """How many features the configuration's layout has (compiled code: imported once a config is checked)."""
    from rlcompare.envs.features import feature_count

    return feature_count(c.environment, c.features, c.grid_bins, c.tilings, c.tiles, c.hash_size)


def _check_grid(c: ExperimentConfig) -> None:
    """Bins and bounds that fit the observations, and weights that fit in memory."""
    env = c.environment
    dims = env.observation_size
    per_dim = c.bins if isinstance(c.bins, tuple) else (c.bins,)
    require(all(COUNT.holds(b) for b in per_dim) and len(per_dim) in (1, dims) and len(per_dim) >= 1, "bins",
             c.bins, f"an integer >= 1, or {dims} of them (one per observation dimension of {c.env})")
    if env.n_states:
        return
    if c.bounds is None:
        unbounded = [d for d in range(dims) if not (math.isfinite(env.low[d]) and math.isfinite(env.high[d]))]
        require(not unbounded, "bounds", None, f"(low, high) for each of the {dims} observation dimensions of "
                 f"{c.env}: its observation box is unbounded in dimensions {unbounded}")
    else:
        require(len(c.bounds) == dims and all(math.isfinite(lo) and math.isfinite(hi) and lo < hi
                                               for lo, hi in c.bounds), "bounds", c.bounds,
                 f"{dims} pairs of finite numbers (low, high) with low < high, one per observation dimension")
    features = feature_count_of(c)
    per_seed = features * env.n_actions * (2 + len(c.stages)) * 8
    needed = per_seed * len(c.seeds)
    if needed > MAX_WEIGHT_BYTES and per_seed < MAX_WEIGHT_BYTES / 100:  # the seeds' number is what is too large
        raise ConfigError("seeds", len(c.seeds), f"at most {MAX_WEIGHT_BYTES // per_seed:,} seeds of {features:,} "
                          f"features x {env.n_actions} actions, whose weights and snapshots fit in "
                          f"{MAX_WEIGHT_BYTES / 2**30:g} GiB (they need {needed / 2**30:.1f} GiB)")
    require(needed <= MAX_WEIGHT_BYTES, "bins" if c.features == "grid" else "tiles", c.bins if c.features == "grid"
             else c.tiles, f"a layout whose {features:,} features x {env.n_actions} actions x {len(c.seeds)} seeds "
             f"fit in {MAX_WEIGHT_BYTES / 2**30:g} GiB with their snapshots (they need {needed / 2**30:.1f} GiB)")


def _check_tiles(c: ExperimentConfig) -> None:
    if c.features != "tiles" or c.environment.n_states:
        return
    from rlcompare.envs.features import make_features

    try:
        make_features(c.environment, c.features, c.grid_bins, c.tilings, c.tiles, c.hash_size, c.bounds)
    except ValueError as error:
        raise ConfigError("tiles", (c.tilings, c.tiles, c.hash_size),
                          f"a layout that fits the bounds ({error})") from None


_CHECKS = (_check_numbers, _check_stages, _check_grid, _check_tiles)
