"""Every method rlcompare runs, once: its name, label, family, book section, rule and update, and the
configuration fields it reads. The configuration, the command line, the engine, the benchmark, the tables and
the figures read this registry; adding a method is its rule and update function and one entry here.

A method's compiled parts are named here (``td:QLearning``: the rule in :mod:`rlcompare.algorithms.td`) and
imported when the engine first asks for them, so that reading the registry (the command line's help, a
configuration's checks) compiles and imports nothing.
"""

from __future__ import annotations

import importlib
import typing
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

BEFORE_UPDATE, AFTER_UPDATE = "before_update", "after_update"
FAMILIES = ("baseline", "one-step", "n-step", "traces", "policy gradient")
"""Each family has one episode loop in the engine."""


def compiled_part(where: str) -> Any:
    """The compiled part at ``module:name`` of :mod:`rlcompare.algorithms`, imported now."""
    module, _, name = where.partition(":")
    return getattr(importlib.import_module(f"rlcompare.algorithms.{module}"), name)


@dataclass(frozen=True)
class Method:
    """One method as the rest of rlcompare sees it."""

    name: str
    label: str
    family: str
    """One of :data:`FAMILIES`."""
    book: str
    """Where it is defined: the paper's algorithm or the book's section."""
    rule_at: str
    """Where its rule is (``module:name`` in :mod:`rlcompare.algorithms`): a named tuple of what the method reads
    beyond α, γ and ε, whose type picks the compiled code (:attr:`rule`)."""
    update_at: str = ""
    """One-step methods: where ``update(rule, w, w2, t, rates, rng, q_next, scratch)`` of ``q(S, A)`` for one
    :class:`~rlcompare.algorithms.td.Transition` ``t`` at :class:`~rlcompare.algorithms.td.Rates` (α, γ, ε) is."""
    values_at: str = ""
    """Where ``values(rule, w, w2, s, out, scratch)`` is: what the behaviour is ε-greedy in and the greedy policy
    greedy in, when it is not ``q`` (Double Q-Learning's ``Q1 + Q2``)."""
    snapshot_at: str = ""
    """Where ``snapshot(rule, w, w2, out)`` is: it writes the weights a snapshot keeps into ``out``, when they are
    not ``w``."""
    reads: tuple[str, ...] = ()
    """Configuration fields it reads beyond the common ones (α, γ, ε and its schedule, the environment)."""
    next_action: str | None = None
    """One-step learners: when their box draws A', before or after updating Q(S, A)."""
    target_takes_next_action: bool = False
    """One-step learners whose target values the A' the behaviour takes (SARSA): A' is drawn before the update
    whatever the order, and, drawing after it, the behaviour's A' is drawn again once Q(S, A) has changed."""
    discount_gradient: bool = True
    """REINFORCE: whether its step carries γ^t."""
    baseline: bool = False
    """REINFORCE: whether it learns a state-value baseline."""
    cuts_traces: bool = False
    """Watkins's Q(λ): every trace is cut after an exploratory (non-greedy) action."""
    color: str | None = None

    @property
    def rule(self) -> type[tuple[Any, ...]]:
        rule: type[tuple[Any, ...]] = compiled_part(self.rule_at)
        return rule

    @property
    def update(self) -> Callable[..., Any] | None:
        return compiled_part(self.update_at) if self.update_at else None

    @property
    def values(self) -> Callable[..., Any] | None:
        return compiled_part(self.values_at) if self.values_at else None

    @property
    def snapshot(self) -> Callable[..., Any] | None:
        return compiled_part(self.snapshot_at) if self.snapshot_at else None

    @property
    def one_step(self) -> bool:
        """A one-step learner: it may draw its next action before or after its update."""
        return self.next_action is not None


