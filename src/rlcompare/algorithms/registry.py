"""Every method rlcompare runs, once: its name, label, family, book section, kernel code and the configuration
fields it reads. The configuration, the command line, the kernels' settings, the benchmark, the tables and the
figures read this registry; adding a method is its update function and one entry here.
"""

from __future__ import annotations

from dataclasses import dataclass

RANDOM, Q_LEARNING, SARSA, EXPECTED_SARSA, DOUBLE_Q, N_STEP_SARSA, SARSA_LAMBDA, Q_LAMBDA, REINFORCE = range(9)
"""The kernels' codes of the episode loops and targets."""
BEFORE_UPDATE, AFTER_UPDATE = "before_update", "after_update"


@dataclass(frozen=True)
class Method:
    """One method as the rest of rlcompare sees it."""

    name: str
    label: str
    family: str
    """``baseline``, ``one-step``, ``n-step``, ``traces`` or ``policy gradient``."""
    book: str
    """Where it is defined: the paper's algorithm or the book's section."""
    code: int
    reads: tuple[str, ...] = ()
    """Configuration fields it reads beyond the common ones (α, γ, ε and its schedule, the environment)."""
    next_action: str | None = None
    """One-step learners: when their box draws A', before or after updating Q(S, A)."""
    discount_gradient: bool = True
    """REINFORCE: whether its step carries γ^t."""
    baseline: bool = False
    """REINFORCE: whether it learns a state-value baseline."""
    color: str | None = None

    @property
    def one_step(self) -> bool:
        """A one-step learner: it may draw its next action before or after its update."""
        return self.next_action is not None


METHODS = {m.name: m for m in (
    Method("random", "random", "baseline", "the paper's random-action baseline", RANDOM, color="#7f7f7f"),
    Method("q_learning", "Q-Learning", "one-step", "the paper's Algorithm 1, Sutton and Barto 6.5", Q_LEARNING,
           next_action=AFTER_UPDATE, color="#e07b00"),
    Method("sarsa", "SARSA", "one-step", "the paper's Algorithm 2, Sutton and Barto 6.4", SARSA,
           next_action=BEFORE_UPDATE, color="#2a9d8f"),
    Method("expected_sarsa", "Expected SARSA", "one-step", "Sutton and Barto 6.6", EXPECTED_SARSA,
           reads=("target_epsilon",), next_action=AFTER_UPDATE),
    Method("double_q_learning", "Double Q-Learning", "one-step", "Sutton and Barto 6.7", DOUBLE_Q,
           next_action=AFTER_UPDATE),
    Method("n_step_sarsa", "n-step SARSA", "n-step", "Sutton and Barto 7.2", N_STEP_SARSA, reads=("n",)),
    Method("sarsa_lambda", "SARSA(λ)", "traces", "Sutton and Barto 12.7", SARSA_LAMBDA, reads=("lam", "trace")),
    Method("q_lambda", "Q(λ)", "traces", "Watkins's Q(λ), Sutton and Barto 12.10", Q_LAMBDA, reads=("lam", "trace")),
    Method("reinforce", "REINFORCE", "policy gradient", "the paper's Algorithm 3, as written (no γ^t)", REINFORCE,
           discount_gradient=False),
    Method("reinforce_book", "REINFORCE (book)", "policy gradient", "Sutton and Barto 13.3 (with γ^t)", REINFORCE),
    Method("reinforce_baseline", "REINFORCE with baseline", "policy gradient", "Sutton and Barto 13.4", REINFORCE,
           reads=("baseline_alpha",), baseline=True),
)}
"""Every method, by the name a configuration gives."""


def method(name: str) -> Method:
    return METHODS[name]


def label(name: str) -> str:
    """The method's name for tables and figures; the name itself for one rlcompare does not know."""
    return METHODS[name].label if name in METHODS else name
