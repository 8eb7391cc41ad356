"""Chess as studies: the endgames against the exact solver, and the whole game in self-play rated on a ladder."""
