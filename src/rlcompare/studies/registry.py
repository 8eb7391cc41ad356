"""Every study, one record each: its name, what it asks, its options and where its runner lives.

``rlcompare reproduce STUDY`` is generated from these records: a subcommand per study taking exactly the fields
of its options class (docstrings as help), so an option a study does not read is an error. ``reproduce --list``,
``rlcompare report`` and the README's list read them too; nothing else lists the studies. A runner is imported
only when its study runs (the deep study's needs the ``deep`` extra); ``--plan`` imports the study's planner, where it
names one, in its place: the design without the report's modules (pandas, matplotlib).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from rlcompare.studies.interface import Options, Seeded, listed, option
from rlcompare.validation import ConfigError

PAPER_LEARNERS = ("q_learning", "sarsa")


@dataclass(frozen=True)
class PaperOptions(Seeded):
    """The paper's grid of configurations on one environment."""

    episodes: int = option(5000, minimum=1)
    """Training episodes per seed (the paper gives none)."""
    algorithms: str = ",".join(PAPER_LEARNERS)
    """Comma-separated algorithms run on the paper's grid besides the random baseline; 'all' for every one. Each
    adds rows to Tables I and II."""
    videos: bool = True
    """Render videos of the greedy agents into the report."""

    def check(self) -> None:
        self.learners  # noqa: B018 - refuses an unknown algorithm on creation

    @property
    def learners(self) -> tuple[str, ...]:
        from rlcompare.algorithms.registry import METHODS

        return listed("algorithms", self.algorithms, tuple(a for a in METHODS if a != "random"), every="all")


@dataclass(frozen=True)
class WhyOptions(Seeded):
    episodes: int = option(5000, minimum=1)
    """Training episodes per seed."""


@dataclass(frozen=True)
class Book100Options(Seeded):
    seeds: int = option(100, minimum=1, spellings=("--runs",))
    """Number of runs, as many as the book averages over; the seeds are first-seed, first-seed + 1, ..."""


@dataclass(frozen=True)
class CliffOptions(Seeded):
    seeds: int = option(50, minimum=1, spellings=("--runs",))
    """Number of runs, as many as the book averages over; the seeds are first-seed, first-seed + 1, ..."""


@dataclass(frozen=True)
class Fig63Options(Seeded):
    seeds: int = option(50_000, minimum=1, spellings=("--runs",))
    """Runs of the interim phase, as the book's; the asymptotic phase runs the first 1 in 5,000 of them, at
    least 2."""
    episodes: int = option(100_000, minimum=1)
    """Episodes of the asymptotic phase (the book's 100,000)."""


@dataclass(frozen=True)
class DeepOptions(Seeded):
    seeds: int = option(10, minimum=1, spellings=("--runs",))
    """Number of seeds; the seeds are first-seed, first-seed + 1, ..."""
    steps: int | None = option(None, minimum=1)
    """Environment steps of every deep training, in place of each preset's (for a quick look). Each method trains
    whole batches of steps in every evaluation round, so fewer or more than given where they do not divide it;
    each training's line then says how many."""
    episodes: int = option(5000, minimum=1)
    """Training episodes per seed of the tabular pair."""
    methods: str | None = None
    """Comma-separated deep methods. Default: every one."""
    envs: str | None = None
    """Comma-separated environments (CartPole-v1, Acrobot-v1, MountainCar-v0). Default: all three."""
    workers: int | None = option(None, minimum=1)
    """Deep configurations trained at once. Default: one per core, at most 4."""


