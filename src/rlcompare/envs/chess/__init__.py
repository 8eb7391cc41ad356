"""Chess as facts and compiled rules: the endgames by name, their rules equal to python-chess's, the exact solver,
the endgame environment, and pgx's whole games as facts."""
