"""Each claim sentence a report opens with is generated from the verdict it states: change a claim's label (or
its seeds' numbers) and the sentence changes with it, in the paper's answer and in the MinAtar study's; no
sentence is written by hand next to a number computed elsewhere."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rlcompare.report.findings import _verdict_words, gap_and_interval, opening, tally
from rlcompare.stats.compare import Judged, compare_paired
from rlcompare.stats.significance import VERDICTS
from rlcompare.studies.paper.claims import paper_claim, within

CLAIMS = [paper_claim("a", "constant", "behaviour_return"), paper_claim("b", "constant", "greedy_return"),
          paper_claim("c", "decay", "behaviour_return"),
          paper_claim("d", "decay", "greedy_return", kind="within", bounds=within(20))]


def _metrics(shift: float = 5.0) -> dict[str, pd.DataFrame]:
    rng = np.random.default_rng(0)
    return {name: pd.DataFrame({"behaviour_return": rng.normal(s, 1, 8), "greedy_return": rng.normal(s / 2, 5, 8)})
            for name, s in (("sarsa-constant", shift), ("q_learning-constant", 0), ("sarsa-decay", -shift),
                            ("q_learning-decay", 0))}


def _verdicts(labels: list[str]) -> pd.DataFrame:
    return pd.DataFrame({"verdict": labels, "fragile": [label.endswith("(fragile)") for label in labels]})


@pytest.mark.parametrize("row", range(len(CLAIMS)))
@pytest.mark.parametrize("label", VERDICTS)
def test_the_papers_answer_states_each_claims_own_label(row: int, label: str) -> None:
    labels = ["supported"] * len(CLAIMS)
    labels[row] = label
    sentences = opening(CLAIMS, _verdicts(labels), _metrics())
    sentence = sentences[0 if CLAIMS[row].a == "sarsa-constant" else 1]
    assert _verdict_words(CLAIMS[row], label, len(CLAIMS)) in sentence
    fragile = labels.copy()
    fragile[row] = f"{label} (fragile)"  # the mark changes the tally, not the claim's words
    assert opening(CLAIMS, _verdicts(fragile), _metrics()) == sentences
    assert tally(_verdicts(fragile)) != tally(_verdicts(labels))


def test_the_papers_answer_states_the_seeds_own_numbers() -> None:
    for shift in (5.0, -2.0):
        metrics = _metrics(shift)
        sentence = opening(CLAIMS, _verdicts(["supported"] * 4), metrics)[0]
        gap = compare_paired(metrics["sarsa-constant"]["behaviour_return"].to_numpy(),
                             metrics["q_learning-constant"]["behaviour_return"].to_numpy(), improvement=False)
        words, interval = gap_and_interval(gap.difference)
        assert f"SARSA collects {words} reward per episode than Q-Learning while it learns ({interval};" in sentence
        assert f"{len(metrics['sarsa-constant'])} paired seeds." in sentence


@pytest.mark.parametrize("label", ["on-policy better", "off-policy better", "equivalent (within ±1)", "not resolved",
                                   "no data"])
def test_the_minatar_answer_states_each_games_own_label(label: str) -> None:
    pytest.importorskip("jax")
    from rlcompare.studies.paired_plan import OVERALL
    from rlcompare.studies.paired_report import answer

    rng = np.random.default_rng(1)
    paired = compare_paired(rng.normal(3, 1, 8), rng.normal(2, 1, 8), 1.0)
    compared = {"Breakout": Judged(paired, 0.01, 0.5, label, 1.0),
                "Asterix": Judged(paired, 0.01, 0.5, "not resolved", 1.0),
                OVERALL: Judged(paired, 0.02, 0.5, label, 0.1)}
    games, overall = answer(compared, 8)
    words, interval = gap_and_interval(paired.difference)
    assert f"on Breakout {words} ({interval}; {label})" in games
    assert f"on Asterix {words} ({interval}; not resolved)" in games
    assert overall.endswith(f"({interval}; {label}).")
