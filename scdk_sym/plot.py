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
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from .errors import InputError, PlotError
from .model.rotations import rot_exp
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
    try:
        import matplotlib  # noqa: F401
        from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: F401
        from matplotlib.figure import Figure  # noqa: F401
        from matplotlib.lines import Line2D  # noqa: F401
        from matplotlib.patches import Polygon  # noqa: F401
    except ImportError as exc:
        raise PlotError(
            f"figures need matplotlib, which is not installed: {INSTALL_HINT} "
            "(or pip install matplotlib)"
        ) from exc


def _figure(width: float = 6.0, height: float = 4.5):
    require_matplotlib()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=120)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path: str | Path) -> Path:
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(p, format="png")
    except OSError as exc:
        raise PlotError(f"cannot write figure {str(p)!r}: {exc.strerror or exc}") from exc
    return p


# ---------------------------------------------------------------------------- geometry


def placements(model: Model, cfg: Configuration) -> tuple[dict, dict]:
    """World placements of every link and of every joint frame (before its motion).

    Args:
        model: the model.
        cfg: a configuration (its ``joints`` give every joint value).

    Returns:
        (links, frames): link name -> (4, 4) placement in the base frame, joint name ->
        (4, 4) placement of the joint frame [model length unit].
    """
    values = dict(cfg.joints)
    links: dict[str, np.ndarray] = {model.tree.root: np.eye(4)}
    frames: dict[str, np.ndarray] = {}
    for j in model.tree.joints:
        F = links[j.parent] @ np.asarray(j.origin, dtype=float)
        frames[j.name] = F
        M = np.eye(4)
        if j.type == "floating":
            c = [values[n] for n in j.coordinates]
            M[:3, :3] = rot_exp(np.array(c[3:]))
            M[:3, 3] = c[:3]
        elif j.type == "prismatic":
            M[:3, 3] = np.asarray(j.axis) * values[j.name]
        elif j.type in ("revolute", "continuous"):
            M[:3, :3] = rot_exp(np.asarray(j.axis) * values[j.name])
        links[j.child] = F @ M
    return links, frames


def rigid_groups(model: Model) -> dict[str, int]:
    """Link -> index of its rigid body (links joined by fixed joints)."""
    parent = {link: link for link in model.tree.links}

    def find(a: str) -> str:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for j in model.tree.joints:
        if j.type == "fixed":
            parent[find(j.child)] = find(j.parent)
    roots = sorted({find(link) for link in model.tree.links})
    return {link: roots.index(find(link)) for link in model.tree.links}


@dataclass(frozen=True)
class RobotDrawing:
    """The robot of one configuration as flat bodies and segments, in the base frame.

    Attributes:
        polygons: (N, d) outlines of the rigid bodies with three or more points that span an
            area, the base first (empty (0, d) when the base is no such body) [model length
            unit].
        polygon_links: a link of each polygon's body ('' for an empty base).
        segments: (2, d) links drawn as a segment from where they are driven to where they
            drive (legs, arms, rods).
        segment_links: the link each segment belongs to.
        closures: (2, d) each loop closure's two frame origins (A, B): a distance closure's
            segment (a leg of fixed or actuated length), a point for the other types.
        closure_types: the type of each closure ("3d", "2d", "6d", "distance").
    """

    polygons: tuple[np.ndarray, ...]
    polygon_links: tuple[str, ...]
    segments: tuple[np.ndarray, ...]
    segment_links: tuple[str, ...]
    closures: tuple[np.ndarray, ...]
    closure_types: tuple[str, ...]


def robot_drawing(model: Model, cfg: Configuration) -> tuple[list, list]:
    """Polygons (rigid bodies with three or more points) and segments of a configuration.

    Returns:
        (polygons, segments): lists of (N, 2) and (2, 2) arrays of x-y points in the base
        frame [model length unit]; the first polygon is the base (empty if it is not one).
    """
    d = _drawing(model, cfg, 2)
    segments = list(d.segments)
    segments += [c for c, t in zip(d.closures, d.closure_types, strict=True) if t == "distance"]
    return list(d.polygons), segments


def robot_drawing_3d(model: Model, cfg: Configuration) -> RobotDrawing:
    """The robot of a configuration in 3-D: bodies outlined in their own plane, segments.

    A body whose points are not coplanar is outlined by the hull of their projection on the
    best-fitting plane.

    Args:
        model: the model.
        cfg: the configuration.

    Returns:
        The drawing, every array with 3 columns (x, y, z) [model length unit].
    """
    return _drawing(model, cfg, 3)


