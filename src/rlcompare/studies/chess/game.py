"""``rlcompare reproduce chess``: the paper's question on a whole game of chess, with networks, in self-play.

A configuration of the paired study (:mod:`rlcompare.studies.paired`): Q(λ) (off-policy, the opponent's best legal
reply) against SARSA(λ) (on-policy, the reply played), one network playing both sides, on Gardner's 5 x 5 minichess
by default or on chess (``--game chess``), through pgx (:mod:`rlcompare.deep.chess.games`). A method's result is its
final greedy network's score against the uniformly random player; the verdicts compare those on paired seeds. Then a
rating ladder (:mod:`rlcompare.studies.chess.ladder`): every network against the random player, the one-ply material
player and the other method's network of the same seed, and on chess against Stockfish at two settings, each pair of
games from a seeded random opening with colours swapped, every distinct game rated together by a Bradley-Terry fit
on the Elo scale (random = 0) with two-level bootstrap intervals (seeds, then games). The ladder's games are played
once, when the runs are trained, and kept beside them.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.deep.chess.games import chess_game_env
from rlcompare.deep.results import DeepResults
from rlcompare.experiment import rundir, store
from rlcompare.report.page import Section, save_figure, write_report, write_table
from rlcompare.stats.design import GATE, can_pass, seeds_needed, smallest_p
from rlcompare.stats.significance import ALPHA
from rlcompare.studies.chess import ladder as chess_ladder
from rlcompare.studies.chess.game_plan import CHESS, STUDY, game_title, plan_of
from rlcompare.studies.chess.game_plan import study_plan as study_plan
from rlcompare.studies.chess.ladder import MATERIAL, RANDOM, Learner, games_of
from rlcompare.studies.chess.stages import stage_games
from rlcompare.studies.interface import UI, Report
from rlcompare.studies.paired import cluster, train
from rlcompare.studies.paired_plan import PAIR, Key, short_label
from rlcompare.studies.paired_report import curves_drawn, findings
from rlcompare.studies.registry import ChessOptions

if TYPE_CHECKING:
    from rlcompare.stats.seeded_ratings import Levelled

STOCKFISH = "stockfish"
"""What the Stockfish rungs' names begin with."""
LADDER = "ladder"
"""The directory, inside the study's, of each game's ladder: its games and what they were played from."""
GAMES_FILE = "games.parquet"


def run(out: Path, options: ChessOptions, ui: UI, *, study: str = STUDY, force: bool = False) -> dict[str, Any]:
    """Every training of the plan (on this machine or on the Ray cluster at ``options.address``), then the ladder's
    games, where the directory has none for these runs."""
    if options.game == "chess" and options.stockfish:
        from rlcompare.players.stockfish import find_stockfish

        find_stockfish()  # a missing engine is one line, before anything is trained
    plan = plan_of(options)
    backend = cluster(options.address)
    where = f"on Ray at {options.address}" if backend else "on this machine"
    ui.say(f"{game_title(options.game)}: {len(plan.configs())} trainings x {len(plan.seeds)} seeds x "
           f"{plan.steps_text()} of self-play {where}.")
    runs = train(out, study, plan, ui, force=force, backend=backend)
    with ui.working("Playing the rating ladder"):
        play_ladder(Path(out), runs, options)
    return runs


def learners_of(runs: dict[str, DeepResults], env: str) -> list[Learner]:
    return [Learner(short_label(r.config.algorithm), r) for r in sorted(runs.values(), key=lambda r: r.config.name)
            if r.config.env == env]


def played_from(runs: dict[str, DeepResults]) -> dict[str, str]:
    """What the ladder was played from: each run's name and when it was trained."""
    return {name: str(r.meta.get("created", "")) for name, r in sorted(runs.items())}


