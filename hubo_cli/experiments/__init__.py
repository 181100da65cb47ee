"""Experiments that reproduce the papers' evaluations on the simulated robot."""
