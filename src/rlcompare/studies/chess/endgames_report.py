"""The chess-endgames study's runner (:func:`run`, :mod:`rlcompare.studies.chess.endgames`'s) and its report: the
answer in a sentence from its verdicts, the verdicts (one Holm family, declared margins, a learning gate), why
(order against target), and pictures a chess player reads: mate-rate
curves, the learnt value of each square of the defending king against the exact one, where each learner loses its
piece, games at three stages of learning as animated boards, and every evaluation game of the first seed as PGN."""

from __future__ import annotations

from collections import Counter
from collections.abc import Hashable, Mapping
from dataclasses import replace
from pathlib import Path

import chess
import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.algorithms.registry import AFTER_UPDATE, BEFORE_UPDATE
from rlcompare.envs.chess import rules as chess_rules
from rlcompare.envs.chess.endgames import ENDGAMES, parse
from rlcompare.experiment import rundir, store
from rlcompare.experiment.engines import load_run
from rlcompare.formatting import number
from rlcompare.report.page import Section, save_figure, write_report, write_table
from rlcompare.stats.compare import Paired, compare_paired, gated_label, judge_family
from rlcompare.stats.design import SIGNED_RANK, reach, smallest_p
from rlcompare.stats.intervals import Estimate, interval
from rlcompare.stats.significance import has_learnt
from rlcompare.studies.chess import endgames as study
from rlcompare.studies.chess.endgames import run, settings
from rlcompare.studies.chess.endgames import study_plan as study_plan
from rlcompare.studies.interface import UI, Report
from rlcompare.studies.margins import margin
from rlcompare.tabular.results import Results

Key = tuple[str, str, str, str]
"""(endgame, defender, schedule, measure)"""
STAGES = (("early", 0.1), ("middle", 0.5), ("final", 1.0))
TERMS = {"SARSA - Q-Learning": ((1, "sarsa-decay"), (-1, "q_learning-decay")),
         "order": ((1, f"q_learning-decay-{BEFORE_UPDATE}"), (-1, "q_learning-decay")),
         "target": ((1, f"sarsa-decay-{AFTER_UPDATE}"), (-1, "q_learning-decay")),
         "interaction": ((1, "sarsa-decay"), (-1, f"sarsa-decay-{AFTER_UPDATE}"),
                         (-1, f"q_learning-decay-{BEFORE_UPDATE}"), (1, "q_learning-decay"))}
"""Each term of the decomposition as a signed sum of runs, per seed (:mod:`rlcompare.studies.paper.why`)."""


def _values(metrics: pd.DataFrame, measure: str, episodes: int) -> np.ndarray:
    """A measure per seed, oriented so that more is better; never holding counts as the whole budget (censored)."""
    values = metrics[measure].to_numpy(dtype=float)
    if measure == "episodes_to_hold":
        values = np.where(np.isnan(values), episodes, values)
    return values * study.MEASURES[measure][1]


def _margin(measure: str, episodes: int) -> float:
    value = margin(study.STUDY, study.MEASURES[measure][0])
    return value * episodes if measure == "episodes_to_hold" else value


