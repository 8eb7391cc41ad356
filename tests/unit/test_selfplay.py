"""Self-play in the deep engine: legal-move masks in every choice, the opponent's value negated in the bootstrap
(negamax), and games between fixed players, checked by hand and against pgx's own rules."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from rlcompare.deep import float64
from rlcompare.deep.chess.games import chess_game_env
from rlcompare.deep.envs import is_game, jax_env
from rlcompare.deep.pqn import (
    bootstrap_values,
    epsilon_greedy,
    expected_value,
    greedy,
    lambda_returns,
    uniform_legal,
)
from rlcompare.deep.rollout import material_mover, play, random_mover

Q = jnp.array([[3.0, 9.0, 1.0, 5.0]])
LEGAL = jnp.array([[True, False, True, True]])
"""The best action (1) is illegal: the best legal one is 3."""


def test_greedy_and_max_are_over_the_legal_moves() -> None:
    assert int(greedy(Q, LEGAL)[0]) == 3
    assert int(greedy(Q)[0]) == 1
    assert float(bootstrap_values("max", Q, jnp.array([0]), jnp.float32(0.1), LEGAL)[0]) == 5.0


def test_the_expectation_is_over_the_legal_moves() -> None:
    epsilon = 0.3
    by_hand = epsilon / 3 * (3.0 + 1.0 + 5.0) + (1 - epsilon) * 5.0
    assert float(expected_value(Q, jnp.float32(epsilon), LEGAL)[0]) == pytest.approx(by_hand, rel=1e-6)
    assert float(expected_value(Q, jnp.float32(epsilon))[0]) == pytest.approx(
        epsilon / 4 * 18.0 + (1 - epsilon) * 9.0, rel=1e-6)


def test_sarsa_bootstraps_from_the_reply_played_even_where_the_mask_would_forbid_none() -> None:
    assert float(bootstrap_values("sample", Q, jnp.array([2]), jnp.float32(0.1), LEGAL)[0]) == 1.0


@pytest.mark.slow("4,000 draws vmapped, compiled")
def test_epsilon_greedy_never_draws_an_illegal_move() -> None:
    keys = jax.random.split(jax.random.key(0), 4000)
    drawn = np.asarray(jax.vmap(lambda k: epsilon_greedy(k, Q, jnp.float32(1.0), LEGAL)[0])(keys))
    assert set(np.unique(drawn)) == {0, 2, 3}
    counts = np.bincount(drawn, minlength=4)[[0, 2, 3]]
    assert stats.chisquare(counts).pvalue > 1e-3  # uniform over the three legal moves
    greedy_only = np.asarray(jax.vmap(lambda k: epsilon_greedy(k, Q, jnp.float32(0.0), LEGAL)[0])(keys[:50]))
    assert (greedy_only == 3).all()


@pytest.mark.slow("4,000 draws vmapped, compiled")
def test_a_uniform_legal_draw_is_uniform_over_many_actions() -> None:
    legal = jnp.zeros((1, 50), bool).at[0, jnp.array([4, 17, 33, 49])].set(True)
    keys = jax.random.split(jax.random.key(1), 4000)
    drawn = np.asarray(jax.vmap(lambda k: uniform_legal(k, legal)[0])(keys))
    assert set(np.unique(drawn)) == {4, 17, 33, 49}
    assert stats.chisquare(np.bincount(drawn)[[4, 17, 33, 49]]).pvalue > 1e-3


def test_negamax_returns_by_hand() -> None:
    """Three plies of one game, the third mating: with a discount of -γ each mover's return is its own reward
    minus γ times the next mover's return (λ-weighted with the next value)."""
    gamma, lam = 0.9, 0.5
    rewards = jnp.array([[0.0], [0.0], [1.0]])
    terminated = jnp.array([[False], [False], [True]])
    values = jnp.array([[0.2], [-0.4], [0.7]])  # each next position's value to the side to move there
    returns = np.asarray(lambda_returns(rewards, terminated, jnp.zeros_like(terminated), values, -gamma, lam))[:, 0]
    g2 = 1.0
    g1 = 0.0 - gamma * ((1 - lam) * -0.4 + lam * g2)
    g0 = 0.0 - gamma * ((1 - lam) * 0.2 + lam * g1)
    np.testing.assert_allclose(returns, [g0, g1, g2], rtol=1e-6)
    assert returns[1] < 0 < returns[0]  # the side mated loses; the side that mates wins, two plies back


