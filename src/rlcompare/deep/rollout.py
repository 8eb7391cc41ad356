"""What every deep method shares: episode bookkeeping inside the jitted loop, greedy evaluation, the shape of
a training's output, and training in rounds of updates with an evaluation after each round."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from rlcompare.deep.envs import (
    Environment,
    GameEnv,
    evaluation_epsilon,
    is_game,
    observe_all,
    reset_all,
    step_all,
)

Params = Any
Act = Callable[..., jax.Array]
"""``(params, observations) -> greedy actions``; in a two-player game ``(params, observations, legal)``."""


class Episodes(NamedTuple):
    """Running return and length of each parallel environment's current episode."""

    returns: jax.Array
    """(envs,) float32"""
    lengths: jax.Array
    """(envs,) int32"""

    @classmethod
    def start(cls, n_envs: int) -> Episodes:
        return cls(jnp.zeros(n_envs, jnp.float32), jnp.zeros(n_envs, jnp.int32))


class Finished(NamedTuple):
    """Per environment step, which episodes ended and with what return and length (meaningful where ``done``)."""

    done: jax.Array
    returns: jax.Array
    lengths: jax.Array
    terminated: jax.Array


def track(episodes: Episodes, reward: jax.Array, terminated: jax.Array, truncated: jax.Array
          ) -> tuple[Episodes, Finished]:
    """Add one step to each running episode; report and restart those that ended."""
    returns = episodes.returns + reward.astype(jnp.float32)
    lengths = episodes.lengths + 1
    done = terminated | truncated
    restarted = Episodes(jnp.where(done, 0.0, returns).astype(jnp.float32), jnp.where(done, 0, lengths))
    return restarted, Finished(done, returns, lengths, terminated)


STAGES = (("early", 0.1), ("middle", 0.5))
"""The stages of learning kept besides the final network, as shares of the training (the tabular engine's
``DEFAULT_STAGES``): the paper shows its agents "in three stages of learning"."""


def stage_rounds(rounds: int) -> tuple[int, ...]:
    """The round after which each of :data:`STAGES` is kept (0-based; at least the first round)."""
    return tuple(max(1, round(share * rounds)) - 1 for _, share in STAGES)


class TrainOutput(NamedTuple):
    """What one seed's training returns (a leading seed axis under ``vmap``)."""

    params: Params
    """The final parameters of the greedy policy."""
    snapshots: Params
    """The greedy policy's parameters after each of :func:`stage_rounds`, with a leading stage axis."""
    finished: Finished
    """(rounds, updates per round, steps per update, envs): the training episodes as they ended."""
    eval_returns: jax.Array
    """(rounds, eval episodes) greedy returns after each round."""
    eval_lengths: jax.Array
    eval_terminated: jax.Array
    finite: jax.Array
    """(rounds, updates per round): whether every parameter was finite after each update (a diverged training's
    are not, and its greedy policy is a network of NaNs)."""


Evaluating = tuple[jax.Array, Any, jax.Array, jax.Array, jax.Array, jax.Array]
"""An evaluation in progress: the step, the environments' states, which episodes are running, and each one's
return, length and whether it terminated."""

EVALUATION_STEPS = 27_000
"""Where a greedy evaluation stops an episode that has no limit of its own (MinAtar under its paper's protocol):
the 108,000 frames of 4 that Machado et al. (2018) allow an Atari evaluation episode."""


def evaluation_limit(env: Environment) -> int:
    return env.max_steps or EVALUATION_STEPS