def verdicts(runs: Mapping[str, Results], metrics: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """SARSA against Q-Learning on every measure of every setting, one Holm family, each behind the learning gate:
    a learner has learnt where its mate rate beats 0 by the mate-rate margin (one-sided signed-rank test)."""
    keys: list[Key] = []
    found: dict[Hashable, Paired] = {}
    learnt: dict[tuple[str, str, str], tuple[bool, bool]] = {}
    for setting in settings(runs):
        endgame, defender, schedule = setting
        sarsa, q = (metrics[f"{endgame}-{defender}-{a}-{schedule}"] for a in ("sarsa", "q_learning"))
        episodes = runs[f"{endgame}-{defender}-sarsa-{schedule}"].config.episodes
        learnt[setting] = (_learnt(sarsa), _learnt(q))
        for measure in study.MEASURES:
            keys.append((*setting, measure))
            found[keys[-1]] = compare_paired(_values(sarsa, measure, episodes), _values(q, measure, episodes),
                                             _margin(measure, episodes), improvement=False)
    judged = judge_family(found, study.SIDES)
    rows = []
    for endgame, defender, schedule, measure in keys:
        j, sign = judged[endgame, defender, schedule, measure], study.MEASURES[measure][1]
        rows.append({"endgame": endgame, "defender": defender, "exploration": _exploration(schedule),
                     "measure": study.MEASURES[measure][0], "SARSA": sign * j.paired.a_mean,
                     "Q-Learning": sign * j.paired.b_mean,
                     "SARSA - Q-Learning": _oriented(j.paired.difference, sign).format(3),
                     "p (Holm)": j.p, "smallest p": number(smallest_p(SIGNED_RANK, j.paired.seeds), 2),
                     "detectable (80% power)": number(j.detectable),
                     "better": gated_label(j.label, learnt[endgame, defender, schedule], study.SIDES)})
    return pd.DataFrame(rows)


def _learnt(metrics: pd.DataFrame) -> bool:
    return has_learnt(metrics["mate_rate"].to_numpy(), 0.0, margin(study.STUDY, "mate rate"))


def _oriented(difference: Estimate, sign: int) -> Estimate:
    """A difference of values oriented by :func:`_values`, in the measure's own direction again."""
    low, high = sorted((sign * difference.low, sign * difference.high))
    return Estimate(sign * difference.value, low, high)


def _exploration(schedule: str) -> str:
    return "ε decaying from 1" if schedule == "decay" else f"ε = {study.EPSILON:g}"


def answer(frame: pd.DataFrame, seeds: int) -> str:
    """The study's answer in one sentence, from the mate-rate verdicts; where ``seeds`` are too few for any
    verdict of the family, it says so."""
    rows = frame[frame["measure"] == "mate rate"]
    if rows.empty:
        return "No setting has both learners trained: no answer yet."
    counts = Counter(rows["better"])
    told = ", ".join(f"{what} in {n}" for what, n in counts.most_common())
    design = reach(SIGNED_RANK, seeds, family=2 * len(frame))  # each comparison's direction and equivalence
    short = f" {design.sentence()}" if not design.can_decide else ""
    return (f"On-policy or off-policy in chess endgames? Over {len(rows)} settings (endgame x defender x ε), "
            f"by the greedy mate rate from {study.EVAL_STARTS} fixed won starts: {told}.{short}")


def why_in_brief(frame: pd.DataFrame) -> str:
    """One sentence: on the mate rate, the largest part of SARSA - Q-Learning in each endgame and defender."""
    rows = frame[frame["measure"] == "mate rate"] if not frame.empty else frame
    parts = []
    for _, row in rows.iterrows():
        largest = max(("order", "target", "interaction"), key=lambda term: abs(row[term].value))
        parts.append(f"{row['endgame']} against the {row['defender']} defender, the {largest} "
                     f"({row[largest].value:+.3f} of {row['SARSA - Q-Learning'].value:+.3f})")
    return f"Why, with ε decaying: the largest part of SARSA - Q-Learning's mate rate is, {'; '.join(parts)}." \
        if parts else ""


def decomposition(runs: Mapping[str, Results], metrics: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """Per endgame and defender (ε decaying), SARSA - Q-Learning split into order, target and interaction, on the
    mate rate and the behaviour return, each an :class:`~rlcompare.stats.intervals.Estimate` with its 95% bootstrap
    interval over seeds."""
    rows = []
    for endgame in ENDGAMES:
        for defender in study.DEFENDERS:
            prefix = f"{endgame}-{defender}-"
            if not all(prefix + name in runs for term in TERMS.values() for _, name in term):
                continue
            for measure in ("mate_rate", "behaviour_return"):
                row: dict[str, object] = {"endgame": endgame, "defender": defender,
                                          "measure": study.MEASURES[measure][0]}
                for term, cells in TERMS.items():
                    per_seed = sum(sign * metrics[prefix + name][measure].to_numpy() for sign, name in cells)
                    row[term] = interval(np.asarray(per_seed))
                rows.append(row)
    return pd.DataFrame(rows)


# --- pictures -----------------------------------------------------------------------------------------------


def curves_figure(runs: Mapping[str, Results]) -> Figure:
    """The greedy mate rate over training, mean over seeds, one panel per endgame and defender."""
    from rlcompare.studies.measures import solved

    panels = sorted({(e, d) for e, d, _ in settings(runs)})
    figure = Figure(figsize=(4.2 * max(len(panels), 1), 3.4))
    for i, (endgame, defender) in enumerate(panels):
        ax = figure.add_subplot(1, len(panels), i + 1)
        for name, results in runs.items():
            if not name.startswith(f"{endgame}-{defender}-") or results.config.next_action is not None:
                continue  # the order ablation's runs
            c, r = results.config, results.records
            rates = solved(c.environment.success, r.eval_returns, r.eval_lengths, r.eval_terminated,
                           c.step_limit).mean(axis=2)
            after = (np.arange(rates.shape[1]) + 1) * c.eval_every
            ax.plot(after, rates.mean(axis=0), color=("#2a9d8f" if c.algorithm == "sarsa" else "#e07b00"),
                    linestyle="-" if c.schedule == "decay" else "--",
                    label=f"{study.SIDES[c.algorithm != 'sarsa']}, {_exploration(c.schedule)}")
        ax.axhline(study.HOLD_LEVEL, color="#999", linewidth=0.8)
        ax.set(title=f"{endgame}, {defender} defender", xlabel="episodes", ylabel="greedy mate rate", ylim=(0, 1.02))
        ax.legend(fontsize=7)
    figure.tight_layout()
    return figure


def value_figure(runs: Mapping[str, Results], name: str) -> Figure:
    """The learnt value of the position against the exact one, for each square of the defending king, with White's
    king and piece where the longest mate of the evaluation set has them (mean over seeds of the final tables)."""
    from rlcompare.report.boards import value_map

    board, exact, learnt = exact_and_learnt(runs[name], runs.get(name.replace("q_learning", "sarsa")))
    figure = Figure(figsize=(10.5, 3.6))
    titles = ("exact: γ^(moves to mate - 1)", "Q-Learning, learnt", "SARSA, learnt")
    top = float(np.nanmax(exact))
    for i, (values, title) in enumerate(zip((exact, *learnt), titles, strict=False)):
        value_map(figure.add_subplot(1, 3, i + 1), values, pieces=board, title=title, vmin=0.0, vmax=top,
                  colorbar="value" if i == 2 else None)
    return figure


def exact_and_learnt(results: Results, other: Results | None) -> tuple[chess.Board, np.ndarray, list[np.ndarray]]:
    """White's king and piece where the deepest evaluation start has them; for each square of the black king, the
    exact value of the position (γ^(moves to mate - 1), the return of +1 at mate) and each run's learnt one (the
    largest action value, mean over seeds); NaN where the square is not a legal won position."""
    from rlcompare.envs.chess.endgame import make_endgame
    from rlcompare.envs.chess.solver import solve

    env = results.config.env
    tables = make_endgame(parse(env))
    piece = ENDGAMES[parse(env).endgame].piece
    starts = study.evaluation_starts(env)
    deepest = int(starts[np.argmax(study.optimum_moves(env, starts))])
    white_king, white_piece, _ = chess_rules.decode(deepest)
    positions = white_king * 4096 + white_piece * 64 + np.arange(64)
    won = (solve(piece).white[positions] > 0) & (tables.state_of[positions] >= 0)
    exact = np.full(64, np.nan)
    exact[won] = results.config.gamma ** (study.optimum_moves(env, positions[won]) - 1)
    learnt = []
    for learner in (results, other):
        if learner is None:
            continue
        values = np.full(64, np.nan)
        finals = np.stack([learner.q_table(seed) for seed in learner.seeds])  # (seeds, states, actions)
        values[won] = finals[:, tables.state_of[positions[won]]].max(axis=2).mean(axis=0)
        learnt.append(values)
    board = chess.Board.empty()
    board.set_piece_at(white_king, chess.Piece(chess.KING, chess.WHITE))
    board.set_piece_at(white_piece, chess.Piece(chess_rules.PIECE_TYPES[piece], chess.WHITE))
    return board, exact, learnt


def failure_figure(runs: Mapping[str, Results], games: Mapping[str, list[study.Games]], names: tuple[str, ...]
                   ) -> Figure | None:
    """Each learner's most frequent losing position and move (the piece left hanging, or stalemate), over the
    seeds' evaluation games."""
    from rlcompare.envs.chess.endgame import make_endgame
    from rlcompare.report.boards import draw_board

    found = []
    for name in names:
        results = runs[name]
        tables = make_endgame(parse(results.config.env))
        lost = Counter(int(pair) for seed_games in games[name] for pair in seed_games.last[seed_games.failed])
        if lost:
            (pair, count), = lost.most_common(1)
            state, action = divmod(pair, chess_rules.n_actions(tables.piece))
            played = int(tables.positions[state])
            piece = ENDGAMES[parse(results.config.env).endgame].piece
            found.append((name, chess_rules.board_of(piece, played, True), chess_rules.move_of(piece, played, action),
                          count, sum(lost.values())))
    if not found:
        return None
    figure = Figure(figsize=(3.6 * len(found), 3.9))
    for i, (name, board, move, count, total) in enumerate(found):
        draw_board(figure.add_subplot(1, len(found), i + 1), board, highlight=move,
                   title=f"{name}\n{board.san(move)}: {count} of {total} lost games")
    return figure


def write_games(runs: Mapping[str, Results], name: str, directory: Path) -> str:
    """Every evaluation game of the first seed's final policy in ``name`` as PGN; its path for the page."""
    from rlcompare.players.endgame import ChessAgent, play
    from rlcompare.report.boards import game_pgn, write_pgn

    results = runs[name]
    seed = results.seeds[0]
    agent = ChessAgent(results.q_table(seed), results.config.env, seed)
    rng = np.random.default_rng(study.EVAL_SEED + seed)
    piece = ENDGAMES[parse(results.config.env).endgame].piece
    games = []
    for round_, index in enumerate(study.evaluation_starts(results.config.env)):
        start = chess_rules.board_of(piece, int(index), True)
        games.append(game_pgn(play(agent, start, rng), start, {
            "Event": f"rlcompare {study.STUDY}: {name}", "Site": "rlcompare", "Round": str(round_ + 1),
            "White": f"{results.config.algorithm} seed {seed}", "Black": f"{parse(results.config.env).defender} "
            "defender"}))
    path = write_pgn(directory / f"{name}.pgn", games)
    return f"{path.parent.name}/{path.name}"


def stage_animations(out: Path, runs: Mapping[str, Results], names: tuple[str, ...]) -> list[tuple[str, str, str]]:
    """A game from the deepest evaluation start by each learner's first seed at three stages of learning, as
    animated boards (GIF). The stages are the same seed trained again with snapshots at each stage: a run's result
    depends on its seed alone, so its final table equals the study's (checked here)."""
    from rlcompare.players.endgame import ChessAgent, play
    from rlcompare.report.boards import move_captions, positions, write_game_animation
    from rlcompare.tabular.train import train

    videos = []
    for name in names:
        results = runs[name]
        seed = results.seeds[0]
        again = train(replace(results.config, seeds=(seed,), stages=STAGES))
        if not np.array_equal(again.q_table(seed), results.q_table(seed)):
            raise store.StoreError(f"{name}: seed {seed} trained again differs from the stored run")
        starts = study.evaluation_starts(results.config.env)
        deepest = int(starts[np.argmax(study.optimum_moves(results.config.env, starts))])
        piece = ENDGAMES[parse(results.config.env).endgame].piece
        start = chess_rules.board_of(piece, deepest, True)
        for stage, _ in STAGES:
            agent = ChessAgent(again.q_table(seed, stage), results.config.env, seed, stage)
            moves = play(agent, start, np.random.default_rng(study.EVAL_SEED + seed))
            path = write_game_animation(out / "videos" / f"{name}-{stage}.gif", positions(start, moves),
                                        move_captions(start, moves))
            videos.append(("", f"videos/{path.name}", f"{name}, {stage} ({len(moves)} plies)"))
    return videos


# --- the page -----------------------------------------------------------------------------------------------


def load(out: Path) -> tuple[dict[str, Results], list[str]]:
    """The study's runs whose files belong together, and a line for each directory that does not load."""
    runs, problems = {}, []
    for run_dir in sorted(p for p in Path(out).iterdir() if p.is_dir() and p.name.split("-")[0] in ENDGAMES):
        try:
            runs[run_dir.name] = load_run(run_dir)
        except (OSError, ValueError, KeyError) as error:  # StoreError included
            problems.append(f"{run_dir.name}: {error}")
    return runs, problems + rundir.missing_members(out, [problem.split(":")[0] for problem in problems])


def report(out: Path, ui: UI | None = None, *, runs: dict[str, Results] | None = None, videos: bool = True
           ) -> Report:
    """Tables, figures, games and ``report.html`` of the study in ``out``, from ``runs`` or its run directories."""
    out = Path(out)
    with store.rewriting(out, "study"), (ui or UI()).working("Building the report"):
        runs, problems = load(out) if runs is None else (runs, [])
        if not settings(runs):
            raise store.StoreError(f"{out}: no setting has both SARSA and Q-Learning runs; " + "; ".join(problems))
        games = study.played(runs)
        metrics = study.measured(runs, games)
        table, why = verdicts(runs, metrics), decomposition(runs, metrics)
        means = study.summary(metrics)
        why_table = why.map(lambda v: v.format(3) if isinstance(v, Estimate) else v)
        files = {name: write_table(frame, out / "tables", name) for name, frame in
                 (("verdicts", table), ("decomposition", why_table), ("means", means[0]))}
        sentences = [answer(table, len(next(iter(runs.values())).seeds)), why_in_brief(why)]
        figures = [(save_figure(curves_figure(runs), out / "figures" / "mate-rate.png"),
                    "Greedy mate rate from random won starts over training, mean over seeds")]
        main = [f"{e}-{d}-{a}-decay" for e, d, s in settings(runs) if s == "decay" for a in ("q_learning", "sarsa")]
        pictures: list[tuple[str, str, str]] = []
        pgn: list[str] = []
        if videos:
            first = main[0]
            figures.append((save_figure(value_figure(runs, first), out / "figures" / "values.png"),
                            f"{first}: the value of each square of the defending king, exact and learnt"))
            failures = failure_figure(runs, games, tuple(main))
            if failures is not None:
                figures.append((save_figure(failures, out / "figures" / "losses.png"),
                                "Where each learner most often loses its piece (or stalemates), over its seeds"))
            pictures = stage_animations(out, runs, tuple(main[:2]))
            pgn = [write_games(runs, name, out / "games") for name in main]
        first_run = next(iter(runs.values()))
        path = write_report(out / "report.html", "On- or off-policy in chess endgames, against the exact optimum", [
            Section("Answer", [
                *sentences, f"{len(first_run.seeds)} paired seeds; γ = {study.GAMMA:g}, α = {study.ALPHA:g}; +1 at "
                "mate, nothing otherwise (docs/chess.md). Every comparison is "
                "one family under Holm's correction, with margins declared before any run (docs/why.md). A setting "
                "where a learner's mate rate does not beat 0 by the margin is labelled as not learnt."],
                tables=[("SARSA against Q-Learning", table, files["verdicts"])], figures=figures[:1]),
            Section("Why: the order of choosing and updating against the target", [
                "ε decaying: SARSA - Q-Learning = order + target + interaction, per seed (the why study's "
                "decomposition), with 95% bootstrap intervals."],
                tables=[("Decomposition", why_table, files["decomposition"])]),
            Section("Every configuration", tables=[(means[1], means[0], files["means"])]),
            Section("Pictures and games", [f"PGN of every evaluation game: {', '.join(pgn)}"] if pgn else [],
                    figures=figures[1:], videos=pictures),
        ], problems)
        return Report(path, sentences, problems)


__all__ = ["report", "run"]
