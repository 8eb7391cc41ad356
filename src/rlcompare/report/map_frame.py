"""What a map over two observation dimensions shows, apart from matplotlib so that a study can name it
without loading the plotting stack."""

from __future__ import annotations

from typing import NamedTuple


class MapFrame(NamedTuple):
    """What a map over two observation dimensions shows: their bounds, their names and the actions' names, all
    the environment's (``Environment.map_axes`` and ``action_names``)."""

    extent: tuple[float, float, float, float]
    """``(x low, x high, y low, y high)``: the grid's bounds."""
    axes: tuple[str, str]
    actions: tuple[str, ...]