@dataclass(frozen=True)
class MinAtarOptions(Seeded):
    seeds: int = option(9, minimum=1, spellings=("--runs",))
    """Number of seeds; the seeds are first-seed, first-seed + 1, ... (the MinAtar paper ran 30; below 9 the
    signed-rank test cannot decide 3 games and the overall row, a direction and an equivalence test each, under
    Holm: --plan says so)."""
    budget: str = "short"
    """short (3 games, 250,000 steps: 11 minutes measured on 2 CPU cores with the default pair and 9 seeds),
    paper (every game, the MinAtar paper's 5 M frames) or pqn (every game, purejaxql's 10 M steps); --plan gives
    this machine's time once its trainings have run here."""
    games: str | None = None
    """Comma-separated games (asterix, breakout, freeway, seaquest, space_invaders). Default: the budget's."""
    protocol: str = "minatar"
    """minatar (the MinAtar paper's: sticky actions, each step repeating the last action with probability 0.1;
    all 6 actions; no time limit) or gymnax (PQN's: no sticky actions, only the actions each game uses, gymnax's
    time limits)."""
    steps: int | None = option(None, minimum=1)
    """Environment steps of every training, in place of the budget's. Each method trains whole batches of steps in
    every evaluation round, so fewer or more than given where they do not divide it; each training's line then
    says how many."""
    methods: str = "pqn_sarsa_lambda,pqn_q_lambda"
    """Comma-separated deep methods (docs/deep.md lists them), each with its MinAtar preset; by default the paper's
    pair, SARSA(λ) and Peng's Q(λ). 'ablations': the pair, Watkins's Q(λ) (traces cut after exploratory actions)
    and the pair at λ = 0 (the one-step targets alone), which separate the target from the traces (descriptive:
    only the pair gets verdicts; 2.5 times the time); 'all' for every one."""
    workers: int | None = option(None, minimum=1)
    """Trainings at once. Default: one per core, at most 2."""
    videos: bool = True
    """Render videos of each method's agent at three stages of learning in every game."""
    address: str | None = None
    """Train on the Ray cluster at this address ('auto': the one 'ray start' began here; or HOST:PORT), each
    training's blocks of up to 10 seeds a task, instead of on this machine."""

    def check(self) -> None:
        from rlcompare.envs.minatar import GAMES, PROTOCOLS

        for name, allowed in (("budget", ("short", "paper", "pqn")), ("protocol", tuple(PROTOCOLS))):
            if getattr(self, name) not in allowed:
                raise ConfigError(name, getattr(self, name), f"one of {', '.join(allowed)}")
        if self.games is not None:
            listed("games", self.games, tuple(GAMES))


ATARI_BUDGETS = ("smoke", "100k", "10m", "200m")


@dataclass(frozen=True)
class AtariOptions(Seeded):
    """Q(λ) against SARSA(λ) on the Atari 2600 (:mod:`rlcompare.studies.atari.study`)."""

    seeds: int = option(2, minimum=1, spellings=("--runs",))
    """Number of seeds; the seeds are first-seed, first-seed + 1, ... The smoke budget is a plumbing check (it
    checks the pipeline, not the question); the others need 7 seeds for one game, 9 for Atari-5 and 12 for Atari
    100k's 26 games (--plan says so)."""
    budget: str = "smoke"
    """smoke (Breakout, 32,768 steps: the whole pipeline in about 10 minutes on 2 CPU cores), 100k (Atari 100k's 26
    games, 100,000 steps), 10m (Atari-5, 10 M steps = 40 M frames) or 200m (Atari-5, purejaxql's 200 M frames);
    docs/atari.md says what each takes, and --plan this machine's time once its trainings have run here."""
    games: str | None = None
    """A set of games (atari5, atari100k, breakout-pong, atari57, breakout) or comma-separated titles as Gymnasium
    spells them (Breakout, Pong, Qbert, ...). Default: the budget's."""
    steps: int | None = option(None, minimum=1)
    """Agent steps (4 frames each) of every training, in place of the budget's."""
    methods: str = "pqn_sarsa_lambda,pqn_q_lambda"
    """Comma-separated deep methods (docs/deep.md), each with its Atari preset: by default the paper's pair,
    SARSA(λ) and Peng's Q(λ); 'all' for every one."""
    videos: bool = True
    """Render each method's agent at three stages of learning, playing Gymnasium's ALE/<Game>-v5."""
    address: str | None = None
    """Train on the Ray cluster at this address ('auto', or HOST:PORT), each training a task, instead of on this
    machine."""

    def check(self) -> None:
        from rlcompare.envs.atari.scores import chosen_games

        if self.budget not in ATARI_BUDGETS:
            raise ConfigError("budget", self.budget, f"one of {', '.join(ATARI_BUDGETS)}")
        if self.games is not None:
            chosen_games(self.games)


