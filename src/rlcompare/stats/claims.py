"""A claim as a study states it, before any seed is read: the sentence and the comparison that tests it
(:mod:`rlcompare.stats.verdicts` judges it). Here, without numpy's statistics or scipy, so that a study's plan
can count its claims."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

RATIO_FACTOR = 1.25
""""About R times" means within ``[R / 1.25, R * 1.25]`` (the 80-125% band of bioequivalence)."""

Kind = Literal["direction", "ratio", "within", "level"]


@dataclass(frozen=True)
class Claim:
    """A sentence, and the comparison over paired seeds that tests it: configuration ``a`` against ``b`` on
    ``metric``, read seed by seed.

    ``kind`` says what is tested:

    - ``direction``: A minus B on the same seeds has the sign ``sign`` (Wilcoxon signed-rank);
    - ``ratio``: B over A is about ``value``, within ``[value / 1.25, value * 1.25]`` (TOST on per-seed log ratios);
    - ``within``: A minus B lies in ``bounds``, a margin on one side or both (two one-sided t tests);
    - ``level``: the mean of ``reads`` (``a`` or ``b``) lies on side ``sign`` of ``value`` (Wilcoxon signed-rank).

    ``floor``: the claim reads a greedy choice, and is undecidable where the choice lies below its noise floor
    (``floors`` of :func:`judge`, by configuration). ``about``: what the claim reads, in words (default: A - B).
    """

    text: str
    a: str
    b: str
    metric: str
    kind: Kind = "direction"
    sign: int = 1
    value: float = 0.0
    bounds: tuple[float, float] = (-math.inf, math.inf)
    reads: str = "a"
    floor: bool = False
    about: str = ""
