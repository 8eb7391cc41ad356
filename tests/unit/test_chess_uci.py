"""The UCI loop that serves a ladder player: each command answered as the protocol says and flushed before the
next line is read, malformed input answered with ``info string`` and never an exception, and one whole game
through python-chess's own UCI client against Stockfish."""

from __future__ import annotations

import contextlib
import io
import sys

import chess
import chess.engine
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rlcompare.players.basic import RandomPlayer
from rlcompare.players.games import play_game
from rlcompare.players.stockfish import SKILL_0, MissingEngine, StockfishPlayer, find_stockfish
from rlcompare.players.uci import Deferred, Session, centipawns, serve, warm_up_boards

AFTER_E4 = chess.Board("rnbqkbnr/pppppppp/8/8/4P3/8/PPPP1PPP/RNBQKBNR b KQkq - 0 1")
MATED = "rnb1kbnr/pppp1ppp/8/4p3/6Pq/5P2/PPPPP2P/RNBQKBNR w KQkq - 1 3"
"""White mated (fool's mate): no legal move."""
KNOWN_STARTS = ("id ", "uciok", "readyok", "bestmove ", "info string ")


class Recorder:
    """Plays the first legal move by UCI string and keeps every board it was asked about."""

    name = "recorder"

    def __init__(self) -> None:
        self.boards: list[str] = []

    def move(self, board: chess.Board) -> chess.Move:
        self.boards.append(board.fen())
        return min(board.legal_moves, key=chess.Move.uci)

    def close(self) -> None:
        pass


class Output(io.StringIO):
    """``stdout`` that keeps what was written since the last flush apart."""

    def __init__(self) -> None:
        super().__init__()
        self.pending = ""

    def write(self, text: str) -> int:
        self.pending += text
        return len(text)

    def flush(self) -> None:
        super().write(self.pending)
        self.pending = ""


class Input:
    """``stdin`` that fails the test if an answer is still unflushed when the next line is read."""

    def __init__(self, lines: list[str], out: Output) -> None:
        self.lines, self.out, self.read = [line + "\n" for line in lines], out, 0

    def readline(self) -> str:
        assert self.out.pending == "", f"unflushed after {self.lines[self.read - 1]!r}: {self.out.pending!r}"
        self.read += 1
        return self.lines[self.read - 1] if self.read <= len(self.lines) else ""


def talk(lines: list[str], player=None, **options) -> list[str]:
    """What the loop answers to ``lines``, each answer flushed before the next line is read."""
    out = Output()
    serve(player or RandomPlayer(0), Input(lines, out), out, **options)  # type: ignore[arg-type]
    assert out.pending == ""
    return out.getvalue().splitlines()


def infos(answers: list[str]) -> list[str]:
    return [answer for answer in answers if answer.startswith("info string ")]


def test_uci_names_the_engine_and_ends_with_uciok():
    assert talk(["uci"]) == ["id name random", "id author rlcompare", "uciok"]
    assert talk(["uci"], name="ladder random")[0] == "id name ladder random"


class Valuer(Recorder):
    """The recorder's move, valued at ``value``."""

    name = "valuer"

    def __init__(self, value: float) -> None:
        super().__init__()
        self.value = value

    def evaluate(self, board: chess.Board) -> tuple[chess.Move, float]:
        return self.move(board), self.value


def test_a_player_that_values_its_move_sends_depth_score_and_pv_before_bestmove():
    assert talk(["go"], Valuer(0.5)) == ["info depth 1 score cp 111 pv a2a3", "bestmove a2a3"]
    assert talk(["go"], Valuer(-2.0)) == ["info depth 1 score cp -12800 pv a2a3", "bestmove a2a3"]
    assert talk(["go"], Recorder()) == ["bestmove a2a3"]  # no value, no score
    deferred = Deferred("network", lambda: Valuer(0.25))
    assert talk(["isready", "go"], deferred) == ["readyok", "info depth 1 score cp 46 pv a2a3", "bestmove a2a3"]


