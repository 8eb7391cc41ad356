"""How rlcompare writes a number or a value in words: one formatter for tables, notes, sentences and errors.

A number reads as a person writes it: thousands separated, about three significant digits, trailing zeros
dropped and never an exponent (``2,490``, ``-176``, ``8.68``, ``0.0012``). A value quoted in an error message is
cut to one short line however large it is.
"""

from __future__ import annotations

import math
from typing import Any

NO_DATA = "no data"
"""What a table or a sentence shows where there is no number."""
MAX_QUOTE = 80
"""Characters of a value that a message quotes at the most."""


def number(value: float | None, digits: int = 3) -> str:
    """``value`` with about ``digits`` significant digits, thousands separated, never an exponent; a whole number
    as it is (``1,440``), NaN or None as :data:`NO_DATA`."""
    if value is None or math.isnan(value):
        return NO_DATA
    if math.isinf(value):
        return "∞" if value > 0 else "-∞"
    if float(value).is_integer() and abs(value) < 1e15:
        return f"{int(value):,}"
    if abs(value) >= 10 ** (digits - 1):
        return f"{value:,.0f}"
    import numpy as np  # the one number of numpy's this module reads: imported when a fraction is written

    text = np.format_float_positional(value, precision=digits, unique=True, fractional=False, trim="-")
    return text.rstrip(".")


def distinct_numbers(a: float, b: float, digits: int = 2) -> tuple[str, str]:
    """``a`` and ``b`` with as many significant digits (``digits`` to 6) as it takes to tell them apart."""
    for shown in range(digits, 7):
        pair = number(a, shown), number(b, shown)
        if pair[0] != pair[1]:
            return pair
    return number(a, 6), number(b, 6)


def quote(value: Any, limit: int = MAX_QUOTE) -> str:
    """``repr(value)`` cut to at most ``limit`` characters, saying how long it was when cut: what an error
    quotes of a value stays one short line however large the value."""
    try:
        return cut(repr(value), limit)
    except ValueError:  # an integer with more digits than Python will print
        return f"<an integer of {value.bit_length():,} bits>" if isinstance(value, int) else "<unprintable>"


def cut(text: str, limit: int) -> str:
    """``text`` cut to at most ``limit`` characters, with its length appended when cut."""
    return text if len(text) <= limit else f"{text[:limit]}… ({len(text):,} characters)"
