"""Standalone C for real-time direct kinematics: generated kernels and a tracker.

:func:`generate` writes self-contained C sources and headers of a model's tracker (no
CasADi headers or runtime); :func:`tracker_library` compiles the same sources into a cached
shared library and loads it with ctypes (used by :func:`scdk_sym.solvers.track_c.track_c`).
"""

from .generate import GeneratedSources, compile_library, generate
from .library import CTracker, Options, tracker_library

__all__ = [
    "CTracker",
    "GeneratedSources",
    "Options",
    "compile_library",
    "generate",
    "tracker_library",
]