@dataclass(frozen=True)
class ChessEndgameOptions(Seeded):
    """Q-Learning against SARSA on chess endgames (:mod:`rlcompare.studies.chess.endgames`)."""

    episodes: int | None = option(None, minimum=1)
    """Training episodes per seed in every setting, in place of each setting's budget (KRK against the optimal
    defender 150,000; KQK 100,000; against the random defender 30,000)."""
    endgames: str = "KRK,KQK"
    """Comma-separated endgames: KRK (king and rook against king), KQK (king and queen)."""
    defenders: str = "optimal,random"
    """Comma-separated defenders: optimal (resists longest, by the solver's depth to mate) or random."""
    algorithms: str = ",".join(PAPER_LEARNERS)
    """Comma-separated one-step learners; with both Q-Learning and SARSA, the order ablation runs too."""
    videos: bool = True
    """Draw boards, value maps, animated games at three stages and PGN of the evaluation games."""

    def check(self) -> None:
        self.chosen  # noqa: B018 - refuses an unknown endgame, defender or learner on creation

    @property
    def chosen(self) -> tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]:
        from rlcompare.algorithms.registry import METHODS
        from rlcompare.envs.chess.endgames import ENDGAMES

        return (listed("endgames", self.endgames, tuple(ENDGAMES)),
                listed("defenders", self.defenders, ("optimal", "random")),
                listed("algorithms", self.algorithms, tuple(m for m in METHODS if METHODS[m].one_step)))


@dataclass(frozen=True)
class ChessOptions(Seeded):
    """Q(λ) against SARSA(λ) in self-play on a whole game of chess (:mod:`rlcompare.studies.chess.game`)."""

    seeds: int = option(7, minimum=1, spellings=("--runs",))
    """Number of seeds; the seeds are first-seed, first-seed + 1, ... (below 7 the signed-rank test cannot decide:
    a direction and an equivalence test under Holm ask 0.025 of it)."""
    game: str = "gardner_chess"
    """gardner_chess (Gardner's 5 x 5 minichess, the CPU's game) or chess."""
    budget: str = "cpu"
    """cpu (500,000 plies per training: about 25 minutes on 2 CPU cores with the default seeds) or gpu (10 M plies;
    docs/chess-game.md says what each takes; --plan this machine's time once its trainings have run here)."""
    steps: int | None = option(None, minimum=1)
    """Environment steps (plies) of every training, in place of the budget's."""
    methods: str = "pqn_sarsa_lambda,pqn_q_lambda"
    """Comma-separated PQN methods (docs/deep.md): by default the paper's pair, SARSA(λ) and Q(λ)."""
    pairs: int = option(32, minimum=1)
    """Pairs of games (colours swapped) of each pairing of the ladder in pgx; against Stockfish a sixteenth."""
    stockfish: bool = True
    """On chess, rate against Stockfish (Debian's package) at Skill Level 0 and at UCI_Elo 1350."""
    workers: int | None = option(None, minimum=1)
    """Trainings at once. Default: one per core, at most 2."""
    videos: bool = True
    """Draw each method's network at three stages of learning, with its game's record."""
    address: str | None = None
    """Train on the Ray cluster at this address ('auto', or HOST:PORT) instead of on this machine."""

    def check(self) -> None:
        from rlcompare.envs.chess.games import GAMES

        for name, allowed in (("game", tuple(GAMES)), ("budget", ("cpu", "gpu"))):
            if getattr(self, name) not in allowed:
                raise ConfigError(name, getattr(self, name), f"one of {', '.join(allowed)}")


