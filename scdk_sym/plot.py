"""Figures like the paper's Figs. 4-6 (PNG, headless matplotlib) and of tracked motions.

* :func:`plot_configurations` (Fig. 4): the robot drawn in the base x-y plane at several
  configurations (start, solutions, singular configuration).
* :func:`plot_det_jp` (Fig. 5): ``det J_p`` along ``s`` for the two branches of a solve.
* :func:`plot_phase` (Fig. 6): the phase plot ``s' = b det J_p`` against ``s``.
* :func:`plot_solve` writes all three for a solve on both branches.
* :func:`plot_track`: the pose components of a track against the sample index, with the
  singular-manifold crossings marked.

matplotlib is imported lazily (``pip install "scdk_sym[plot]"``) and used without pyplot, on
its Agg canvas, so it never changes the caller's backend.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from .drawing import RobotDrawing, placements, rigid_groups, robot_drawing, robot_drawing_3d
from .errors import InputError, PlotError
from .optional import require
from .results import Configuration, SolveResult, TrackResult
from .robot import Model, as_vector

#: Colours of the two branches (convergent, divergent) and of the singular configuration.
COLORS = {"convergent": "tab:blue", "divergent": "tab:orange", "singular": "tab:red"}


#: How to get the optional plotting dependency.
INSTALL_HINT = 'pip install "scdk_sym[plot]"'


def require_matplotlib() -> None:
    """Check that matplotlib can be imported.

    Raises:
        PlotError: it cannot (the message gives the install command).
    """
    require(
        ("matplotlib", "matplotlib.backends.backend_agg", "matplotlib.figure",
         "matplotlib.lines", "matplotlib.patches"),
        needed_for="figures",
        install=f"{INSTALL_HINT} (or pip install matplotlib)",
        error=PlotError,
    )  # fmt: skip


def new_figure(width: float = 6.0, height: float = 4.5):
    require_matplotlib()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=120)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig, path: str | Path) -> Path:
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(p, format="png")
    except OSError as exc:
        raise PlotError(f"cannot write figure {str(p)!r}: {exc.strerror or exc}") from exc
    return p


# ---------------------------------------------------------------------------- figures


def plot_configurations(
    model: Model,
    configurations: Sequence[tuple[str, Configuration, str]],
    path: str | Path,
    title: str | None = None,
) -> Path:
    """Draw configurations of the robot (the paper's Fig. 4) and write the PNG.

    Planar robots are drawn in the base x-y plane, spatial ones (e.g. a 6-6 platform) in 3-D
    (see :func:`configurations_figure`).

    Args:
        model: the model.
        configurations: (label, configuration, colour) triples, drawn in order.
        path: PNG file to write.
        title: figure title (default: the model name).

    Returns:
        The path written.
    """
    return save_figure(configurations_figure(model, configurations, title), path)


def is_spatial(model: Model, configurations: Sequence[Configuration]) -> bool:
    """Whether the drawn robot leaves a plane ``z = const`` in any of the configurations.

    Args:
        model: the model.
        configurations: the configurations to draw.

    Returns:
        True when the points of :func:`robot_drawing_3d` (bodies, segments, closures) spread
        along z by more than ``1e-9`` of the model's size [model length unit].
    """
    z: list[np.ndarray] = []
    for cfg in configurations:
        d = robot_drawing_3d(model, cfg)
        z += [P[:, 2] for P in (*d.polygons, *d.segments, *d.closures)]
    heights = np.concatenate(z) if z else np.zeros(1)
    return float(np.ptp(heights)) > 1e-9 * max(1.0, model.length_scale)


def configurations_figure(
    model: Model,
    configurations: Sequence[tuple[str, Configuration, str]],
    title: str | None = None,
):
    """The figure of :func:`plot_configurations` (a matplotlib ``Figure`` on an Agg canvas).

    Planar robots: one 2-D axes in the base x-y plane. Spatial robots
    (:func:`is_spatial`): one 3-D axes with the base, each rigid body outlined and filled,
    and every segment (legs, arms, distance closures) as a line from end to end.

    Args:
        model: the model.
        configurations: (label, configuration, colour) triples, drawn in order.
        title: figure title (default: the model name).

    Raises:
        PlotError: no configuration, or matplotlib is missing.
    """
    if not configurations:
        raise PlotError("no configuration to draw")
    require_matplotlib()
    if is_spatial(model, [cfg for _, cfg, _ in configurations]):
        return _configurations_3d(model, configurations, title)
    from matplotlib.lines import Line2D
    from matplotlib.patches import Polygon

    fig = new_figure(6.0, 6.0)
    ax = fig.add_subplot(1, 1, 1)
    handles = []
    for n, (label, cfg, color) in enumerate(configurations):
        polygons, segments = robot_drawing(model, cfg)
        style = "--" if label.startswith("start") else "-"
        base, polygons = polygons[0], polygons[1:]
        if n == 0 and len(base):  # the base does not move: drawn once
            ax.add_patch(Polygon(base, closed=True, facecolor="0.85", edgecolor="black",
                                 linewidth=1.2, zorder=0))  # fmt: skip
        for P in polygons:
            ax.add_patch(Polygon(P, closed=True, fill=True, alpha=0.12, facecolor=color,
                                 edgecolor=color, linestyle=style, linewidth=1.4))  # fmt: skip
        for S in segments:
            ax.plot(S[:, 0], S[:, 1], style, color=color, linewidth=1.6, marker="o",
                    markersize=3)  # fmt: skip
        handles.append(Line2D([], [], color=color, linestyle=style, label=label))  # type: ignore[arg-type]
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(title or f"{model.name}: configurations")
    ax.legend(handles=handles, loc="best", fontsize="small")
    fig.tight_layout()
    return fig


def _configurations_3d(model, configurations, title):
    """The 3-D figure of :func:`configurations_figure`."""
    from matplotlib.lines import Line2D
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = new_figure(6.5, 6.0)
    ax = fig.add_subplot(1, 1, 1, projection="3d")
    handles, seen = [], []
    for n, (label, cfg, color) in enumerate(configurations):
        drawing = robot_drawing_3d(model, cfg)
        style = "--" if label.startswith("start") else "-"
        base, polygons = drawing.polygons[0], drawing.polygons[1:]
        if n == 0 and len(base):  # the base does not move: drawn once
            ax.add_collection3d(Poly3DCollection([base], facecolor="0.85", edgecolor="black",
                                                 linewidth=1.2, alpha=0.6))  # fmt: skip
            seen.append(base)
        for P in polygons:
            face = Poly3DCollection([P], facecolor=color, edgecolor=color, linestyle=style,
                                    linewidth=1.4, alpha=0.25)  # fmt: skip
            ax.add_collection3d(face)
            seen.append(P)
        legs = [c for c, t in zip(drawing.closures, drawing.closure_types, strict=True)
                if t == "distance"]  # fmt: skip
        for S in (*drawing.segments, *legs):
            ax.plot(S[:, 0], S[:, 1], S[:, 2], style, color=color, linewidth=1.6, marker="o",
                    markersize=3)  # fmt: skip
            seen.append(S)
        handles.append(Line2D([], [], color=color, linestyle=style, label=label))  # type: ignore[arg-type]
    P = np.vstack(seen) if seen else np.zeros((1, 3))
    lo, hi = P.min(axis=0), P.max(axis=0)
    half = 0.5 * max(float(np.max(hi - lo)), 1e-9 * max(1.0, model.length_scale))
    mid = 0.5 * (lo + hi)
    ax.set_xlim(mid[0] - half, mid[0] + half)  # equal scales on the three axes
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(mid[2] - half, mid[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    ax.set_title(title or f"{model.name}: configurations")
    ax.legend(handles=handles, loc="upper left", fontsize="small")
    fig.tight_layout()
    return fig


def first_hit(s: np.ndarray) -> tuple[int, float] | None:
    """The first crossing of ``s = 1`` along a sampled path (the solution of a solve).

    Args:
        s: (N,) path parameter at the samples.

    Returns:
        ``(i, a)``: ``s = 1`` at the fraction ``a`` in [0, 1] of the way from sample ``i`` to
        sample ``i + 1`` (linear interpolation), or ``None`` when the path never meets it.
    """
    d = np.asarray(s, dtype=float) - 1.0
    idx = np.nonzero((d[:-1] * d[1:] <= 0) & (d[:-1] != d[1:]))[0]
    if not idx.size:
        return None
    i = int(idx[0])
    return i, float(d[i] / (d[i] - d[i + 1]))


def _branch_curves(results: Sequence[SolveResult]):
    """(result, s, det J_p, s', style) of each recorded path, cut where it reaches s = 1."""
    curves = [r for r in results if r.path is not None]
    if not curves:
        raise PlotError("the solve results have no recorded path: solve with record_path=True")
    out = []
    for r in curves:
        p = r.path
        if p is None:
            continue
        s, det, sdot = (np.asarray(a, dtype=float) for a in (p.s, p.det_jp, p.sdot))
        hit = first_hit(s)
        if hit is not None:  # the solution: the first crossing of s = 1 along the path
            i, a = hit
            s = np.append(s[: i + 1], 1.0)
            det = np.append(det[: i + 1], det[i] + a * (det[i + 1] - det[i]))
            sdot = np.append(sdot[: i + 1], sdot[i] + a * (sdot[i + 1] - sdot[i]))
        wide = r.branch == "convergent"
        style = {"color": COLORS.get(r.branch), "linewidth": 4.0 if wide else 1.6,
                 "alpha": 0.45 if wide else 1.0}  # fmt: skip
        out.append((r, s, det, sdot, style))
    return out


def _plot_along_s(results, path, which: int, ylabel: str, title: str):
    """One curve per solve against ``s``: ``which`` 2 is det J_p, 3 is s'."""
    fig = new_figure()
    ax = fig.add_subplot(1, 1, 1)
    for curve in _branch_curves(results):
        r, s, v, style = curve[0], curve[1], curve[which], curve[4]
        ax.plot(s, v, label=f"{r.branch} (b = {r.b:+.0f})", **style)
        ax.plot(s[:1], v[:1], "o", color=style["color"])
        ax.plot(s[-1:], v[-1:], "s", color=style["color"])
        for c in r.crossings:
            ax.plot([c.s], [0.0], "x", color=COLORS["singular"], markersize=9, mew=2)
    ax.axhline(0.0, color="black", linewidth=0.8)
    ax.axvline(1.0, color="gray", linewidth=0.8, linestyle=":")
    ax.set_xlabel("s")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    return save_figure(fig, path)


def plot_det_jp(results: Sequence[SolveResult], path: str | Path, title: str | None = None):
    """``det J_p`` along ``s`` for each solve (the paper's Fig. 5).

    Args:
        results: solves with a recorded path (``record_path=True``), e.g. both branches.
        path: PNG file to write.
        title: figure title.

    Returns:
        The path written.
    """
    default = "det J_p along the path (o start, square solution, x singular)"
    return _plot_along_s(results, path, 2, "det J_p", title or default)


def plot_phase(results: Sequence[SolveResult], path: str | Path, title: str | None = None):
    """Phase plot ``s' = b det J_p`` against ``s`` for each solve (the paper's Fig. 6).

    Args:
        results: solves with a recorded path (``record_path=True``).
        path: PNG file to write.
        title: figure title.

    Returns:
        The path written.
    """
    default = "phase plot (o start, square solution, x singular)"
    return _plot_along_s(results, path, 3, "s' = b det J_p", title or default)


def plot_solve(
    model: Model,
    theta0: ArrayLike,
    start: Configuration | None = None,
    out_dir: str | Path = ".",
    prefix: str | None = None,
    backend: str = "cvodes",
) -> list[Path]:
    """Solve on both branches and write the paper's three figures.

    Files: ``<prefix>_configurations.png`` (start, the two solutions and the singular
    configurations met), ``<prefix>_det_jp.png`` and ``<prefix>_phase.png``.

    Args:
        model: the model.
        theta0: (k,) actuated values to solve for.
        start: start configuration (default ``model.home``).
        out_dir: directory of the figures (created if needed).
        prefix: file name prefix (default: the model name).
        backend: a backend :func:`~scdk_sym.solvers.solve.solve` offers (:mod:`scdk_sym.backends`).

    Returns:
        The three paths written.

    Raises:
        PathError: a branch does not reach ``theta0`` (the error names it).
    """
    from .solvers.solve import solve

    require_matplotlib()
    theta0 = as_vector(theta0, model.k, f"theta0 ({', '.join(model.actuated)})")
    start = model.home if start is None else start
    results = [
        solve(model, theta0, start=start, branch=b, record_path=True, backend=backend)
        for b in ("convergent", "divergent")
    ]
    out = Path(out_dir)
    prefix = prefix or model.name
    shown = [("start " + format_vector(start.x), start, "gray")]
    for r in results:
        shown.append((f"{r.branch} " + format_vector(r.x), r.configuration, COLORS[r.branch]))
    for r in results:
        for c in r.crossings:
            cfg = model.configuration(c.y, c.theta)
            shown.append(("singular " + format_vector(cfg.x), cfg, COLORS["singular"]))
    return [
        plot_configurations(model, shown, out / f"{prefix}_configurations.png"),
        plot_det_jp(results, out / f"{prefix}_det_jp.png"),
        plot_phase(results, out / f"{prefix}_phase.png"),
    ]


def format_vector(x: np.ndarray) -> str:
    return "x = [" + ", ".join(f"{0.0 if abs(v) < 1e-9 else v:.4g}" for v in np.asarray(x)) + "]"


def plot_track(
    model: Model, result: TrackResult, path: str | Path, title: str | None = None
) -> Path:
    """Pose components of a track against the sample index, crossings marked.

    Each singular-manifold crossing (between samples ``index`` and ``index + 1``) is a
    vertical line at ``index + 0.5``.

    Args:
        model: the model (for the coordinate names).
        result: the track.
        path: PNG file to write.
        title: figure title.

    Returns:
        The path written.
    """
    x = np.asarray(result.x)
    if x.ndim != 2 or x.shape[1] != len(model.workspace) or not len(x):
        raise InputError(
            f"track result x must have shape (N, {len(model.workspace)}), got {x.shape}"
        )
    n = x.shape[1]
    fig = new_figure(7.0, 1.6 + 1.4 * n)
    t = np.arange(len(x))
    axes = fig.subplots(n, 1, sharex=True, squeeze=False)[:, 0]
    for i, (ax, name) in enumerate(zip(axes, model.workspace, strict=True)):
        ax.plot(t, x[:, i], ".-", color="tab:blue", markersize=3, linewidth=1.0)
        for k, c in enumerate(result.crossings):
            ax.axvline(c.index + 0.5, color=COLORS["singular"], linestyle="--", linewidth=1.5,
                       label="singular crossing" if (i == 0 and k == 0) else None)  # fmt: skip
        unit = 1.0 if name in ("phi", "roll", "pitch", "yaw") else max(model.length_scale, 1e-12)
        lo, hi = float(np.min(x[:, i])), float(np.max(x[:, i]))
        if hi - lo < 1e-3 * unit:  # (nearly) constant: do not blow rounding noise up
            mid = 0.5 * (lo + hi)
            ax.set_ylim(mid - 0.05 * unit, mid + 0.05 * unit)
        ax.set_ylabel(name)
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("sample")
    if result.crossings:
        axes[0].legend(fontsize="small", loc="best")
    fig.suptitle(title or f"{model.name}: tracked pose ({len(result.crossings)} crossing(s))")
    fig.tight_layout()
    return save_figure(fig, path)


__all__ = [
    "PlotError",
    "plot_configurations",
    "plot_det_jp",
    "plot_phase",
    "plot_solve",
    "plot_track",
    "RobotDrawing",
    "configurations_figure",
    "first_hit",
    "is_spatial",
    "placements",
    "rigid_groups",
    "robot_drawing",
    "robot_drawing_3d",
]


def plot_range(grid, path: str | Path, certificate=None, title: str | None = None) -> Path:
    """A transmission's margin over a box of two outputs (a
    :class:`~scdk_sym.solvers.transmission_range.MarginGrid`), with the open parts of a
    :class:`~scdk_sym.solvers.transmission_range.RangeCertificate` (where a singular
    configuration may lie) outlined in red and its proven parts in white.

    Raises:
        PlotError: matplotlib missing, or the file cannot be written.
    """
    from matplotlib.patches import Rectangle

    fig = new_figure(6.0, 4.8)
    ax = fig.add_subplot(111)
    mesh = ax.pcolormesh(grid.columns, grid.rows, grid.margin, shading="auto", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label="margin (relative smallest singular value)")
    if certificate is not None:
        i, j = _range_axes(certificate)
        for boxes, color, lw in ((certificate.boxes, "white", 0.4),
                                 (certificate.open_boxes, "red", 1.2)):  # fmt: skip
            for b in boxes:
                ax.add_patch(Rectangle((b[j, 0], b[i, 0]), b[j, 1] - b[j, 0], b[i, 1] - b[i, 0],
                                       fill=False, edgecolor=color, lw=lw))  # fmt: skip
    ax.set_xlabel(f"{grid.outputs[1]} [rad]")
    ax.set_ylabel(f"{grid.outputs[0]} [rad]")
    ax.set_title(title or "margin of the motor <-> joint map")
    fig.tight_layout()
    return save_figure(fig, path)


def _range_axes(certificate) -> tuple[int, int]:
    """The indices of the certificate's two widest outputs (the grid's, as
    :func:`~scdk_sym.solvers.transmission_range.margin_grid` picks them)."""
    widths = certificate.upper - certificate.lower
    order = [int(k) for k in np.argsort(-widths, kind="stable")[:2]]
    return order[0], order[1]
