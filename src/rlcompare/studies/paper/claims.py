"""The paper's claims, each a sentence of it and the comparison over paired seeds that tests it, with its margin
declared before any run is read (``docs/why.md``, "Verdicts")."""

from __future__ import annotations

import dataclasses
from collections.abc import Collection
from typing import Any

from rlcompare.stats.claims import Claim
from rlcompare.studies.margins import margin

NAMES = ("SARSA", "Q-Learning")
"""What the verdicts call A and B: every claim of the paper sets SARSA against Q-Learning on one schedule."""


def paper_claim(text: str, schedule: str, metric: str, **how: Any) -> Claim:
    """A claim of the paper: SARSA (A) against Q-Learning (B) with ε ``schedule``."""
    return Claim(text, f"sarsa-{schedule}", f"q_learning-{schedule}", metric, **how)


def within(share: float) -> tuple[float, float]:
    return (-share, share)


CLAIMS = (
    paper_claim("With ε decaying, Q-Learning takes about 4 times as long as SARSA to converge (Table I: 41.5 vs "
                "10.7)", "decay", "convergence_episode", kind="ratio", value=41.5 / 10.7),
    paper_claim("With ε decaying, SARSA converges faster than Q-Learning", "decay", "convergence_episode", sign=-1),
    paper_claim("With ε constant, both converge within a similar time frame (Table I: 13.8 vs 11.5): within 10% of "
                "training", "constant", "convergence_episode", kind="within",
                bounds=within(margin("paper", "a similar time frame (convergence)"))),
    paper_claim("With ε constant, SARSA has the higher mean cumulative reward (Table II: -176 vs -262)", "constant",
                "behaviour_return", sign=1),
    paper_claim("With ε constant, SARSA finds a better solution: its greedy policy returns more", "constant",
                "greedy_return", sign=1),
    paper_claim("With ε decaying, SARSA has the higher mean cumulative reward (Table II: -174 vs -191)", "decay",
                "behaviour_return", sign=1),
    paper_claim("With ε decaying, both find the same solution (-174 to -191): greedy returns within 20", "decay",
                "greedy_return", kind="within", bounds=within(margin("paper", "the same solution (greedy return)"))),
    paper_claim("With ε decaying, SARSA finds a better solution: its greedy policy returns more (the constant-ε "
                "claim, asked of decaying ε)", "decay", "greedy_return", sign=1),
    paper_claim("With ε constant, SARSA accelerates backwards first: push left from most start states", "constant",
                "first_action_left", kind="level", sign=1, value=0.5, reads="a", floor=True),
    paper_claim("With ε constant, Q-Learning accelerates forward first: push left from few start states", "constant",
                "first_action_left", kind="level", sign=-1, value=0.5, reads="b", floor=True),
)
"""The paper's claims, with their margins declared before any run is read (``docs/why.md``, "Verdicts")."""


def claims_asked(runs: Collection[str], position_velocity: bool) -> list[Claim]:
    """The claims whose two configurations are among ``runs``; the first action's claims only where the
    observation is Mountain Car's position and velocity."""
    return [c for c in CLAIMS if {c.a, c.b} <= set(runs) and (position_velocity or c.metric != "first_action_left")]


def scaled(claim: Claim, episodes: int) -> Claim:
    """A "same time frame" margin given as a share of training, in episodes."""
    if claim.kind == "within" and claim.metric == "convergence_episode":
        return dataclasses.replace(claim, bounds=(claim.bounds[0] * episodes, claim.bounds[1] * episodes))
    return claim