@dataclass(frozen=True)
class SensitivityOptions(Options):
    seeds: int = option(20, minimum=1, spellings=("--runs",))
    """Number of seeds; the study's sweep derives them from one root seed, so the same number gives the same
    seeds."""
    episodes: int = option(1500, minimum=1)
    """Training episodes per seed."""
    grid: tuple[str, ...] = ()
    """The values of one axis of the grid, KEY=V1,V2,... with KEY alpha, gamma, epsilon_end or
    truncation_as_terminal (the cross, ε decaying from 1 to epsilon_end) or epsilon (the constant ε values of the
    schedule block, crossed with gamma at α = 0.05, time limit terminal); repeat the option. Default:
    alpha=0.01,0.05,0.1,0.2,0.5 gamma=0.9,0.99,1 epsilon_end=0,0.01,0.05 truncation_as_terminal=false,true
    epsilon=0.1,0.25,0.5."""
    workers: int | None = option(None, minimum=1)
    """Trials at once on this machine. Default: every core."""
    address: str | None = None
    """Run the trials on the Ray cluster at this address ('auto': the one 'ray start' began here; or HOST:PORT)
    instead of this machine's cores."""


@dataclass(frozen=True)
class Study:
    """One study: ``rlcompare reproduce NAME``."""

    name: str
    summary: str
    """One line: what the study asks."""
    options: type[Options]
    runner: str
    """``module`` or ``module:attribute``: the object whose ``run`` and ``report`` carry the study out
    (:mod:`rlcompare.studies.interface`)."""
    extra: str = ""
    """The optional extra its runner needs, if any."""
    planner: str = ""
    """``module`` whose ``study_plan`` gives the design (``--plan``) without the runner's report modules; empty: the
    runner's own."""

    def load_runner(self) -> Any:
        """The runner, imported now; an :class:`ImportError` saying how to install a missing extra."""
        return _load(self.runner)

    def load_planner(self) -> Any:
        """What offers ``study_plan``: the planner where the study names one, else the runner; imported now."""
        return _load(self.planner or self.runner)


def _load(name: str) -> Any:
    module, _, attribute = name.partition(":")
    loaded = importlib.import_module(module)
    return getattr(loaded, attribute) if attribute else loaded


