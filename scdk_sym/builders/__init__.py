"""Builders of parametric closed-chain models (each returns a loaded :class:`Model`)."""

from .planar import planar_3rrr, planar_3rrr_reduced, seed_geometry

__all__ = ["planar_3rrr", "planar_3rrr_reduced", "seed_geometry"]