def _drawing(model: Model, cfg: Configuration, dims: int) -> RobotDrawing:
    """The drawing in the x-y plane (``dims`` 2) or in space (``dims`` 3)."""
    links, frames = placements(model, cfg)
    group = rigid_groups(model)
    points: dict[int, list[np.ndarray]] = {}
    members: dict[int, str] = {}
    for link, T in links.items():
        points.setdefault(group[link], []).append(T[:3, 3])
        members.setdefault(group[link], link)
    for j in model.tree.joints:  # joint frames belong to the body of their parent link
        points[group[j.parent]].append(frames[j.name][:3, 3])
    polygons, polygon_links, big = [], [], set()
    base = group[model.tree.root]
    tol = 1e-9 * max(1.0, model.length_scale) ** 2
    for g in sorted(points, key=lambda g: (g != base, g)):  # the base first
        outline = _outline(np.array(points[g]), dims, tol)
        if outline is not None:
            polygons.append(outline)
            polygon_links.append(members[g])
            big.add(g)
    if base not in big:
        polygons.insert(0, np.zeros((0, dims)))
        polygon_links.insert(0, "")
    segments, segment_links = [], []
    entry = {j.child: j for j in model.tree.joints}
    scale = 1e-12 * max(1.0, model.length_scale)
    for j in model.tree.joints:
        into = entry.get(j.parent)
        # a link is a segment from where it is driven to where it drives; links moved by a
        # prismatic or floating joint are displacements (slider chains, legs), not bodies
        if into is None or into.type in ("prismatic", "floating") or group[j.parent] in big:
            continue
        a = frames[into.name][:3, 3]
        b = links[j.child][:3, 3] if j.type == "fixed" else frames[j.name][:3, 3]
        if np.linalg.norm(a - b) > scale:
            segments.append(np.array([a[:dims], b[:dims]]))
            segment_links.append(j.parent)
    closures = tuple(
        np.array([links[c.frame_a][:dims, 3], links[c.frame_b][:dims, 3]]) for c in model.closures
    )
    return RobotDrawing(
        tuple(polygons),
        tuple(polygon_links),
        tuple(segments),
        tuple(segment_links),
        closures,
        tuple(c.type for c in model.closures),
    )


def _outline(P: np.ndarray, dims: int, tol: float) -> np.ndarray | None:
    """The hull of a body's points (x-y or in their best plane), ``None`` below area ``tol``."""
    if dims == 2:
        Q = np.unique(np.round(P[:, :2], 12), axis=0)
        if len(Q) >= 3 and _area(Q) > tol:
            return _hull(Q)
        return None
    Q = np.unique(np.round(P, 12), axis=0)
    if len(Q) < 3:
        return None
    centre = Q.mean(axis=0)
    _, _, Vt = np.linalg.svd(Q - centre)
    flat = np.unique(np.round((Q - centre) @ Vt[:2].T, 12), axis=0)
    if len(flat) < 3 or _area(flat) <= tol:
        return None
    return centre + _hull(flat) @ Vt[:2]


def _area(P: np.ndarray) -> float:
    H = _hull(P)
    x, y = H[:, 0], H[:, 1]
    return 0.5 * abs(float(x @ np.roll(y, -1) - y @ np.roll(x, -1)))


def _hull(P: np.ndarray) -> np.ndarray:
    """Convex hull (monotone chain) of 2-D points, counter-clockwise."""
    pts = sorted(map(tuple, P))
    if len(pts) < 3:
        return np.array(pts)

    def half(seq):
        out: list = []
        for p in seq:
            while len(out) >= 2 and _cross(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out[:-1]

    return np.array(half(pts) + half(reversed(pts)))


def _cross(o, a, b) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


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
    return _save(configurations_figure(model, configurations, title), path)


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

    fig = _figure(6.0, 6.0)
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

    fig = _figure(6.5, 6.0)
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
    fig = _figure()
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
    return _save(fig, path)


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
        backend: a backend :func:`~scdk_sym.solvers.sc.solve` offers (:mod:`scdk_sym.backends`).

    Returns:
        The three paths written.

    Raises:
        PathError: a branch does not reach ``theta0`` (the error names it).
    """
    from .solvers.sc import solve

    require_matplotlib()
    theta0 = as_vector(theta0, model.k, f"theta0 ({', '.join(model.actuated)})")
    start = model.home if start is None else start
    results = [
        solve(model, theta0, start=start, branch=b, record_path=True, backend=backend)
        for b in ("convergent", "divergent")
    ]
    out = Path(out_dir)
    prefix = prefix or model.name
    shown = [("start " + _fmt(start.x), start, "gray")]
    for r in results:
        shown.append((f"{r.branch} " + _fmt(r.x), r.configuration, COLORS[r.branch]))
    for r in results:
        for c in r.crossings:
            cfg = model.configuration(c.y, c.theta)
            shown.append(("singular " + _fmt(cfg.x), cfg, COLORS["singular"]))
    return [
        plot_configurations(model, shown, out / f"{prefix}_configurations.png"),
        plot_det_jp(results, out / f"{prefix}_det_jp.png"),
        plot_phase(results, out / f"{prefix}_phase.png"),
    ]


def _fmt(x: np.ndarray) -> str:
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
    fig = _figure(7.0, 1.6 + 1.4 * n)
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
    return _save(fig, path)


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