STUDIES = {study.name: study for study in (
    Study("paper", "the paper: Q-Learning vs SARSA on MountainCar-v0, ε constant and decaying, and the order ablation",
          PaperOptions, "rlcompare.studies.paper.study:MOUNTAIN_CAR"),
    Study("why", "why SARSA wins there: target (max, taken, expectation) x order of choosing A' and updating",
          WhyOptions, "rlcompare.studies.paper.why"),
    Study("cartpole", "the paper's grid of configurations on CartPole-v1", PaperOptions,
          "rlcompare.studies.paper.study:CARTPOLE"),
    Study("acrobot", "the paper's grid of configurations on Acrobot-v1", PaperOptions,
          "rlcompare.studies.paper.study:ACROBOT"),
    Study("book-10.2", "Semi-gradient SARSA with tile coding (Figure 10.2)", Book100Options,
          "rlcompare.studies.book.figures:FIG_10_2"),
    Study("book-12.10", "SARSA(λ) with replacing traces (Figure 12.10)", Book100Options,
          "rlcompare.studies.book.figures:FIG_12_10"),
    Study("cliff", "Cliff Walking: SARSA, Q-Learning and Expected SARSA (Example 6.6)", CliffOptions,
          "rlcompare.studies.book.figures:CLIFF_STUDY"),
    Study("book-6.3", "Cliff Walking against α, 100 episodes x 50,000 runs and 100,000 x 10 (Figure 6.3; about "
          "5 min on 2 cores)", Fig63Options, "rlcompare.studies.book.figures:FIG_6_3"),
    Study("deep", "the question with networks: Q(λ), SARSA(λ), DQN, PPO on three environments (the 'deep' extra)",
          DeepOptions, "rlcompare.studies.deep.study", extra="deep", planner="rlcompare.studies.deep.plan"),
    Study("minatar", "the question on Atari-class games: Q(λ) vs SARSA(λ) with MinAtar's network, paired seeds "
          "(the 'deep' extra)", MinAtarOptions, "rlcompare.studies.deep.minatar", extra="deep",
          planner="rlcompare.studies.deep.minatar_plan"),
    Study("atari", "the question on the Atari 2600 through Gymnasium's ALE: Q(λ) vs SARSA(λ), human-normalised "
          "scores (the 'atari' extra)", AtariOptions, "rlcompare.studies.atari.study", extra="atari",
          planner="rlcompare.studies.atari.plan"),
    Study("chess-endgames", "the question on chess endgames (KRK, KQK) against an optimal and a random defender, "
          "measured against the exact optimum", ChessEndgameOptions, "rlcompare.studies.chess.endgames_report",
          planner="rlcompare.studies.chess.endgames"),
    Study("chess", "the question on a whole game in self-play: Q(λ) vs SARSA(λ) on Gardner's minichess or chess, "
          "rated on a ladder up to Stockfish (the 'deep' extra)", ChessOptions, "rlcompare.studies.chess.game",
          extra="deep", planner="rlcompare.studies.chess.game_plan"),
    Study("sensitivity", "does SARSA still beat Q-Learning across α, γ, the ε schedule and the time limit? (a sweep; "
          "Ray: --address)", SensitivityOptions, "rlcompare.studies.sensitivity.study"),
)}
"""Every study, in the order ``reproduce --list`` shows them; ``paper`` is what ``reproduce`` alone runs."""
MEASURED_DEFAULTS = {
    "paper": "smallest p 1.9e-9 against Holm's 0.005 over 10 claims; detects 1.9-3.5 of behaviour return, 27-89 of "
             "greedy return, 871 episodes to converge; 84 s on 2 cores",
    "why": "a 95% bootstrap interval over 30 seeds (no p); 92 s on 2 cores",
    "cartpole": "smallest p 1.9e-9 against Holm's 0.0063 over 8 claims; detects 3.9-80 of behaviour return, 133-150 "
                "of greedy return; 31 s on 2 cores",
    "acrobot": "smallest p 1.9e-9 against Holm's 0.0063 over 8 claims; detects 3.2-6.1 of behaviour return, 62-86 of "
               "greedy return; 5.3 min on 2 cores",
    "book-10.2": "the figure: no test decides a question; 41 s on 2 cores",
    "book-12.10": "the figure: no test decides a question; 43 s on 2 cores",
    "cliff": "smallest p 1.8e-15 against 0.05; 4 s on 2 cores",
    "book-6.3": "t tests of the book's 42 claims; 6.4 min on 2 cores",
    "deep": "smallest p 0.002 against Holm's 0.0028 over 18 tests; the networks' final greedy return detects 85 on "
            "CartPole, 19.5 on Acrobot, 51 on Mountain Car (margins 25, 25, 10); 52 min on 2 cores shared with other "
            "work",
    "minatar": "smallest p 0.0039 against Holm's 0.0063 over 8 tests; detects 1.72 points of Breakout, 48.4 of Space "
               "Invaders; 10.6 min on 2 cores",
    "atari": "a plumbing check (2 seeds: smallest p 0.5 against 0.025); 16 min on 2 cores",
    "chess-endgames": "smallest p 1.9e-9 against Holm's 0.00063 over 80 tests; detects 0.027-0.31 of the mate rate, "
                      "0.61-8.2 excess moves; 3.5 min on 2 cores",
    "chess": "smallest p 0.016 against Holm's 0.025 over 2 tests, the learning gate's 0.0078 against 0.05; detects "
             "0.151 of the result against random (margin 0.1); 20.4 min on 2 cores",
    "sensitivity": "smallest p 1.9e-6 against Holm's 0.00051 over 99 cells; 3.1 min on 2 cores",
}
"""What each study's default design can decide, as measured here on 2026-11-29 (``docs/defaults.md``): the smallest p
its seeds allow against the level it faces, the differences its verdicts detect at 80% power, and its time."""
DEFAULT_STUDY = "paper"


def study(name: str) -> Study:
    """The study called ``name``; a :class:`KeyError` naming the studies there are."""
    try:
        return STUDIES[name]
    except KeyError:
        raise KeyError(f"unknown study {name!r}; studies: {', '.join(STUDIES)}") from None
