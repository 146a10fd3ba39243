"""Atlases: direct kinematics over large joint grids, chunked on Dask, stored in Zarr.

* :mod:`~scdk_sym.atlases.grid`: ``NAME=lo:hi:n`` grids and their C-order flattening;
* :mod:`~scdk_sym.atlases.chunk`: one chunk on a worker (the C tracker library's sweep, each
  grid point continued from its neighbour, then ``sc.solve`` for the points it leaves);
* :mod:`~scdk_sym.atlases.store`: the Zarr layout, done-markers and the run check;
* :mod:`~scdk_sym.atlases.run`: :func:`atlas`, the client loop (local, LocalCluster or a
  scheduler address);
* :mod:`~scdk_sym.atlases.plot`: 2-D slices of a store.
"""

from .chunk import STATUS
from .grid import Axis, Grid, make_grid
from .run import AtlasRun, atlas
from .store import open_atlas

__all__ = ["STATUS", "AtlasRun", "Axis", "Grid", "atlas", "make_grid", "open_atlas"]
