"""The Atari 2600 as a study: human-normalised answers and agents that play ALE."""
