"""Builders of parametric closed-chain models (each returns a loaded :class:`Model`)."""

from .planar import five_bar, planar_3rpr, planar_3rrr, planar_3rrr_reduced, seed_geometry
from .spatial import delta, hexa, stewart_gough, three_rps

__all__ = [
    "delta",
    "five_bar",
    "hexa",
    "planar_3rpr",
    "planar_3rrr",
    "planar_3rrr_reduced",
    "seed_geometry",
    "stewart_gough",
    "three_rps",
]
