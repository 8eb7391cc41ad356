"""Findings first: a few generated sentences that answer "on- or off-policy here, and why".

They are read off the verdicts (the paper's claims, tested on paired seeds with Holm's correction) and, where a
``why`` study stands beside the paper's, off its decomposition of SARSA minus Q-Learning into the order of
choosing and updating, the target, and their interaction. Nothing here is written by hand but the grammar.
"""

from __future__ import annotations

from collections import Counter

import pandas as pd

from rlcompare.analysis.stats import CONTRADICTED, NO_DATA, NOT_RESOLVED, SUPPORTED, UNDECIDABLE
from rlcompare.analysis.tables import Claim

SCHEDULE_TEXT = {"constant": "ε constant", "decay": "ε decaying"}
RETURN_METRICS = {"behaviour_return": "while learning (ε-greedy return over training)",
                  "greedy_return": "with its final greedy policy"}


def _bare(label: str) -> str:
    return label.removesuffix(" (fragile)")


def answer(claims: list[Claim], verdicts: pd.DataFrame) -> list[str]:
    """Which method collects more reward, per schedule, on- against off-policy: the direction claims on the
    behaviour and greedy returns, with their estimates and labels."""
    sentences = []
    for claim, (_, row) in zip(claims, verdicts.iterrows(), strict=True):
        if claim.metric not in RETURN_METRICS or claim.kind != "direction":
            continue
        label = _bare(row["verdict"])
        where = f"With {SCHEDULE_TEXT[claim.schedule]}, {RETURN_METRICS[claim.metric]}"
        gap = f"SARSA - Q-Learning = {row['estimate']} (p (Holm) = {row['p (Holm)']:.2g})"
        if label == SUPPORTED:
            sentences.append(f"{where}, on-policy SARSA beats off-policy Q-Learning: {gap}.")
        elif label == CONTRADICTED:
            sentences.append(f"{where}, off-policy Q-Learning beats on-policy SARSA: {gap}.")
        else:
            sentences.append(f"{where}, neither is shown better ({label}): {gap}.")
    return sentences


def tally(verdicts: pd.DataFrame) -> str:
    """How the claims came out, with the family and the fragile ones."""
    counts = Counter(_bare(v) for v in verdicts["verdict"])
    parts = [f"{counts[label]} {label}" for label in (SUPPORTED, CONTRADICTED, NOT_RESOLVED, UNDECIDABLE, NO_DATA)
             if counts[label]]
    fragile = int(verdicts["fragile"].sum())
    return (f"Of the paper's {len(verdicts)} claims tested here: {', '.join(parts)}"
            + (f"; {fragile} of them fragile (the label changes with the convergence rule)." if fragile else "."))


def paper_findings(claims: list[Claim], verdicts: pd.DataFrame, why: list[str] | None) -> list[str]:
    """The report's opening: the answer, the tally of claims, and the why (or how to get it)."""
    cause = why or ["Why: not measured in this study. `rlcompare reproduce why` separates the on-policy target "
                    "from the order of choosing the next action and updating, which also differs between the "
                    "paper's two algorithms."]
    return [*answer(claims, verdicts), tally(verdicts), *cause]
