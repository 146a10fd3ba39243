"""Regenerate the shipped models built by :mod:`scdk_sym.builders` (SI units).

Run from the repository root: ``python models/generate.py`` (writes ``models/<name>/``).
The tests rebuild each model from :data:`ARGUMENTS` and compare it with the shipped files.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np


def ring(radius: float, centres_deg, spread_deg: float) -> np.ndarray:
    """(6, 3) points in pairs at polar angles ``centre -+ spread / 2`` on a circle [m]."""
    out = []
    for c in centres_deg:
        for side in (-1.0, 1.0):
            a = math.radians(c + side * spread_deg / 2)
            out.append([radius * math.cos(a), radius * math.sin(a), 0.0])
    return np.array(out)


#: Builder name -> keyword arguments of each shipped model.
ARGUMENTS = {
    "stewart_gough": {
        "base_points": ring(0.50, (0.0, 120.0, 240.0), 20.0),
        # each base pair joins the two platform anchors nearest to it (at -+50 deg)
        "platform_points": ring(0.30, (60.0, 180.0, 300.0), 20.0)[[5, 0, 1, 2, 3, 4]],
        "home_x": (0.0, 0.0, 0.55, 0.0, 0.0, 0.0),
    },
    "planar_3rpr": {
        "base_points": [[0.0, 0.0], [1.0, 0.0], [0.4, 0.9]],
        "platform_points": [[0.0, 0.0], [0.3, 0.0], [0.1, 0.25]],
        "home_x": (0.35, 0.25, 0.3),
    },
    "delta": {
        # base triangle side f = 457.3 mm, effector side e = 115.0 mm, rf = 112.0 mm,
        # re = 232.0 mm: radii are the inradii f / (2 sqrt 3) and e / (2 sqrt 3)
        "base_radius": 0.4573 / (2 * math.sqrt(3)),
        "platform_radius": 0.1150 / (2 * math.sqrt(3)),
        "arm": 0.112,
        "rod": 0.232,
    },
    "hexa": {
        "base_radius": 0.20,
        "platform_radius": 0.10,
        "arm": 0.20,
        "rod": 0.40,
        "base_spread": 0.4,
        "platform_spread": 1.6,
    },
    "five_bar": {
        "base_points": [[-0.10, 0.0], [0.10, 0.0]],
        "arm": 0.20,
        "rod": 0.25,
    },
}


def build(name: str):
    """The model ``name`` built from :data:`ARGUMENTS`."""
    from scdk_sym import builders

    return getattr(builders, name)(**ARGUMENTS[name])


def main(argv: list[str] | None = None) -> int:
    here = Path(__file__).resolve().parent
    for name in argv or list(ARGUMENTS):
        build(name).save(here / name)
        print(f"wrote {here / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
