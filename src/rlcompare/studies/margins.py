"""Every margin a verdict reads, in one table, each with its reason, declared before any run was read
(``docs/why.md``, "Every margin, its reason and its power"); what the seeds can prove of each is
:mod:`rlcompare.stats.power`'s."""

from __future__ import annotations

from dataclasses import dataclass

from rlcompare.stats.claims import RATIO_FACTOR


@dataclass(frozen=True)
class Margin:
    """A bound below which a difference counts as none (or, for a ratio, a band around the claimed factor)."""

    study: str
    bounds: str
    """What it bounds, as the report names it."""
    value: float
    unit: str
    reason: str


MARGINS = {m.study + ": " + m.bounds: m for m in (
    Margin("paper", "a similar time frame (convergence)", 0.1, "share of the training's episodes",
           "the paper reads its Table I's 13.8 against 11.5 (17% of the larger) as a similar time frame; a tenth "
           "of the training (500 of 5000 episodes) holds that reading"),
    Margin("paper", "the same solution (greedy return)", 20.0, "return per episode",
           "the paper calls -174 and -191 the same solution: 17 apart; 20 holds its own reading"),
    Margin("paper", "about R times (ratio)", RATIO_FACTOR, "factor on either side of R",
           "the 80-125% band of average bioequivalence (FDA 2001), the field's convention for 'about' a ratio"),
    Margin("deep", "CartPole-v1 (final greedy return)", 25.0, "return per episode",
           "5% of the return's range (0 to 500)"),
    Margin("deep", "Acrobot-v1 (final greedy return)", 25.0, "return per episode",
           "5% of the return's range (-500 to 0)"),
    Margin("deep", "MountainCar-v0 (final greedy return)", 10.0, "return per episode",
           "5% of the return's range (-200 to 0)"),
    Margin("minatar", "a game (final greedy return)", 0.1, "share of the random-to-reference range",
           "a tenth of the way from the random policy's return to the MinAtar paper's DQN at 5 M frames, in the "
           "game's own points (Breakout 0.95, Space Invaders 4.0, Asterix 1.6), as human-normalised scores are read "
           "on the Atari 2600; one point, the margin before, was a sixth of what Breakout's "
           "learners had learnt at the short budget and a thirtieth of Space Invaders'"),
    Margin("minatar", "learnt (final greedy return above random)", 0.1, "share of the random-to-reference range",
           "a method has learnt a game when its final greedy return beats the random policy's by a tenth of the "
           "random-to-reference range (one-sided signed-rank test, α = 0.05): below it, a verdict would be about "
           "two policies that have learnt nothing yet"),
    Margin("minatar", "over the games (normalised score)", 0.05, "normalised score",
           "5% of the distance from a random policy (0) to the MinAtar paper's DQN at 5 M frames (1), game by game"),
    Margin("atari", "a game (final return)", 0.1, "share of the random-to-human range",
           "a tenth of the way from the published random score to the published human score (human-normalised 0.1), "
           "in the game's own points (Breakout 2.9, Pong 3.5): the unit every Atari paper reads, and a tenth of it "
           "is a gap that separates published agents"),
    Margin("atari", "learnt (final return above random)", 0.05, "share of the random-to-human range",
           "a method has learnt a game when its final return beats the published random score by a twentieth of the "
           "random-to-human range (one-sided signed-rank test, α = 0.05): Atari's budgets are short beside the "
           "games' scale, and a twentieth still rules out a policy no better than chance"),
    Margin("atari", "over the games (human-normalised score)", 0.05, "human-normalised score",
           "5% of the distance from the random score (0) to the human score (1), game by game, as MinAtar's overall "
           "margin"),
    Margin("chess-endgames", "mate rate", 0.05, "share of the evaluation starts",
           "ten of the 200 evaluation starts: below it two policies mate from the same positions but a handful"),
    Margin("chess-endgames", "optimal share", 0.05, "share of the evaluation starts",
           "as the mate rate's: ten of the 200 starts mated in the fewest moves"),
    Margin("chess-endgames", "excess moves", 0.5, "moves per mated game",
           "half a move per game: a chess player counts moves, and less than one in every second game is no "
           "difference in technique"),
    Margin("chess-endgames", "behaviour return", 0.05, "mates per training episode",
           "the return is 1 at mate and 0 otherwise, so 0.05 is one more mate in twenty games while learning"),
    Margin("chess-endgames", "episodes to hold", 0.1, "share of the training's episodes",
           "as the paper's similar time frame: a tenth of the budget"),
    Margin("chess", "a game (result against the random player)", 0.1, "share of the random-to-perfect range",
           "a tenth of the way from the random player's result against itself (0) to winning every game (+1): five "
           "points in a hundred games of score, about 35 Elo near an even score"),
    Margin("chess", "learnt (result above the random player's)", 0.1, "share of the random-to-perfect range",
           "a network has learnt the game when it beats the random player by a tenth of that range (a score of "
           "0.55; one-sided signed-rank test, α = 0.05)"),
    Margin("book 6.3", "Expected SARSA at least as good as SARSA", 1.0, "return per episode",
           "one step of Cliff Walking's -1 per step: less than a step per episode is no difference"),
    Margin("book 6.3", "an asymptote collapses", 5.0, "return per episode",
           "5 steps per episode, against the book's axis from -160 to 0"),
)}
"""Every margin, by ``"<study>: <what it bounds>"``."""


def margin(study: str, bounds: str) -> float:
    return MARGINS[f"{study}: {bounds}"].value