def test_centipawns_map_a_value_by_leela_s_tangent_clipped_to_minus_one_and_one():
    values = [-1.0, -0.9, -0.5, -0.1, 0.0, 0.1, 0.5, 0.9, 1.0]
    cps = [centipawns(value) for value in values]
    assert cps == sorted(cps)
    assert len(set(cps)) == len(cps)
    assert cps == [-centipawns(-value) for value in values]
    assert (centipawns(0.0), centipawns(0.5), centipawns(0.9), centipawns(1.0)) == (0, 111, 671, 12800)
    assert centipawns(1.7) == centipawns(float("inf")) == 12800
    assert centipawns(float("-inf")) == -12800
    assert centipawns(float("nan")) == 0


def test_isready_answers_readyok_each_time():
    assert talk(["isready", "isready"]) == ["readyok", "readyok"]


def test_a_deferred_player_is_made_at_isready_not_before_uci_is_answered():
    """A network is loaded and compiled when the GUI asks isready (a move on each warm-up board: the start, a move
    after it, a FEN's position, a game pgx has ended), so that uciok comes at once; a player that cannot be made is
    said so, and readyok still comes."""
    made: list[Recorder] = []

    def make() -> Recorder:
        made.append(Recorder())
        return made[-1]

    session = Session(Deferred("network", make), "network")
    assert session.handle("uci")[-1] == "uciok"
    assert made == []
    assert session.handle("isready") == ["readyok"]
    assert len(made) == 1
    assert made[0].boards == [board.fen() for board in warm_up_boards()]
    assert [len(board.move_stack) for board in warm_up_boards()] == [0, 1, 1, 9]
    session.handle("position startpos moves e2e4")
    assert session.handle("go")[-1].startswith("bestmove ")
    assert len(made) == 1
    broken = Deferred("broken", lambda: (_ for _ in ()).throw(OSError("no such run")))
    answers = talk(["isready", "go"], broken, name="broken")
    assert answers[0].startswith("info string broken could not be made ready: OSError('no such run')")
    assert answers[1] == "readyok"
    assert answers[-1] == "bestmove 0000"


def test_position_startpos_with_moves_is_the_board_the_player_sees():
    recorder = Recorder()
    answers = talk(["position startpos moves e2e4", "go"], recorder)
    assert recorder.boards == [AFTER_E4.fen()]
    assert answers == [f"bestmove {min(AFTER_E4.legal_moves, key=chess.Move.uci).uci()}"]


def test_position_fen_with_moves():
    recorder = Recorder()
    fen = "6k1/5ppp/8/8/8/8/8/R5K1 w - - 0 1"
    talk([f"position fen {fen} moves g1f2 g8f8", "go depth 3"], recorder)
    assert recorder.boards == ["5k2/5ppp/8/8/8/8/5K2/R7 w - - 2 2"]


def test_castling_is_read_in_uci_notation():
    recorder = Recorder()
    talk(["position fen r3k2r/8/8/8/8/8/8/R3K2R w KQkq - 0 1 moves e1g1 e8c8", "go"], recorder)
    assert recorder.boards == ["2kr3r/8/8/8/8/8/8/R4RK1 w - - 2 2"]


def test_go_answers_a_legal_move_whatever_its_parameters():
    for go in ("go", "go wtime 1000 btime 900 winc 10 binc 10 movestogo 20", "go depth 5", "go nodes 100",
               "go movetime 50", "go mate 3"):
        answers = talk(["position startpos moves e2e4", go])
        assert len(answers) == 1
        assert AFTER_E4.parse_uci(answers[0].removeprefix("bestmove "))


def test_go_searchmoves_keeps_to_the_moves_named():
    answers = talk(["position startpos", "go searchmoves g1f3 b1c3 wtime 100"], Recorder())  # Recorder plays a2a3
    assert answers[-1] == "bestmove b1c3"
    assert infos(answers) == ["info string recorder chose a2a3, outside searchmoves"]


def test_go_without_a_legal_move_answers_the_null_move():
    assert talk([f"position fen {MATED}", "go"]) == ["bestmove 0000"]


def test_go_before_any_position_plays_from_the_start():
    recorder = Recorder()
    talk(["go"], recorder)
    assert recorder.boards == [chess.STARTING_FEN]


def test_ucinewgame_returns_to_the_start_and_answers_nothing():
    recorder = Recorder()
    answers = talk(["position startpos moves e2e4", "ucinewgame", "go"], recorder)
    assert recorder.boards == [chess.STARTING_FEN]
    assert len(answers) == 1