def evaluate(env: Environment, act: Act, params: Params, key: jax.Array, episodes: int, epsilon: float = 0.0
             ) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Greedy episodes run side by side until each has ended or :func:`evaluation_limit` steps have passed:
    ``(returns, lengths, terminated)``, each ``(episodes,)``. The environments' own draws come from ``key``
    folded with 1 and the step. With ``epsilon``, each action is uniformly random with that chance (DQN's
    evaluation takes 0.05; 1 is the uniformly random policy)."""
    if is_game(env):  # the greedy policy against the uniformly random player
        return play(env, policy_mover(act, params, epsilon), random_mover, key, episodes)
    states = reset_all(env, jax.random.split(key, episodes), role="evaluation")
    step_key = jax.random.fold_in(key, 1)
    limit = evaluation_limit(env)

    def going(carry: Evaluating) -> jax.Array:
        t, _, running, *_ = carry
        return (t < limit) & jnp.any(running)

    def one_step(carry: Evaluating) -> Evaluating:
        t, state, running, returns, lengths, terminated = carry
        action = act(params, observe_all(env, state))
        keys = jax.random.split(jax.random.fold_in(step_key, t), episodes)
        if epsilon > 0.0:
            explore_key, action_key = jax.random.split(jax.random.fold_in(key, 2 + t))
            random_actions = jax.random.randint(action_key, (episodes,), 0, env.n_actions)
            action = jnp.where(jax.random.uniform(explore_key, (episodes,)) < epsilon, random_actions, action)
        state, reward, term, trunc = step_all(env, state, action, keys, role="evaluation")
        returns = returns + jnp.where(running, reward, 0.0).astype(jnp.float32)
        lengths = lengths + running.astype(jnp.int32)
        terminated = terminated | (running & term)
        return t + 1, state, running & ~(term | trunc), returns, lengths, terminated

    start = (jnp.zeros((), jnp.int32), states, jnp.ones(episodes, bool), jnp.zeros(episodes, jnp.float32),
             jnp.zeros(episodes, jnp.int32), jnp.zeros(episodes, bool))
    _, _, _, returns, lengths, terminated = jax.lax.while_loop(going, one_step, start)
    return returns, lengths, terminated


Mover = Callable[[GameEnv, Any, jax.Array], jax.Array]
"""``(game, states, key) -> moves``: a fixed player of a two-player game, for a batch of positions."""


def random_mover(game: GameEnv, states: Any, key: jax.Array) -> jax.Array:
    """The uniformly random player: any legal move, each as likely."""
    legal = jax.vmap(game.legal)(states)
    return jnp.argmax(jnp.where(legal, jax.random.uniform(key, legal.shape), -1.0), axis=-1)


def material_mover(game: GameEnv, states: Any, key: jax.Array) -> jax.Array:
    """The one-ply material player: a move that takes the most valuable piece it can, else any legal move, drawn
    uniformly among the equals."""
    legal = jax.vmap(game.legal)(states)
    gain = jnp.where(legal, jax.vmap(game.captures)(states), -1.0)
    best = gain == jnp.max(gain, axis=-1, keepdims=True)
    return jnp.argmax(jnp.where(best, jax.random.uniform(key, legal.shape), -1.0), axis=-1)


def policy_mover(act: Act, params: Params, epsilon: float = 0.0) -> Mover:
    """The greedy policy of ``params`` as a player: its best legal move, or with chance ``epsilon`` any legal move."""
    def move(game: GameEnv, states: Any, key: jax.Array) -> jax.Array:
        chosen = act(params, observe_all(game, states), jax.vmap(game.legal)(states))
        if epsilon == 0.0:
            return chosen
        explore_key, random_key = jax.random.split(key)
        explore = jax.random.uniform(explore_key, chosen.shape) < epsilon
        return jnp.where(explore, random_mover(game, states, random_key), chosen)

    return move


def play(game: GameEnv, player: Mover, opponent: Mover, key: jax.Array, games: int
         ) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Games of ``player`` against ``opponent`` side by side, ``player`` taking the first side (White) in the even
    games and the second in the odd ones: ``(results, plies, decided)``, each ``(games,)``, a result being
    ``player``'s +1 (won), 0 (drawn) or -1 (lost). The game's own end stops each; the loop ends when all have."""
    states = jax.vmap(game.reset)(jax.random.split(key, games))
    results, plies, decided, _ = _played(game, player, opponent, key, states, games, digest=False)
    return results, plies, decided


def play_from(game: GameEnv, player: Mover, opponent: Mover, key: jax.Array, states: Any
              ) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """:func:`play` from the given positions (``states``, a batch: ``player`` White in the even ones), with each
    game's identity: ``(results, plies, decided, digest)``, ``digest`` ``(games, 2)`` uint32, two polynomial hashes
    of the moves played (Karp and Rabin's rolling hash, on two multipliers), equal for equal move sequences."""
    games = jax.tree.leaves(states)[0].shape[0]
    return _played(game, player, opponent, key, states, games, digest=True)


DIGEST_MULTIPLIERS = (1_000_003, 2_654_435_761)
"""The multipliers of :func:`play_from`'s two move hashes (mod 2^32): a prime and Knuth's golden-ratio constant."""