def test_the_games_are_registered_as_two_player_games() -> None:
    game = jax_env("gardner_chess")
    assert is_game(game)
    assert not is_game(jax_env("CartPole-v1"))
    assert game.observation_shape == (5, 5, 17)
    assert jax_env("chess").observation_shape == (8, 8, 21)


@pytest.mark.slow("compiles pgx's chess step")
@float64
def test_the_mover_is_rewarded_for_mate_and_every_move_is_from_its_side() -> None:
    """Fool's mate in pgx's chess: +1 to the side that mates, the observation always from the side to move."""
    import chess

    from rlcompare.deep.chess.board import action_of

    game = chess_game_env("chess")
    step, observe = jax.jit(game.step), jax.jit(game.observe)
    state = game.reset(jax.random.key(0))
    board = chess.Board()
    rewards = []
    for uci in ("f2f3", "e7e5", "g2g4", "d8h4"):
        move = chess.Move.from_uci(uci)
        mine_before = np.asarray(observe(state))[..., :6].sum()
        assert mine_before == len([p for p in board.piece_map().values() if p.color == board.turn])
        state, reward, terminated, _ = step(state, jnp.int32(action_of(state, move)))
        board.push(move)
        rewards.append(float(reward))
    assert rewards == [0.0, 0.0, 0.0, 1.0]
    assert bool(terminated)
    assert board.is_checkmate()


@pytest.mark.slow("plays 64 games of Gardner's minichess twice in pgx, compiling each")
@float64
def test_the_material_player_beats_the_random_player_and_random_is_even_with_itself() -> None:
    game = chess_game_env("gardner_chess")
    key = jax.random.key(3)
    even, _, _ = jax.jit(lambda k: play(game, random_mover, random_mover, k, 256))(key)
    material, plies, decided = jax.jit(lambda k: play(game, material_mover, random_mover, k, 256))(key)
    assert abs(float(np.mean(even))) < 0.15
    assert float(np.mean(material)) > 0.12  # it takes what it can, but mates only by chance: mostly draws
    assert int(np.max(plies)) <= 256
    assert np.all(np.asarray(decided) == (np.asarray(material) != 0))


@pytest.mark.slow("steps pgx's chess through 40 plies of 5 random games, jitted")
@float64
def test_the_material_player_counts_captures_as_python_chess_does() -> None:
    """What each legal move takes, in pgx (the ladder's games in JAX) and on python-chess's board (its games
    against Stockfish), en passant included."""
    import chess

    from rlcompare.deep.chess.board import legal_actions, move_of
    from rlcompare.players.basic import captured_value

    game = chess_game_env("chess")
    step, captures = jax.jit(game.step), jax.jit(game.captures)
    rng = np.random.default_rng(0)
    en_passant_seen = 0
    for start in ("rnbqkbnr/pppppppp/8/8/8/8/PPPPPPPP/RNBQKBNR w KQkq - 0 1",
                  "rnbqkbnr/ppp1p1pp/8/3pPp2/8/8/PPPP1PPP/RNBQKBNR w KQkq f6 0 3"):
        for _ in range(3 if start.startswith("rnbqkbnr/pppp") else 1):
            board = chess.Board(start)
            from rlcompare.deep.chess.board import state_of

            state = state_of(board)
            for _ply in range(40):
                values = np.asarray(captures(state))
                for action in legal_actions(state):
                    move = move_of(state, action)
                    assert values[action] == captured_value(board, move), (board.fen(), move)
                    en_passant_seen += board.is_en_passant(move)
                if board.is_game_over():
                    break
                action = int(rng.choice(legal_actions(state)))
                board.push(move_of(state, action))
                state, *_ = step(state, jnp.int32(action))
    assert en_passant_seen >= 1


@pytest.mark.slow("builds a PQN program on Gardner's game")
def test_only_pqn_plays_a_two_player_game() -> None:
    from rlcompare.deep.config import DeepConfig
    from rlcompare.validation import ConfigError

    with pytest.raises(ConfigError, match=r"algorithm: got 'ppo'.*a PQN method for a two-player game"):
        DeepConfig(algorithm="ppo", env="gardner_chess", seeds=(0,))
    assert DeepConfig(algorithm="pqn_sarsa_lambda", env="gardner_chess", seeds=(0,)).environment.players == 2