METHODS = {m.name: m for m in (
    Method("random", "random", "baseline", "the paper's random-action baseline", "policies:RandomActions",
           color="#7f7f7f"),
    Method("q_learning", "Q-Learning", "one-step", "the paper's Algorithm 1, Sutton and Barto 6.5",
           "td:QLearning", "td:q_learning_update", next_action=AFTER_UPDATE, color="#e07b00"),
    Method("sarsa", "SARSA", "one-step", "the paper's Algorithm 2, Sutton and Barto 6.4", "td:Sarsa",
           "td:sarsa_update", next_action=BEFORE_UPDATE, target_takes_next_action=True, color="#2a9d8f"),
    Method("expected_sarsa", "Expected SARSA", "one-step", "Sutton and Barto 6.6", "td:ExpectedSarsa",
           "td:expected_sarsa_update", reads=("target_epsilon",), next_action=AFTER_UPDATE),
    Method("double_q_learning", "Double Q-Learning", "one-step", "Sutton and Barto 6.7", "td:DoubleQLearning",
           "td:double_q_update", values_at="td:double_q_values", snapshot_at="td:mean_of_tables",
           next_action=AFTER_UPDATE),
    Method("double_expected_sarsa", "Double Expected SARSA", "one-step", "Sutton and Barto, Exercise 6.13",
           "td:DoubleExpectedSarsa", "td:double_expected_sarsa_update", values_at="td:double_q_values",
           snapshot_at="td:mean_of_tables", reads=("target_epsilon",), next_action=AFTER_UPDATE),
    Method("n_step_sarsa", "n-step SARSA", "n-step", "Sutton and Barto 7.2", "nstep:NStepSarsa", reads=("n",)),
    Method("sarsa_lambda", "SARSA(λ)", "traces", "Sutton and Barto 12.7", "traces:SarsaLambda",
           reads=("lam", "trace")),
    Method("q_lambda", "Q(λ)", "traces", "Watkins's Q(λ), Sutton and Barto 12.10", "traces:QLambda",
           reads=("lam", "trace"), cuts_traces=True),
    Method("reinforce", "REINFORCE", "policy gradient", "the paper's Algorithm 3, as written (no γ^t)",
           "reinforce:Reinforce", discount_gradient=False),
    Method("reinforce_book", "REINFORCE (book)", "policy gradient", "Sutton and Barto 13.3 (with γ^t)",
           "reinforce:Reinforce"),
    Method("reinforce_baseline", "REINFORCE with baseline", "policy gradient", "Sutton and Barto 13.4",
           "reinforce:Reinforce", reads=("baseline_alpha",), baseline=True),
)}
"""Every method, by the name a configuration gives."""


def method(name: str) -> Method:
    return METHODS[name]


DERIVED: dict[str, Callable[[Any, Method], Any]] = {
    "draw_before": lambda config, m: (config.next_action or m.next_action) == BEFORE_UPDATE,
    "replacing": lambda config, m: config.trace == "replacing",
    "target_epsilon": lambda config, m: -1.0 if config.target_epsilon is None else float(config.target_epsilon),
    "discount_gradient": lambda config, m: m.discount_gradient,
    "baseline_alpha": lambda config, m: float(config.baseline_alpha) if m.baseline else 0.0,
    "n_actions": lambda config, m: int(config.environment.n_actions),
}
"""Rule fields that are not a configuration field of the same name, and how a configuration gives them."""


def rule_for(config: Any) -> tuple[Any, ...]:
    """The configured method's rule: each field of its named tuple read from the configuration's field of the
    same name (as the tuple's type), or derived (:data:`DERIVED`). A new method's rule needs nothing here unless
    a field of it is neither."""
    chosen = METHODS[config.algorithm]
    fields = typing.get_type_hints(chosen.rule)  # a named tuple's fields, in order, with their types
    return chosen.rule(**{name: DERIVED[name](config, chosen) if name in DERIVED else kind(getattr(config, name))
                          for name, kind in fields.items()})


def label(name: str) -> str:
    """The method's name for tables and figures; the name itself for one rlcompare does not know."""
    return METHODS[name].label if name in METHODS else name
