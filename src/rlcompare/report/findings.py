"""Findings first: a few generated sentences that answer "on- or off-policy here, and why".

They are read off the verdicts (the paper's claims, tested on paired seeds with Holm's correction) and, where a
``why`` study stands beside the paper's, off its decomposition of SARSA minus Q-Learning into the order of
choosing and updating, the target, and their interaction. Nothing here is written by hand but the grammar.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pandas as pd

from rlcompare.formatting import number
from rlcompare.stats.compare import compare_paired
from rlcompare.stats.intervals import Estimate
from rlcompare.stats.significance import CONTRADICTED, NO_DATA, NOT_RESOLVED, SUPPORTED, UNDECIDABLE
from rlcompare.stats.verdicts import Claim

SCHEDULE_TEXT = {"constant": "ε constant", "decay": "ε decaying"}
RETURN_METRICS = {"behaviour_return": "while learning (ε-greedy return over training)",
                  "greedy_return": "with its final greedy policy"}


SCHEDULE_WORDS = {"constant": "With ε constant", "decay": "With ε decaying"}
BEHAVIOUR_AND_GREEDY = (
    "The two returns answer different questions: the return while learning counts every exploring move the agent "
    "makes (ε-greedy), the greedy return only what its final policy does without exploring. An on-policy method "
    "learns the values of the policy it follows, exploration included, so it can lead while learning and not "
    "after.")


def _bare(label: str) -> str:
    return label.removesuffix(" (fragile)")


def amount(estimate: Estimate, signed: bool = False) -> str:
    """``8.7 (95% interval 1.9 to 14.5)``; ``signed``: ``+8.7 ...``."""
    value = ("+" if signed and estimate.value > 0 else "") + number(estimate.value)
    if np.isnan(estimate.low):
        return f"{value} (no interval: too few seeds)"
    return f"{value} (95% interval {number(estimate.low)} to {number(estimate.high)})"


def _words(value: float) -> str:
    return f"{number(abs(value))} {'more' if value >= 0 else 'less'}"


def gap_and_interval(estimate: Estimate) -> tuple[str, str]:
    """SARSA - Q-Learning in words, ``("8.7 more", "95% interval 1.9 to 14.5")``; ``"3.1 less"``; where the
    interval crosses 0, ``"95% interval 20 less to 88 more"``."""
    if np.isnan(estimate.low):
        return _words(estimate.value), "no interval: too few seeds"
    if estimate.low < 0 < estimate.high:
        return _words(estimate.value), f"95% interval {_words(estimate.low)} to {_words(estimate.high)}"
    low, high = sorted((abs(estimate.low), abs(estimate.high)))
    return _words(estimate.value), f"95% interval {number(low)} to {number(high)}"


def more_or_less(estimate: Estimate) -> str:
    """``8.7 more (95% interval 1.9 to 14.5)``: :func:`gap_and_interval` in one phrase."""
    gap, interval = gap_and_interval(estimate)
    return f"{gap} ({interval})"


def _verdict_words(claim: Claim, label: str, claims: int) -> str:
    if label == NO_DATA:
        return "no data to test"
    if claim.kind == "within":
        what = f"the same within ±{number(claim.bounds[1])}"
        if label == SUPPORTED:
            return f"{what}: supported"
        return f"not {what}: contradicted" if label == CONTRADICTED else f"whether they are {what} is {label}"
    if label in (SUPPORTED, CONTRADICTED):
        return f"{'SARSA' if (label == SUPPORTED) == (claim.sign > 0) else 'Q-Learning'} better, with the " \
               f"{claims} claims corrected together"
    return f"{label} once the {claims} claims are corrected together"


def opening(claims: list[Claim], verdicts: pd.DataFrame, metrics: dict[str, pd.DataFrame]) -> list[str]:
    """The answer in plain words, a sentence per schedule: how much more (or less) SARSA collects than Q-Learning
    per episode while learning and with its final greedy policy, on paired seeds, with each claim's label."""
    labels: dict[tuple[str, str], tuple[Claim, str]] = {}
    for claim, (_, row) in zip(claims, verdicts.iterrows(), strict=True):
        key = (claim.a, claim.metric)
        if claim.metric in RETURN_METRICS and (key not in labels or claim.kind == "direction"):
            labels[key] = (claim, _bare(row["verdict"]))  # a direction states the sentence's "more" or "less"
    sentences = []
    for schedule, words in SCHEDULE_WORDS.items():
        sarsa, q = metrics.get(f"sarsa-{schedule}"), metrics.get(f"q_learning-{schedule}")
        if sarsa is None or q is None or not all((f"sarsa-{schedule}", m) in labels for m in RETURN_METRICS):
            continue
        gap = {m: gap_and_interval(compare_paired(sarsa[m].to_numpy(), q[m].to_numpy(), improvement=False)
                                   .difference) for m in RETURN_METRICS}
        said = {m: _verdict_words(*labels[(f"sarsa-{schedule}", m)], len(claims)) for m in RETURN_METRICS}
        learning, greedy = gap["behaviour_return"], gap["greedy_return"]
        sentences.append(
            f"{words}, SARSA collects {learning[0]} reward per episode than Q-Learning while it learns "
            f"({learning[1]}; {said['behaviour_return']}); its final greedy policy earns {greedy[0]} ({greedy[1]}; "
            f"{said['greedy_return']}). {len(sarsa)} paired seeds.")
    return sentences


def tally(verdicts: pd.DataFrame) -> str:
    """How the claims came out, with the family and the fragile ones."""
    counts = Counter(_bare(v) for v in verdicts["verdict"])
    parts = [f"{counts[label]} {label}" for label in (SUPPORTED, CONTRADICTED, NOT_RESOLVED, UNDECIDABLE, NO_DATA)
             if counts[label]]
    fragile = int(verdicts["fragile"].sum())
    return (f"Of the paper's {len(verdicts)} claims tested here: {', '.join(parts)}"
            + (f"; {fragile} of them fragile (another convergence rule decides it the other way)." if fragile else "."))


def paper_findings(claims: list[Claim], verdicts: pd.DataFrame, metrics: dict[str, pd.DataFrame],
                   why: list[str] | None) -> list[str]:
    """The report's opening: the answer in plain words, the tally of claims, and the why (or how to get it)."""
    cause = why or ["Why: not measured in this study. `rlcompare reproduce why` separates the on-policy target "
                    "from the order of choosing the next action and updating, which also differs between the "
                    "paper's two algorithms."]
    return [*opening(claims, verdicts, metrics), tally(verdicts), *cause]
