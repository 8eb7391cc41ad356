"""Players of a game that are not learners, and games between players: a random and a material player, Stockfish, a
learnt endgame table on python-chess boards, any player served as a UCI engine (a bot is a room of its own, as in
OpenSpiel)."""
