"""The paired study's configuration and design: what it compares, what a plan of it trains, and the tests its
report makes (:func:`paired_plan`, ``reproduce STUDY --plan``). Apart from :mod:`rlcompare.studies.paired`, which
trains and reads its runs, so that a plan loads neither pandas nor the reports' figures: only the deep engine's
configurations, which check each training's settings.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from rlcompare.deep import float64
from rlcompare.deep.config import DeepConfig
from rlcompare.deep.envs import jax_env
from rlcompare.deep.methods import DEEP_METHODS
from rlcompare.deep.rollout import evaluate
from rlcompare.stats.design import GATE, SIGNED_RANK
from rlcompare.studies.plans import Question, StudyPlan, deep_training, episodic
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.validation import ConfigError

if TYPE_CHECKING:
    import jax

    from rlcompare.stats.compare import Paired
    from rlcompare.tabular.results import Results

PAIR = ("pqn_sarsa_lambda", "pqn_q_lambda")
"""The on-policy and the off-policy target in one engine: the only switch is the bootstrap."""
OVERALL = "overall (normalised)"
"""The comparison of each seed's normalised score averaged over the environments."""
OVERALL_STATISTICS = ("mean", "iqm")
"""How each seed's normalised scores are taken over the environments for :data:`OVERALL`
(:func:`rlcompare.studies.paired.over_environments`)."""
VMAP_WIDTH = 10
"""Seeds trained side by side in one program, at most."""
RANDOM_EPISODES = 200
"""Episodes of the uniformly random policy per environment, in the port: the floor (0) of the normalised scores."""


class Key(NamedTuple):
    """What one paired comparison compares: on an environment (or :data:`OVERALL`), in an engine, one metric."""

    env: str
    engine: str = "network"
    metric: str = "greedy_return"


def no_others(env: str, beside: Mapping[str, Results]) -> dict[Key, Paired]:
    return {}


@dataclass(frozen=True)
class PairedStudy:
    """A configuration of the study: its environments, margins, and what its tables and figures call them."""

    name: str
    """``rlcompare reproduce NAME``: the owner of its directory and the prefix of its tables."""
    envs: tuple[str, ...]
    """Every environment it can run, in the order its report shows them."""
    margins: Mapping[str, float]
    """Per environment, the difference of mean return that counts as none, declared before any run
    (:mod:`rlcompare.studies.margins`)."""
    columns: Callable[[Key], dict[str, str]]
    """The verdict table's first columns, naming what a row compares."""
    label: Callable[[str], str]
    """A method's name in the aggregates' tables and figures."""
    method_order: tuple[str, ...]
    """The order of the methods in the aggregates."""
    tasks: str
    """What rliable's captions call the environments."""
    digits: int = 2
    """Digits of the difference in the verdict table."""
    metrics: tuple[str, ...] = ("greedy_return",)
    """The columns of :func:`per_seed` compared on the pair, in each environment."""
    overall_margin: float | None = None
    """With a margin, the pair is compared over two or more environments too (:data:`OVERALL`)."""
    prefix: str = ""
    """The aggregates' figures' file names begin with it."""
    others: Callable[[str, Mapping[str, Results]], dict[Key, Paired]] = no_others
    """The comparisons on an environment of another engine's runs beside the networks, after the pair's (the deep
    study's tabular pair)."""
    others_per_env: int = 0
    """How many comparisons ``others`` makes on an environment whose runs beside are all there."""
    references: Mapping[str, float] = field(default_factory=dict)
    """Per environment, a reference score with a published source (the MinAtar paper's DQN). Where given, the
    environment's margin is a share of the range from the random policy's return to it, normalised scores run from
    0 (random) to 1 (the reference), and the pair is compared only where a method has learnt it (:meth:`learnt`)."""
    learnt_share: float = 0.0
    """The share of that range a method's final return must beat the random policy's by to have learnt."""
    floors: Mapping[str, float] = field(default_factory=dict)
    """Per environment, a published random policy's score (Atari's table), the floor of its normalised scores in
    place of the random policy played in the port (:func:`random_floor`)."""
    overall_statistic: str = "mean"
    """How :data:`OVERALL` takes each seed's normalised scores over the environments
    (:func:`rlcompare.studies.paired.over_environments`): their ``mean``, or their ``iqm``, which one environment's
    outlying score cannot move."""
    frames_per_step: int = 0
    """Frames an environment step plays (the Atari 2600's frame skip, 4): where set, curves are drawn against frames,
    as the protocol counts its budgets (Machado et al. 2018)."""

    def floor_of(self, env: str) -> float:
        """The random policy's score on ``env``: published, or played in the port."""
        return self.floors[env] if env in self.floors else random_floor(env)

    def margin_of(self, env: str, floor: float | None) -> float:
        """The environment's margin in its own units: declared, or a share of its random-to-reference range."""
        if env in self.references and floor is not None:
            return self.margins[env] * (self.references[env] - floor)
        return self.margins[env]

    def family(self, plan: Plan) -> int:
        """The tests :func:`~rlcompare.studies.paired_report.judged` makes on ``plan``'s runs, all trained and
        learnt: on each environment the pair's metrics and the comparisons beside; over two or more environments the
        pair overall, where a margin is declared for it. Each is a direction test and an equivalence test."""
        pair = len(self.metrics) if set(PAIR) <= set(plan.methods) else 0
        beside = self.others_per_env if plan.beside else 0
        overall = int(self.overall_margin is not None and pair > 0 and len(plan.envs) > 1)
        return 2 * (len(plan.envs) * (pair + beside) + overall)

    def learnt(self, env: str, finals: np.ndarray, floor: float) -> bool:
        """Whether ``finals`` (each seed's final greedy return) show the environment learnt at this budget
        (:func:`~rlcompare.stats.significance.has_learnt`); True where no reference is declared."""
        from rlcompare.stats.significance import has_learnt  # scipy's statistics, where a number needs them

        if env not in self.references:
            return True
        return has_learnt(finals, floor, self.learnt_share * (self.references[env] - floor))


