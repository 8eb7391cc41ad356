"""Chess endgames and pgx's whole games as facts and compiled rules: the endgames by name, their rules equal to python-
chess's, the exact solver, the environment, pgx's games."""