def test_go_infinite_holds_its_move_until_stop():
    answers = talk(["position startpos", "go infinite", "isready", "stop"])
    assert answers[0] == "readyok"
    assert answers[1].startswith("bestmove ")
    assert len(answers) == 2


def test_go_ponder_holds_its_move_until_ponderhit():
    answers = talk(["position startpos moves e2e4", "go ponder wtime 100 btime 100", "ponderhit"])
    assert len(answers) == 1
    assert AFTER_E4.parse_uci(answers[0].removeprefix("bestmove "))


def test_stop_with_nothing_searched_answers_nothing():
    assert talk(["stop", "position startpos", "go", "stop"])[1:] == []


def test_a_new_go_drops_a_held_move():
    recorder = Recorder()
    answers = talk(["go infinite", "position startpos moves e2e4", "go", "stop"], recorder)
    assert answers == [f"bestmove {min(AFTER_E4.legal_moves, key=chess.Move.uci).uci()}"]
    assert len(recorder.boards) == 2


def test_setoption_debug_and_register_answer_nothing():
    assert talk(["setoption name Hash value 16", "setoption name Nonsense value x y z", "setoption name Clear Hash",
                 "debug on", "register later", "isready"]) == ["readyok"]


def test_quit_ends_the_loop_and_so_does_the_end_of_input():
    assert talk(["isready", "quit", "isready"]) == ["readyok"]
    assert talk(["isready"]) == ["readyok"]


def test_an_unknown_command_is_answered_with_info_string():
    assert talk(["hello there", "isready"]) == ["info string unknown command 'hello there'", "readyok"]


def test_unknown_tokens_before_a_command_are_skipped_as_the_protocol_says():
    assert talk(["joho isready"]) == ["info string unknown tokens 'joho' skipped", "readyok"]


def test_empty_lines_answer_nothing():
    assert talk(["", "   ", "isready"]) == ["readyok"]


def test_an_illegal_move_in_position_stops_the_position_before_it():
    recorder = Recorder()
    answers = talk(["position startpos moves e2e4 e7e5 e1e3 g1f3", "go"], recorder)
    assert recorder.boards == ["rnbqkbnr/pppp1ppp/8/4p3/4P3/8/PPPP1PPP/RNBQKBNR w KQkq - 0 2"]
    assert len(infos(answers)) == 1
    assert "'e1e3' not played" in infos(answers)[0]
    assert answers[-1].startswith("bestmove ")


def test_a_malformed_or_null_move_in_position_is_said_too():
    for bad in ("e2", "zz99", "0000", "e7e5"):
        recorder = Recorder()
        answers = talk([f"position startpos moves {bad}", "go"], recorder)
        assert recorder.boards == [chess.STARTING_FEN]
        assert f"'{bad}' not played" in infos(answers)[0]


def test_a_bad_fen_leaves_no_position_and_the_next_go_answers_the_null_move():
    """Once the engine kept the position before a bad FEN, and the next go answered for a board the GUI no longer
    showed."""
    recorder = Recorder()
    answers = talk(["position startpos moves e2e4", "position fen this is not a fen", "go"], recorder)
    assert recorder.boards == []
    assert infos(answers)[0].startswith("info string bad FEN 'this is not a fen'")
    assert infos(answers)[1] == "info string no position until the next one that can be set"
    assert answers[-1] == "bestmove 0000"


@pytest.mark.parametrize("counters", ["0 99999999999999999999", "99999999999999999999 1", "0 2147483648"])
def test_move_counters_past_32_bits_are_refused_at_position_not_at_go(counters):
    """A FEN with counters of 20 digits was accepted, then go answered with an internal OverflowError."""
    recorder = Recorder()
    answers = talk([f"position fen 8/8/8/4k3/8/8/R7/4K3 w - - {counters}", "go"], recorder)
    assert infos(answers)[0] == (f"info string bad FEN '8/8/8/4k3/8/8/R7/4K3 w - - {counters}': a move counter "
                                 "above 2,147,483,647")
    assert recorder.boards == []
    assert answers[-1] == "bestmove 0000"
    assert not any("Error" in line for line in answers)
    kept = talk(["position fen 8/8/8/4k3/8/8/R7/4K3 w - - 0 2147483647", "go"], Recorder())
    assert kept[-1] != "bestmove 0000"