def _played(game: GameEnv, player: Mover, opponent: Mover, key: jax.Array, states: Any, games: int, digest: bool
            ) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    unused = jax.random.split(key, games)  # the game's step draws nothing
    player_side = jnp.arange(games) % 2
    multipliers = jnp.asarray(DIGEST_MULTIPLIERS, jnp.uint32)

    def going(carry: tuple[Any, ...]) -> jax.Array:
        return jnp.any(carry[2])

    def one_ply(carry: tuple[Any, ...]) -> tuple[Any, ...]:
        t, state, running, results, plies, decided, *hashes = carry
        player_moves = jax.vmap(game.colour)(state) == player_side
        player_key, opponent_key = jax.random.split(jax.random.fold_in(key, t))
        move = jnp.where(player_moves, player(game, state, player_key), opponent(game, state, opponent_key))
        if digest:
            rolled = hashes[0] * multipliers + (move.astype(jnp.uint32) + jnp.uint32(1))[:, None]
            hashes = [jnp.where(running[:, None], rolled, hashes[0])]
        state, reward, term, _ = step_all(game, state, move, unused)
        result = jnp.where(player_moves, reward, -reward)
        results = results + jnp.where(running, result, 0.0).astype(jnp.float32)
        return (t + 1, state, running & ~term, results, plies + running.astype(jnp.int32),
                decided | (running & term & (reward != 0)), *hashes)

    start = (jnp.zeros((), jnp.int32), states, jnp.ones(games, bool), jnp.zeros(games, jnp.float32),
             jnp.zeros(games, jnp.int32), jnp.zeros(games, bool), *([jnp.zeros((games, 2), jnp.uint32)] * digest))
    _, _, _, results, plies, decided, *hashes = jax.lax.while_loop(going, one_ply, start)
    return results, plies, decided, hashes[0] if digest else jnp.zeros((games, 2), jnp.uint32)


def all_finite(params: Params) -> jax.Array:
    """Whether every parameter is finite: a scalar bool."""
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(leaf)) for leaf in jax.tree.leaves(params)]))


def train_in_rounds(update: Callable[[Any, jax.Array], tuple[Any, Finished]], params_of: Callable[[Any], Params],
                    env: Environment, act: Act, rounds: int, updates_per_round: int, eval_episodes: int
                    ) -> Callable[[Any, jax.Array], TrainOutput]:
    """``(runner, key) -> TrainOutput``: ``rounds`` x ``updates_per_round`` calls of ``update(runner, key) ->
    (runner, finished)`` (``finished`` stacked over an update's steps), a greedy evaluation after each round, and
    the parameters kept at each stage of learning."""
    kept_after = jnp.asarray(stage_rounds(rounds))

    def checked_update(runner: Any, key: jax.Array) -> tuple[Any, tuple[Finished, jax.Array]]:
        runner, finished = update(runner, key)
        return runner, (finished, all_finite(params_of(runner)))

    def one_round(carry: tuple[Any, Params], round_and_key: tuple[jax.Array, jax.Array]
                  ) -> tuple[tuple[Any, Params], tuple[Finished, jax.Array, jax.Array, jax.Array, jax.Array]]:
        runner, snapshots = carry
        index, key = round_and_key
        update_key, eval_key = jax.random.split(key)
        runner, (finished, finite) = jax.lax.scan(checked_update, runner,
                                                  jax.random.split(update_key, updates_per_round))
        params = params_of(runner)
        returns, lengths, terminated = evaluate(env, act, params, eval_key, eval_episodes, evaluation_epsilon(env))
        keep = kept_after == index
        snapshots = jax.tree.map(
            lambda kept, now: jnp.where(keep.reshape((-1,) + (1,) * now.ndim), now[None], kept), snapshots, params)
        return (runner, snapshots), (finished, returns, lengths, terminated, finite)

    def train(runner: Any, key: jax.Array) -> TrainOutput:
        empty = jax.tree.map(lambda leaf: jnp.zeros((len(STAGES), *leaf.shape), leaf.dtype), params_of(runner))
        (runner, snapshots), (finished, returns, lengths, terminated, finite) = jax.lax.scan(
            one_round, (runner, empty), (jnp.arange(rounds), jax.random.split(key, rounds)))
        return TrainOutput(params_of(runner), snapshots, finished, returns, lengths, terminated, finite)

    return train
