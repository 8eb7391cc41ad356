"""MinAtar's five games in JAX: gymnax's, with the reference package's rules where gymnax departs from them."""
