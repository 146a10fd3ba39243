"""What a newcomer reads before the first solve: a model's inputs, unknowns, closures, held
joints, home, joint ranges, blocks and the reduction made, as text (``scdk info``)."""

from __future__ import annotations

from .parts import ModelParts


def _range(model: ModelParts, name: str) -> str:
    try:
        j = model.tree.joint(name)
    except Exception:  # a coordinate of a ball or floating joint
        return ""
    if not (abs(j.lower) < 1e6 or abs(j.upper) < 1e6):  # none, or URDF's placeholders
        return ""
    return f" [{j.lower:.4g}, {j.upper:.4g}]"


def _listed(names) -> str:
    names = list(names)
    return ", ".join(names) if names else "(none)"


def describe(model: ModelParts) -> str:
    """Several lines describing ``model`` (see the module docstring)."""
    home = model.home
    units = model.units
    lines = [f"model {model.name!r}" + (f" from {model.path}" if model.path else "")]
    src = model.source
    if src is not None:
        lines.append(f"  source: MJCF read by MuJoCo's compiler; home from its {src.home_name}")
    lines.append(f"  inputs (theta, {model.k}):")
    for i, a in enumerate(model.actuated):
        lines.append(f"    {a} [{units[a]}]{_range(model, a)}  home {float(home.theta[i]):.6g}")
    lines.append(f"  unknowns (y, {model.m}):")
    for i, u in enumerate(model.unknowns):
        lines.append(f"    {u}{_range(model, u)}  home {float(home.y[i]):.6g}")
    lines.append(f"  closures ({len(model.closures)}, {int(model.row_offsets[-1])} rows):")
    for c in model.closures:
        lines.append(f"    {c.label}  {c.rows} row(s)")
    held = dict(model.held)
    idle = {k: v for k, v in model.locked.items() if k not in held}
    springs = getattr(src, "springs", {})
    if held:
        lines.append("  held joints:")
        for k, v in held.items():
            why = " (spring at springref)" if k in springs and springs[k] == v else ""
            lines.append(f"    {k} = {v:.6g}{why}")
    if idle:
        lines.append(f"  idle joints locked at home: {_listed(idle)}")
    lines.append(
        f"  reported frame: {model.frame!r}, x = ({', '.join(model.workspace)}) "
        f"= {[round(float(v), 6) for v in home.x]}"
    )
    lines.append(f"  home closes every loop to {home.residual:.1e}")
    if model.assembly:
        lines.append(f"  home: {model.assembly}")
    if model.reduction:
        lines.append(f"  {model.reduction}")
    blocks = model.blocks
    if len(blocks) > 1:
        lines.append(f"  independent blocks ({len(blocks)}), each solved on its own:")
        for b in blocks:
            lines.append(f"    {_listed(b.unknowns)}  <- {_listed(b.actuated)}")
    for note in getattr(src, "notes", ()):
        lines.append(f"  note: {note}")
    return "\n".join(lines)