@dataclass(frozen=True)
class Plan:
    """What a configuration of the study trains: each method on each environment on the same seeds, and how long;
    and, trained first, another engine's configurations beside the networks (the deep study's tabular pair)."""

    seeds: tuple[int, ...]
    methods: tuple[str, ...]
    envs: dict[str, str]
    """Each environment by the name its runs carry (``{method}-{name}``)."""
    steps: int | None
    """Environment steps of every training in place of each preset's (None: the presets')."""
    workers: int
    """Trainings at once on this machine (each one's results depend on its configuration alone)."""
    eval_rounds: int = DeepConfig.eval_rounds
    """Greedy evaluations over each training."""
    eval_episodes: int = DeepConfig.eval_episodes
    vmap_width: int = VMAP_WIDTH
    """Seeds trained side by side, at most: a seed's numbers depend on it (:mod:`rlcompare.deep.config`)."""
    beside: dict[str, ExperimentConfig] = field(default_factory=dict)
    """The other engine's configurations, by run name."""

    def steps_text(self) -> str:
        """The steps each training runs (whole batches), and the number given where that is another:
        ``32,768 steps (40,960 given; whole batches)``."""
        trained = sorted({config.steps_trained for config in self.configs().values()})
        text = " to ".join(f"{steps:,}" for steps in dict.fromkeys((trained[0], trained[-1]))) + " steps"
        return text + (f" ({self.steps:,} given; whole batches)" if self.steps is not None and trained != [self.steps]
                       else "")

    def configs(self) -> dict[str, DeepConfig]:
        """Each method on each environment with its preset for it."""
        overrides = {} if self.steps is None else {"total_steps": self.steps}
        return {f"{method}-{name}": DeepConfig(algorithm=method, env=env, seeds=self.seeds, hyperparameters=overrides,
                                               vmap_width=min(len(self.seeds), self.vmap_width),
                                               eval_rounds=self.eval_rounds, eval_episodes=self.eval_episodes)
                for name, env in self.envs.items() for method in self.methods}


def paired_plan(study: PairedStudy, plan: Plan, unit: str = "environment steps", plumbing: str = "") -> StudyPlan:
    """What ``plan`` trains (each training's steps as it runs them: whole batches) and the tests of its report:
    the pair, one family under Holm's correction, and where the study has references the learning gate on each
    method, not corrected."""
    seeds = len(plan.seeds)
    trainings = (*episodic(plan.beside), *(deep_training(name, c, unit) for name, c in plan.configs().items()))
    questions = []
    family = study.family(plan)
    if family:
        on, off = (study.label(method) for method in PAIR)
        comparisons = "one comparison, a direction" if family == 2 else f"{family // 2} comparisons, each a direction"
        questions.append(Question(f"{on} against {off} ({comparisons} and an equivalence test)", SIGNED_RANK, seeds,
                                  family))
    if study.references:
        questions.append(Question("whether each method has learnt each game (above the random policy, one-sided)",
                                  GATE, seeds))
    return StudyPlan(trainings, tuple(questions), plumbing, workers=plan.workers)


def checked(plan: Plan) -> Plan:
    """``plan``, its configurations built once to check them; a method's ``total_steps`` refused is named as the
    study's ``steps`` option, the one its user gave."""
    try:
        plan.configs()
    except ConfigError as error:
        given_as_steps = error.field_name.removeprefix("hyperparameters.") == "total_steps"
        raise ConfigError("steps" if given_as_steps else error.field_name, error.value,
                          error.allowed) from None
    return plan


def random_returns(env_name: str, episodes: int = RANDOM_EPISODES, seed: int = 0) -> np.ndarray:
    """Returns of the uniformly random policy in the port (``evaluate`` at ε = 1), from ``jax.random.key(seed)``.
    JAX is imported here, after :mod:`rlcompare.deep` has said how to install it where it is missing."""
    import jax
    import jax.numpy as jnp

    env = jax_env(env_name)

    def no_op(params: None, observations: jax.Array, legal: jax.Array | None = None) -> jax.Array:
        return jnp.zeros(observations.shape[0], jnp.int32)

    @float64
    def play() -> np.ndarray:
        return np.asarray(jax.jit(lambda key: evaluate(env, no_op, None, key, episodes, epsilon=1.0)[0])(
            jax.random.key(seed)))

    return play()


@functools.cache
def random_floor(env_name: str) -> float:
    """The mean of :func:`random_returns`, once per process."""
    return float(random_returns(env_name).mean())


def short_label(method: str) -> str:
    """``SARSA(λ)`` for ``SARSA(λ), network``, where every method has a network."""
    return DEEP_METHODS[method].label.removesuffix(", network")
