"""The chess endgames rlcompare plays, by name: what pictures and tables say of each, and the options an
environment's name carries (``KRK:defender=random,starts=hard``). Reading them imports no compiled code; the
dynamics are :mod:`rlcompare.envs.chess.endgame`'s."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from rlcompare.validation import ConfigError

ROOK, QUEEN = 0, 1
"""The stronger side's piece, as :mod:`rlcompare.envs.chess.rules` moves it."""
MOVE_LIMIT = 50
"""Moves of White per episode (the fifty-move rule's count, without captures or pawns in these endgames)."""
STARTS = ("won", "hard")
REWARDS = {"mate": (0.0, 1.0, 0.0), "moves": (-1.0, -1.0, -float(MOVE_LIMIT + 1))}
"""(a move, the mating move, a move that loses the piece or stalemates): ``moves``, the paper's -1 per move with
a failure costing more than the whole move limit; ``mate``, +1 at mate and nothing else."""
HARD_SHARE = 0.75
"""``hard`` starts: at least this share of the endgame's longest mate away."""


@dataclass(frozen=True)
class Facts:
    """What pictures and tables say of an endgame."""

    name: str
    piece: int
    title: str
    longest_mate: int
    """The longest mate with best play, in White's moves (published: KRK 16, KQK 10)."""
    classes: int
    """The states with ``symmetries=on``: the classes of legal White-to-move positions under the board's 8
    symmetries, and the ended state (:func:`rlcompare.envs.chess.endgame.states` counts them; a test keeps the two
    equal), known here without making the tables."""
    positions: int
    """The states with ``symmetries=off``: one per legal White-to-move position, and the ended state."""

    def n_states(self, symmetries: bool) -> int:
        return self.classes if symmetries else self.positions

    @property
    def n_actions(self) -> int:
        """White's actions: 8 king steps and 7 distances along each of the piece's 4 (rook) or 8 (queen) directions
        (:func:`rlcompare.envs.chess.rules.n_actions`)."""
        return 8 + 7 * (4 if self.piece == ROOK else 8)


ENDGAMES = {"KRK": Facts("KRK", ROOK, "king and rook against king", 16, 21_960, 175_169),
            "KQK": Facts("KQK", QUEEN, "king and queen against king", 10, 18_082, 144_509)}


class Options(NamedTuple):
    """An endgame environment's name, read: ``KRK`` or ``KRK:defender=random,starts=hard,symmetries=off``."""

    endgame: str
    defender: str = "optimal"
    starts: str = "won"
    """``won``, ``hard`` or a FEN (:mod:`rlcompare.envs.chess.endgame`)."""
    symmetries: bool = True
    rewards: str = "mate"

    @property
    def random_share(self) -> float:
        """The defender's share of uniformly random replies."""
        shares = {"optimal": 0.0, "random": 1.0}
        return shares[self.defender] if self.defender in shares else float(self.defender.removeprefix("mixed-"))

    @property
    def name(self) -> str:
        changed = [f"{key}={value}" for key, value, default in (
            ("defender", self.defender, "optimal"), ("starts", self.starts, "won"),
            ("symmetries", "on" if self.symmetries else "off", "on"), ("rewards", self.rewards, "mate"))
            if value != default]
        return self.endgame + (":" + ",".join(changed) if changed else "")


def is_endgame_name(name: str) -> bool:
    return isinstance(name, str) and name.partition(":")[0] in ENDGAMES


def parse(name: str) -> Options:
    """The options an environment name gives; a :class:`ConfigError` naming the part that is not allowed."""
    endgame, _, rest = name.partition(":")
    if endgame not in ENDGAMES:
        raise ConfigError("env", name, f"an endgame: {', '.join(ENDGAMES)}")
    given: dict[str, str] = {}
    for part in filter(None, rest.split(",")):
        key, equals, value = part.partition("=")
        if not equals or key not in Options._fields[1:] or key in given:
            raise ConfigError("env", name, f"{endgame}:KEY=VALUE,... with KEY defender, starts, symmetries or rewards, "
                                           "each once")
        given[key] = value.strip()
    defender = given.get("defender", "optimal")
    if defender not in ("optimal", "random") and not _is_share(defender.removeprefix("mixed-"), defender):
        raise ConfigError("env", name, "defender optimal, random or mixed-P with P in [0, 1] (the share of random "
                          "replies)")
    starts = given.get("starts", "won")
    if starts not in STARTS and "/" not in starts:
        raise ConfigError("env", name, f"starts {', '.join(STARTS)} or a FEN")
    symmetries = given.get("symmetries", "on")
    if symmetries not in ("on", "off"):
        raise ConfigError("env", name, "symmetries on or off")
    rewards = given.get("rewards", "mate")
    if rewards not in REWARDS:
        raise ConfigError("env", name, f"rewards {' or '.join(REWARDS)}")
    return Options(endgame, defender, starts, symmetries == "on", rewards)


def _is_share(text: str, whole: str) -> bool:
    try:
        return whole.startswith("mixed-") and 0.0 <= float(text) <= 1.0
    except ValueError:
        return False


