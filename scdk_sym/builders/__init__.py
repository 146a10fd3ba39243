"""Builders of parametric closed-chain models (each returns a loaded :class:`Model`)."""

from .planar import planar_3rrr, planar_3rrr_reduced, seed_geometry
from .spatial import stewart_gough

__all__ = ["planar_3rrr", "planar_3rrr_reduced", "seed_geometry", "stewart_gough"]
