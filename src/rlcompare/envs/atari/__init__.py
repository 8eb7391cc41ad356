"""The Atari 2600 as Gymnasium's ALE plays it: the protocol, the 57 games, their published random and human scores."""
