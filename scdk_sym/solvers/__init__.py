"""Solvers: solve, track, assembly modes and transmissions of a loaded model."""
