"""Every margin a verdict reads, in one table kept as data (``margins.toml``), each with its reason, declared before
any run was read (``docs/why.md``, "Every margin, its reason and its power"); what the seeds can prove of each is
:mod:`rlcompare.stats.power`'s."""

from __future__ import annotations

from dataclasses import dataclass, fields
from importlib import resources

import tomllib


@dataclass(frozen=True)
class Margin:
    """A bound below which a difference counts as none (or, for a ratio, a band around the claimed factor)."""

    study: str
    bounds: str
    """What it bounds, as the report names it."""
    value: float
    unit: str
    reason: str


MARGINS_FILE = "margins.toml"
"""The table, as data beside this module: one ``[[margin]]`` entry each, in the fields of :class:`Margin`."""


def read_margins(text: str) -> dict[str, Margin]:
    """Every margin of ``text`` (a margins file), by ``"<study>: <what it bounds>"``; an entry with other fields, or
    a value not above 0, is a ``ValueError`` naming it."""
    table: dict[str, Margin] = {}
    for entry in tomllib.loads(text)["margin"]:
        if set(entry) != {f.name for f in fields(Margin)} or not float(entry["value"]) > 0:
            raise ValueError(f"{MARGINS_FILE}: a margin must give {', '.join(f.name for f in fields(Margin))}, its "
                             f"value above 0: {entry}")
        found = Margin(**{**entry, "value": float(entry["value"])})
        table[f"{found.study}: {found.bounds}"] = found
    return table


MARGINS = read_margins(resources.files(__package__).joinpath(MARGINS_FILE).read_text(encoding="utf-8"))
"""Every margin, by ``"<study>: <what it bounds>"``; the ratio's band is :data:`rlcompare.stats.claims.RATIO_FACTOR`
(checked by ``tests/unit/test_margins.py``)."""


def margin(study: str, bounds: str) -> float:
    return MARGINS[f"{study}: {bounds}"].value
