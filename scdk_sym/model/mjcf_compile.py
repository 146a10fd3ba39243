"""MuJoCo's compiler as the reference of MJCF: a file compiled for its kinematics alone.

Mesh, texture, height-field and skin files are left out (each mesh geom becomes a small
sphere, each body without an inertial gets a unit one), so a file loads without its asset
folder; what MuJoCo reads of the kinematics is unchanged.
"""

from __future__ import annotations

from os import PathLike
from pathlib import Path
from typing import Any

from ..errors import DependencyError, ModelError

#: Install command of the MJCF reader's dependency.
INSTALL = 'pip install "scdk_sym[mjcf]"  (or: pip install mujoco)'


def require_mujoco() -> Any:
    """``mujoco``, or a :class:`DependencyError` with the install command."""
    from ..optional import require

    return require("mujoco", needed_for="MJCF models", install=INSTALL, error=DependencyError)


def compile_kinematics(path: str | PathLike[str]) -> Any:
    """The file compiled by MuJoCo with its mesh, texture, height-field and skin files left
    out (each mesh geom a small sphere, each body given a unit inertia): an ``MjModel`` whose
    kinematics are the file's.

    Raises:
        ModelError: MuJoCo cannot read or compile the file (its message kept).
    """
    mujoco = require_mujoco()
    p = Path(path)
    if not p.is_file():
        raise ModelError("not found: expected an MJCF .xml file", str(p))
    try:
        spec = mujoco.MjSpec.from_file(str(p))
        for g in spec.geoms:
            if g.type in (mujoco.mjtGeom.mjGEOM_MESH, mujoco.mjtGeom.mjGEOM_HFIELD,
                          mujoco.mjtGeom.mjGEOM_SDF):  # fmt: skip
                g.type = mujoco.mjtGeom.mjGEOM_SPHERE
                g.size = [0.01, 0.0, 0.0]
                g.meshname = ""
                g.hfieldname = ""
        for kind in ("meshes", "textures", "hfields", "skins"):
            for item in list(getattr(spec, kind)):
                spec.delete(item)
        for mat in spec.materials:
            mat.textures = [""] * len(mat.textures)
        for body in spec.bodies:
            if body.name != "world" and not body.explicitinertial:
                body.explicitinertial = True
                body.mass = 1.0
                body.inertia = [1e-3, 1e-3, 1e-3]
        return spec.compile()
    except ValueError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else repr(exc)
        raise ModelError(f"MuJoCo cannot compile it: {first}", str(p)) from exc