def test_an_impossible_position_is_refused():
    recorder = Recorder()
    answers = talk(["position fen 8/8/8/8/8/8/8/8 w - - 0 1", "go", "position startpos", "go"], recorder)
    assert "no white king" in infos(answers)[0]
    assert recorder.boards == [chess.STARTING_FEN]
    assert answers.count("bestmove 0000") == 1


def test_position_without_startpos_or_fen_or_with_stray_tokens():
    answers = talk(["position", "position e2e4", "position startpos e2e4", "isready"])
    assert [line.split(":")[0] for line in answers] == [
        "info string position needs startpos or fen, got ''",
        "info string no position until the next one that can be set",
        "info string position needs startpos or fen, got 'e2e4'",
        "info string no position until the next one that can be set",
        "info string ignored 'e2e4' after startpos", "readyok"]


def test_a_failing_or_cheating_player_gives_the_null_move_and_says_why():
    class Failing(Recorder):
        def move(self, board: chess.Board) -> chess.Move:
            raise RuntimeError("no idea")

    class Cheating(Recorder):
        def move(self, board: chess.Board) -> chess.Move:
            return chess.Move.from_uci("e2e5")

    assert talk(["go"], Failing()) == ["info string recorder failed: RuntimeError('no idea')", "bestmove 0000"]
    assert talk(["go"], Cheating()) == ["info string recorder chose the illegal move e2e5", "bestmove 0000"]


TOKENS = ("uci", "isready", "position", "startpos", "fen", "moves", "go", "infinite", "ponder", "searchmoves",
          "stop", "ponderhit", "setoption", "name", "value", "ucinewgame", "e2e4", "e7e5", "e1g1", "0000", "8/8",
          "rnbqkbnr/pppppppp/8/8/8/8/PPPPPPPP/RNBQKBNR", "w", "b", "KQkq", "-", "0", "1")
LINES = st.lists(st.sampled_from(TOKENS) | st.text(st.characters(blacklist_characters="\r\n"), max_size=8),
                 max_size=12).map(" ".join).filter(lambda line: "quit" not in line.split())


@given(st.lists(LINES, max_size=8))
def test_no_input_raises_and_every_answer_is_one_the_protocol_knows(lines):
    answers = talk([*lines, "go", "stop"])
    assert all(answer.startswith(KNOWN_STARTS) for answer in answers), answers
    assert answers[-1].startswith("bestmove ")


SERVE_RANDOM = ("import sys; from rlcompare.players.basic import RandomPlayer; "
                "from rlcompare.players.uci import serve; serve(RandomPlayer(0), sys.stdin, sys.stdout)")


class ThroughUci:
    """The served player, as python-chess's UCI client sees it; keeps every move it received."""

    name = "served random"

    def __init__(self, engine: chess.engine.SimpleEngine) -> None:
        self.engine, self.received = engine, []

    def move(self, board: chess.Board) -> chess.Move:
        move = self.engine.play(board, chess.engine.Limit(time=1.0)).move
        assert move is not None
        self.received.append((board.copy(), move))
        return move

    def close(self) -> None:
        pass


@pytest.mark.slow("starts Python and Stockfish and plays a game between them through UCI")
def test_python_chess_plays_a_whole_game_through_the_served_player_against_stockfish():
    try:
        stockfish_path = find_stockfish()
    except MissingEngine as missing:
        pytest.skip(str(missing))
    with chess.engine.SimpleEngine.popen_uci([sys.executable, "-c", SERVE_RANDOM]) as engine:
        assert engine.id["name"] == "random"
        served = ThroughUci(engine)
        with contextlib.closing(StockfishPlayer(SKILL_0, stockfish_path)) as stockfish:
            record = play_game(served, stockfish, max_plies=400)
        engine.quit()
        assert engine.returncode.result(timeout=10) == 0
    assert served.received
    assert all(move in board.legal_moves for board, move in served.received)
    assert record.plies < 400
    assert record.game.end().board().outcome(claim_draw=True) is not None
