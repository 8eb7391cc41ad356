"""Sutton and Barto's figures, and on- against off-policy across their problems."""