def play_ladder(out: Path, runs: dict[str, Any], options: ChessOptions) -> None:
    """The game's ladder, written once for its runs (kept where ``ladder.json`` says it was played from the same
    runs and its games are the ones the study recorded; played again where they are missing or changed)."""
    deep = {name: r for name, r in runs.items() if isinstance(r, DeepResults) and r.config.env == options.game}
    where = out / LADDER / options.game
    marker = where / "ladder.json"
    if marker.exists() and store.read_json(marker).get("runs") == played_from(deep) and \
            store.read_json(marker).get("version") == chess_ladder.VERSION:
        try:
            rundir.read_member_file(out, ladder_games(options.game))
            return
        except store.StoreError:
            pass
    game = chess_game_env(options.game)
    learners = learners_of(deep, options.game)
    games = chess_ladder.pgx_games(game, learners, options.pairs)
    if options.game == "chess" and options.stockfish:
        engine_games, records = chess_ladder.stockfish_games(game, learners, max(1, options.pairs // 16))
        games = pd.concat([games, engine_games], ignore_index=True)
        pgn = "\n\n".join(str(record.game) for record in records) + "\n"
        store.write_bytes_atomic(where / "stockfish.pgn", pgn.encode())
    data = games.to_parquet(index=False)
    store.write_bytes_atomic(where / GAMES_FILE, data)
    rundir.enter_members(out, [], {ladder_games(options.game): data})
    store.write_json_atomic(marker, {"runs": played_from(deep), "pairs": options.pairs, "game": options.game,
                                     "version": chess_ladder.VERSION, "opening_plies": chess_ladder.OPENING_PLIES})


def load_ladder(out: Path, env: str, runs: dict[str, DeepResults]) -> pd.DataFrame:
    """The game's ladder, refused (naming the file) where it was played from other runs than these."""
    where = out / LADDER / env
    marker = where / "ladder.json"
    if not marker.exists():
        raise store.StoreError(f"{marker}: no ladder was played for these runs; run 'rlcompare reproduce chess' "
                               "with the same options to play it")
    if store.read_json(marker).get("runs") != played_from(runs):
        raise store.StoreError(f"{marker}: the ladder was played from other runs than those in {out}")
    games = pd.read_parquet(io.BytesIO(rundir.read_member_file(out, ladder_games(env))))
    missing = set(chess_ladder.COLUMNS) - set(games.columns)
    if missing:
        raise store.StoreError(f"{where / GAMES_FILE}: not a ladder's games of this version (no {sorted(missing)}); "
                               "run 'rlcompare reproduce chess' with the same options to play it again")
    return games


def ladder_games(env: str) -> str:
    """Where a game's ladder keeps its games, relative to the study's directory (recorded with their checksum in
    its :data:`~rlcompare.experiment.rundir.MEMBERS_FILE`)."""
    return f"{LADDER}/{env}/{GAMES_FILE}"


# --- the report -------------------------------------------------------------------------------------------------

ANCHOR = (RANDOM, 0.0)
"""The scale's zero, always: the uniformly random player. Stockfish's rungs are players the ladder measures, named by
their settings; a ``UCI_Elo`` setting is no rating on this scale (it is calibrated at a time control against CCRL)."""


def ladder_table(games: pd.DataFrame, ratings: dict[str, Levelled], against_random: dict[str, Levelled]
                 ) -> pd.DataFrame:
    """Per player, strongest first: its rating with the two-level interval (seeds, then games) and the games-only
    one, each seed's rating and their standard deviation; its games and how many differ, wins, draws, losses and
    score (Wilson); its score against the random player (two-level interval) and each seed's."""
    from rlcompare.stats.ratings import Game, player_records  # scipy: for the report, not the plan

    overall = player_records(Game(*game[:3]) for game in games_of(games))
    rows = []
    for player, rating in sorted(ratings.items(), key=lambda item: -item[1].estimate.value):
        record = overall[player]
        mine = games[(games["white"] == player) | (games["black"] == player)]
        versus = against_random.get(player)
        rows.append({"player": player, "rating (Elo)": rating.estimate.format(0),
                     "games-only interval": rating.games_only.format(0).split(" ", 1)[1],
                     "per seed": per_seed(rating.per_seed, 0), "between seeds (sd)": spread_text(rating, 0),
                     "games": record.games, "distinct games": chess_ladder.distinct_games(mine),
                     "won-drawn-lost": f"{record.wins}-{record.draws}-{record.losses}",
                     "score": record.interval().format(3),
                     "score against random": versus.estimate.format(3) if versus else "",
                     "against random per seed": per_seed(versus.per_seed, 3) if versus else ""})
    return pd.DataFrame(rows)


def per_seed(values: dict[int, float], digits: int) -> str:
    return ", ".join(f"#{seed} {value:.{digits}f}" for seed, value in sorted(values.items()))


def spread_text(levelled: Levelled, digits: int) -> str:
    """The spread between seeds; with one seed none can be measured, and the text says so."""
    if not levelled.per_seed:
        return ""
    return "one seed: none measured" if len(levelled.per_seed) < 2 else f"{levelled.spread:.{digits}f}"


def ladder_figure(ratings: dict[str, Levelled], anchor: tuple[str, float]) -> Figure:
    """Each player's rating with its two-level 95% interval (thin) and its games-only one (thick), strongest at the
    top."""
    ordered = sorted(ratings.items(), key=lambda item: item[1].estimate.value)
    figure = Figure(figsize=(7, 0.5 * len(ordered) + 1.2))
    ax = figure.subplots()
    values = np.array([r.estimate.value for _, r in ordered])
    for which, width, colour in (("estimate", 1.0, "#1f4e79"), ("games_only", 4.0, "#7fa7cf")):
        bounds = [getattr(r, which) for _, r in ordered]
        errors = np.array([[values[i] - b.low for i, b in enumerate(bounds)],
                           [b.high - values[i] for i, b in enumerate(bounds)]])
        ax.errorbar(values, np.arange(len(ordered)), xerr=errors, fmt="o", color=colour, capsize=4 * (width == 1),
                    elinewidth=width)
    ax.set_yticks(np.arange(len(ordered)), [name for name, _ in ordered])
    ax.set_xlabel(f"rating (Elo), {anchor[0]} at {anchor[1]:g}; 95% intervals: seeds then games (thin), games "
                  "alone (thick)")
    ax.grid(axis="x", alpha=0.3)
    figure.tight_layout()
    return figure


def answer_lines(table: pd.DataFrame, judged_label: str, difference: str, seeds: int, game: str) -> list[str]:
    """The answer in words: the verdict on the pair, then the ladder's order."""
    on, off = (short_label(method) for method in PAIR)
    order = ", ".join(f"{player} {rating}" for player, rating in zip(table["player"], table["rating (Elo)"],
                                                                     strict=True))
    return [f"{game}, self-play, {seeds} paired seeds, result of the final greedy network against the uniformly "
            f"random player (+1 won, 0 drawn, -1 lost): {on} minus {off} = {difference} ({judged_label}).",
            f"The ladder, strongest first (Elo, random = 0, 95% intervals over seeds then games): {order}."]


def learners_against_random(table: pd.DataFrame) -> str:
    learners = table[~table["player"].isin([RANDOM, MATERIAL]) & ~table["player"].str.startswith(STOCKFISH)]
    return "; ".join(f"{player} {score} (per seed {seeds})" for player, score, seeds in zip(
        learners["player"], learners["score against random"], learners["against random per seed"], strict=True))


def report(out: Path, ui: UI | None = None, *, runs: dict[str, Any] | None = None, videos: bool = True) -> Report:
    """Verdicts, the ladder (table, figure, games) and ``report.html`` of a chess study directory."""
    with store.rewriting(Path(out), "study"):
        return _build_report(Path(out), videos)


def _build_report(out: Path, videos: bool) -> Report:
    found = findings(out, CHESS)
    problems = list(found.problems)
    lines: list[str] = []
    sections: list[Section] = []
    for env in found.envs:
        game = game_title(env)
        key = Key(env)
        if key not in found.judged:
            continue
        judged = found.judged[key]
        env_runs = {name: r for name, r in found.runs.items() if r.config.env == env}
        try:
            games = load_ladder(out, env, env_runs)
        except store.StoreError as error:  # the verdicts stand; nothing is rated from games not the study's
            problems.append(f"{game}: the ladder is not rated: {error}")
            continue
        from rlcompare.stats.seeded_ratings import seeded_ratings, seeded_scores  # scipy: for the report

        ratings = seeded_ratings(games_of(games), *ANCHOR, seed=0)
        table = ladder_table(games, ratings, seeded_scores(games_of(games), RANDOM, seed=0))
        table_file = write_table(table, out / "tables", f"chess_ladder_{env}")
        figure = save_figure(ladder_figure(ratings, ANCHOR), out / "figures" / f"ladder-{env}.png")
        curves = curves_drawn(found.runs, env, "steps", out / "figures" / f"curves-{env}.png", "environment steps")
        seeds = min(len(r.seeds) for r in env_runs.values())
        lines += answer_lines(table, judged.label, judged.paired.difference.format(2), seeds, game)
        lines.append(f"Score against the random player over the ladder's games (95% intervals over seeds then "
                     f"games): {learners_against_random(table)}.")
        if not can_pass(GATE, seeds):
            lines.append(f"With {seeds} seeds the learning gate cannot pass: the one-sided signed-rank test's "
                         f"smallest p is 1/2^{seeds} = {smallest_p(GATE, seeds):g}, above {ALPHA:g}; at least "
                         f"{seeds_needed(GATE)} seeds can show a game learnt.")
        steps = {r.config.steps_trained for r in env_runs.values()}
        sections.append(Section(f"{game}: the ladder", [
            f"{len(games):,} games ({chess_ladder.distinct_games(games):,} distinct), each pair of games from one "
            f"of {games['opening'].nunique()} openings of {chess_ladder.OPENING_PLIES} random plies with colours "
            "swapped; a method's networks (every seed's) are one player. Ratings: a Bradley-Terry fit on the Elo "
            "scale over every distinct game (a draw half a win; a game two networks repeat counts once), one virtual "
            f"draw between every pair that met, anchored at {ANCHOR[0]} = {ANCHOR[1]:g} (Stockfish's rungs are "
            "measured, named by their settings); 95% intervals from 1,000 bootstrap resamples of the seeds, then "
            "of the games within each seed's pairings, and beside them the games-only interval and each seed's "
            f"rating. Training: {', '.join(f'{s:,}' for s in sorted(steps))} steps per seed."],
            [("The ladder", table, table_file)], [(figure, "Ratings with 95% intervals"), curves]))
        if videos:
            sections.append(stage_section(out, env_runs, env))
    sections.insert(0, Section("The answer", lines, [("Verdicts", found.verdicts, found.files["verdicts"])]))
    page = write_report(out / "report.html", "Chess: on- or off-policy target in self-play", sections, problems)
    return Report(page, lines, problems)


def stage_section(out: Path, runs: dict[str, DeepResults], env: str) -> Section:
    """Each method's first seed at three stages of learning: one game each as White against the random player, its
    last position drawn and its record written (PGN for chess, pgx's FEN of every position for Gardner's)."""
    figures, paragraphs = stage_games(out, runs, env)
    return Section(f"{game_title(env)}: the networks at three stages of learning", paragraphs, figures=figures)

