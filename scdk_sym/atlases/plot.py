"""2-D slices of an atlas store: status, sign of det J_p and assembly-mode count.

One PNG with a panel per quantity over two grid axes, the other axes fixed at given values
(nearest grid value; default the middle one). matplotlib is imported lazily, on its Agg
canvas, as in :mod:`scdk_sym.plot`; only the slice's points are read from the store.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import InputError, UnknownNameError
from ..plot import PlotError, new_figure, save_figure
from .chunk import STATUS
from .store import open_atlas

#: Colours of the status codes (and of points not written yet, -1).
STATUS_COLORS = {
    -1: "#ffffff",
    0: "#4c9be8",
    1: "#d9d9d9",
    2: "#e8554c",
    3: "#8c564b",
    4: "#111111",
    5: "#f2f2f2",
}


def _slice(meta: dict, axes: tuple[str, str] | None, at: Mapping[str, float] | None):
    grid = meta.get("grid")
    if not grid:
        raise PlotError("plot-atlas draws grid stores; this one holds explicit theta rows")
    names = [a["name"] for a in grid["axes"]]
    if len(names) < 2:
        raise PlotError(f"plot-atlas needs a grid of at least two axes, got {names}")
    axes = axes or (names[0], names[1])
    if len(axes) != 2 or axes[0] == axes[1]:
        raise InputError(f"--axes: expected two different grid axes, got {list(axes)}")
    for a in (*axes, *(at or {})):
        if a not in names:
            raise UnknownNameError("grid joint", a, names)
    values = [np.linspace(a["lo"], a["hi"], a["n"]) for a in grid["axes"]]
    index: list = []
    fixed = {}
    for name, v in zip(names, values, strict=True):
        if name in axes:
            index.append(slice(None))
        else:
            j = int(np.argmin(np.abs(v - at[name]))) if at and name in at else len(v) // 2
            index.append(j)
            fixed[name] = float(v[j])
    shape = [len(v) for v in values]
    mesh = np.ix_(
        *[np.arange(n) if isinstance(i, slice) else [i] for i, n in zip(index, shape, strict=True)]
    )
    flat = np.ravel_multi_index(np.broadcast_arrays(*mesh), shape).reshape(
        [n for i, n in zip(index, shape, strict=True) if isinstance(i, slice)]
    )
    if names.index(axes[0]) > names.index(axes[1]):
        flat = flat.T
    return axes, [values[names.index(a)] for a in axes], flat, fixed


def plot_atlas(
    store: str | Path,
    out: str | Path,
    axes: tuple[str, str] | None = None,
    at: Mapping[str, float] | None = None,
) -> Path:
    """Draw a 2-D slice of an atlas store.

    Args:
        store: the atlas store (written by :func:`scdk_sym.atlas`).
        out: the PNG path.
        axes: the grid axes on the horizontal and vertical axes (default: the first two).
        at: values of the other grid axes (nearest grid value; default: the middle one).

    Returns:
        The PNG path.

    Raises:
        PlotError: not a grid store, matplotlib missing, unwritable path.
        UnknownNameError: an axis name that is not a grid axis.
    """
    group = open_atlas(store)
    meta = dict(group.attrs["scdk_atlas"])
    axes, (u, v), flat, fixed = _slice(meta, axes, at)
    sel = flat.ravel()
    status = np.asarray(group["status"].get_coordinate_selection(sel)).reshape(flat.shape)
    det = np.asarray(group["det_jp"].get_coordinate_selection(sel)).reshape(flat.shape)
    panels = [("status", status), ("sign of det J_p", det)]
    if "n_modes" in group:
        nm = np.asarray(group["n_modes"].get_coordinate_selection(sel)).reshape(flat.shape)
        panels.append(("real assembly modes", nm))

    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    fig = new_figure(4.6 * len(panels), 4.8)
    model = meta["model"]["name"]
    held = {**fixed, **meta["grid"].get("fixed", {})}  # other axes, and joints not in the grid
    where = ", ".join(f"{k} = {val:.4g}" for k, val in held.items())
    fig.suptitle(f"atlas of {model}" + (f" at {where}" if where else ""), fontsize=11)
    for j, (title, data) in enumerate(panels):
        ax = fig.add_subplot(1, len(panels), j + 1)
        handles = []
        if title == "status":
            codes = sorted(STATUS_COLORS)
            cmap = ListedColormap([STATUS_COLORS[c] for c in codes])
            norm = BoundaryNorm(np.arange(codes[0] - 0.5, codes[-1] + 1), cmap.N)
            ax.pcolormesh(u, v, data.T, cmap=cmap, norm=norm, shading="nearest")
            present = sorted(set(np.unique(data).tolist()))
            names = {**{c: STATUS[c].split(":")[0] for c in STATUS}, -1: "not computed"}
            handles = [
                Patch(facecolor=STATUS_COLORS[c], edgecolor="0.5", label=f"{c}: {names[c]}")
                for c in present
            ]
        elif title.startswith("sign"):
            sign = np.where(np.isfinite(det), np.sign(det), 0)
            cmap = ListedColormap(["#e8554c", "#d9d9d9", "#4c9be8"])
            ax.pcolormesh(u, v, sign.T, cmap=cmap, vmin=-1.5, vmax=1.5, shading="nearest")
            handles = [
                Patch(facecolor="#4c9be8", label="det J_p > 0"),
                Patch(facecolor="#e8554c", label="det J_p < 0"),
                Patch(facecolor="#d9d9d9", label="not solved"),
            ]
        else:
            top = max(1, int(np.max(data)))
            cmap = ListedColormap(["#d9d9d9"] + [tuple(c) for c in _viridis(top + 1)])
            norm = BoundaryNorm(np.arange(-1.5, top + 1), cmap.N)
            mesh = ax.pcolormesh(u, v, data.T, cmap=cmap, norm=norm, shading="nearest")
            bar = fig.colorbar(mesh, ax=ax, ticks=range(-1, top + 1), fraction=0.05)
            bar.set_label("count (-1: search failed)")
            edges = count_boundaries(u, v, data)
            if len(edges):
                from matplotlib.collections import LineCollection

                ax.add_collection(LineCollection(list(edges), colors="k", linewidths=1.0))
                handles = [Line2D([], [], color="k", lw=1.0, label="count changes: singular")]  # type: ignore[list-item]
        ax.set_title(title, fontsize=10)
        ax.set_xlabel(axes[0])
        ax.set_ylabel(axes[1])
        if handles:
            ax.legend(
                handles=handles,
                loc="upper center",
                bbox_to_anchor=(0.5, -0.14),
                ncol=2 if len(handles) > 2 else len(handles),
                fontsize=7,
                frameon=False,
            )
    fig.tight_layout()
    return save_figure(fig, out)


def count_boundaries(u: np.ndarray, v: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Cell edges between grid neighbours of different assembly-mode counts.

    Two modes meet (``det J_p = 0``) on a singular curve, where the real count changes: these
    edges are the singular curves of the slice as the grid resolves them. Neighbours where
    either count is unknown (-1) are skipped.

    Args:
        u: (nu,) values of the horizontal axis.
        v: (nv,) values of the vertical axis.
        counts: (nu, nv) counts of the slice.

    Returns:
        (E, 2, 2) segments ``[[u0, v0], [u1, v1]]`` in axis units.
    """
    du = np.diff(u) / 2 if len(u) > 1 else np.ones(1)
    dv = np.diff(v) / 2 if len(v) > 1 else np.ones(1)
    known = counts >= 0
    segs = []
    for i, j in zip(*np.nonzero((counts[1:] != counts[:-1]) & known[1:] & known[:-1]), strict=True):
        um = u[i] + du[i]  # between columns i and i + 1
        lo = v[j] - (dv[j - 1] if j > 0 else dv[0])
        hi = v[j] + (dv[j] if j < len(dv) else dv[-1])
        segs.append([[um, lo], [um, hi]])
    for i, j in zip(
        *np.nonzero((counts[:, 1:] != counts[:, :-1]) & known[:, 1:] & known[:, :-1]), strict=True
    ):
        vm = v[j] + dv[j]
        lo = u[i] - (du[i - 1] if i > 0 else du[0])
        hi = u[i] + (du[i] if i < len(du) else du[-1])
        segs.append([[lo, vm], [hi, vm]])
    return np.array(segs, dtype=float).reshape(-1, 2, 2)


def _viridis(n: int) -> np.ndarray:
    from matplotlib import colormaps

    return colormaps["viridis"](np.linspace(0.1, 0.95, n))
