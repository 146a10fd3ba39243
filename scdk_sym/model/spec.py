"""The loop-closure side file (``robot.yaml``): parsing and validation.

A strict superset of the Gepetto "extended URDF" YAML (``closed_loop``, ``type`` in either
case, ``name_mot``, and the joint edits ``joint_name`` / ``joint_type`` that Gepetto's loader
applies to the URDF before closing the loops) with the extensions ``format_version``,
``platform``, ``workspace``, ``home``, ``length_unit`` (default m), the closure types ``2d``
and ``distance``, the per-closure ``length`` list and ``coupling`` (joint couplings: a
polynomial relation between two linear combinations of joint coordinates, as MJCF's joint and
fixed-tendon equalities; their rows follow the frame closures').
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import yaml

from ..errors import ModelError

CLOSURE_TYPES = ("3d", "6d", "2d", "distance")
#: Closures between two frames (the others relate joint coordinates).
FRAME_TYPES = CLOSURE_TYPES
#: Number of residual rows of each closure type.
CLOSURE_ROWS = {"3d": 3, "6d": 6, "2d": 2, "distance": 1, "coupling": 1}
WORKSPACE_NAMES = ("x", "y", "z", "roll", "pitch", "yaw", "phi")
#: Joint edits of Gepetto's format (``joint_type``): a ball joint, a joint held at zero, and
#: universal joints (two revolutes about the named axes of the joint frame, in that order).
JOINT_EDITS = ("SPHERICAL", "FIXED", "UJOINT_XY", "UJOINT_YZ", "UJOINT_ZX", "UJOINT_ZY")
KNOWN_KEYS = (
    "closed_loop",
    "type",
    "name_mot",
    "joint_name",
    "joint_type",
    "format_version",
    "platform",
    "workspace",
    "home",
    "length",
    "length_unit",
    "coupling",
)
#: Length unit of a model that does not state one (URDF lengths are in metres).
DEFAULT_LENGTH_UNIT = "m"


@dataclass(frozen=True)
class Closure:
    """One loop closure between two frames (URDF link names).

    Attributes:
        frame_a: first frame.
        frame_b: second frame.
        type: "3d" (points coincide), "6d" (frames coincide), "2d" (x-y of the points
            coincide in the base frame) or "distance" (|a - b| = length).
        length: distance for "distance" closures [model length unit], else ``nan``.
        length_joint: for a "distance" closure whose length is a joint coordinate (the leg
            length of an SPS/UPS leg, actuated prismatic joint), that joint's name.
        terms_a: for a "coupling": (joint, coefficient) pairs of the combination
            ``a = sum(c q)`` [rad or length unit].
        offset_a: for a "coupling": the value of ``a`` that is its zero.
        terms_b: for a "coupling": the pairs of ``b`` (empty: ``a - offset_a = polycoef[0]``).
        offset_b: for a "coupling": the value of ``b`` that is its zero.
        polycoef: for a "coupling": ``a - offset_a = sum(polycoef[i] (b - offset_b)^i)``.
        name: the closure's name in its source file (MJCF equalities), else empty.
    """

    frame_a: str
    frame_b: str
    type: str
    length: float = math.nan
    length_joint: str | None = None
    terms_a: tuple[tuple[str, float], ...] = ()
    offset_a: float = 0.0
    terms_b: tuple[tuple[str, float], ...] = ()
    offset_b: float = 0.0
    polycoef: tuple[float, ...] = ()
    name: str = ""

    @property
    def rows(self) -> int:
        return CLOSURE_ROWS[self.type]

    @property
    def label(self) -> str:
        if self.name:
            return f"{self.type}({self.name})"
        if self.type == "coupling":
            a = "+".join(j for j, _ in self.terms_a)
            b = "+".join(j for j, _ in self.terms_b)
            return f"coupling({a},{b})" if b else f"coupling({a})"
        return f"{self.type}({self.frame_a},{self.frame_b})"

    @property
    def joints(self) -> tuple[str, ...]:
        """The joint coordinates a coupling relates (empty for a frame closure)."""
        return tuple(j for j, _ in (*self.terms_a, *self.terms_b))

    def coupling_dict(self) -> dict[str, Any]:
        """A coupling as its ``coupling`` YAML entry."""
        out: dict[str, Any] = {
            "a": {j: float(c) for j, c in self.terms_a},
            "a0": float(self.offset_a),
            "poly": [float(p) for p in self.polycoef],
        }
        if self.terms_b:
            out.update(b={j: float(c) for j, c in self.terms_b}, b0=float(self.offset_b))
        if self.name:
            out["name"] = self.name
        return out


@dataclass(frozen=True)
class Spec:
    """Parsed ``robot.yaml``.

    Attributes:
        closures: the loop closures, in the YAML's order.
        actuated: actuated joint names (``name_mot``).
        platform: link whose pose is reported (``None``: the model's default).
        workspace: workspace coordinate names, or ``None`` for the default.
        home: joint coordinate -> value of the assembled home configuration [rad or length
            unit].
        raw: the YAML mapping as read.
        length_unit: unit of every length of the model.
        joint_edits: (joint name, edit) pairs of ``joint_name`` / ``joint_type``, edits from
            :data:`JOINT_EDITS`.
    """

    closures: tuple[Closure, ...]
    actuated: tuple[str, ...]
    platform: str | None = None
    workspace: tuple[str, ...] | None = None
    home: dict[str, float] = field(default_factory=dict)
    raw: dict[str, Any] = field(default_factory=dict)
    length_unit: str = DEFAULT_LENGTH_UNIT
    joint_edits: tuple[tuple[str, str], ...] = ()

    def to_yaml(self) -> str:
        frames = [c for c in self.closures if c.type != "coupling"]
        couplings = [c.coupling_dict() for c in self.closures if c.type == "coupling"]
        data: dict[str, Any] = {
            "closed_loop": [[c.frame_a, c.frame_b] for c in frames],
            "type": [c.type for c in frames],
            "name_mot": list(self.actuated),
            "format_version": 1,
        }
        if couplings:
            data["coupling"] = couplings
        if self.joint_edits:
            data["joint_name"] = [name for name, _ in self.joint_edits]
            data["joint_type"] = [edit for _, edit in self.joint_edits]
        if any(c.type == "distance" for c in frames):
            data["length"] = [
                c.length_joint if c.length_joint else (None if math.isnan(c.length) else c.length)
                for c in frames
            ]
        if self.platform is not None:
            data["platform"] = self.platform
        if self.workspace is not None:
            data["workspace"] = list(self.workspace)
        if self.length_unit != DEFAULT_LENGTH_UNIT:
            data["length_unit"] = self.length_unit
        if self.home:
            data["home"] = {k: float(v) for k, v in self.home.items()}
        return yaml.safe_dump(data, sort_keys=False, default_flow_style=None)


def _str_list(data: dict, key: str, path: str | None) -> list[str]:
    value = data.get(key)
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ModelError(f"'{key}' must be a list of names, got {value!r}", path)
    return value


def parse_spec(text: str, path: str | None = None) -> Spec:
    """Parse and validate the YAML side file (names are checked later against the URDF).

    Raises:
        ModelError: malformed YAML, missing keys, inconsistent lengths, unknown types.
    """
    data = _mapping(text, path)
    return Spec(
        _closures(data, path) + _couplings(data, path),
        _actuated(data, path),
        _platform(data, path),
        _workspace(data, path),
        _home(data, path),
        data,
        _length_unit(data, path),
        _joint_edits(data, path),
    )


def _mapping(text: str, path: str | None) -> dict:
    """The YAML's mapping, its keys known, the required ones present, its version supported."""
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        first = str(exc).replace("\n", " ")
        raise ModelError(f"malformed YAML: {first}", path) from exc
    if not isinstance(data, dict):
        raise ModelError("YAML must be a mapping with keys closed_loop, type, name_mot", path)
    unknown = sorted(set(data) - set(KNOWN_KEYS))
    if unknown:
        raise ModelError(f"unknown keys {unknown}; keys: {', '.join(KNOWN_KEYS)}", path)
    for key in ("closed_loop", "type", "name_mot"):
        if key not in data:
            raise ModelError(f"missing key '{key}'", path)
    version = data.get("format_version", 1)
    if version != 1:
        raise ModelError(f"unsupported format_version {version!r}; supported: 1", path)
    return data


def _closure_types(data: dict, count: int, path: str | None) -> list[str]:
    """``type``: one known closure type per loop, in either case (returned lower-case)."""
    types = _str_list(data, "type", path)
    if len(types) != count:
        raise ModelError(f"'type' has {len(types)} entries but 'closed_loop' has {count}", path)
    for t in types:
        if t.lower() not in CLOSURE_TYPES:
            raise ModelError(f"unknown closure type {t!r}; types: {', '.join(CLOSURE_TYPES)}", path)
    return [t.lower() for t in types]


def _closures(data: dict, path: str | None) -> tuple[Closure, ...]:
    """``closed_loop``, ``type`` and ``length``: the closures, in order."""
    loops = data["closed_loop"]
    if not isinstance(loops, list) or not all(
        isinstance(p, list) and len(p) == 2 and all(isinstance(n, str) for n in p) for p in loops
    ):
        raise ModelError(
            f"'closed_loop' must be a list of [frame_a, frame_b] pairs, got {loops!r}", path
        )
    types = _closure_types(data, len(loops), path)
    lengths = data.get("length")
    if not isinstance(lengths, list):
        lengths = []
    if any(t == "distance" for t in types) and len(lengths) != len(loops):
        raise ModelError("'distance' closures need 'length', one entry per closure", path)
    closures = []
    for i, ((a, b), t) in enumerate(zip(loops, types, strict=True)):
        length, joint = math.nan, None
        if t == "distance":
            value = lengths[i]
            if isinstance(value, str):
                joint = value
            elif not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise ModelError(
                    f"closure {i} ({a}, {b}): length must be > 0 or a joint name, got {value!r}",
                    path,
                )
            else:
                length = float(value)
        closures.append(Closure(a, b, t, length, joint))
    return tuple(closures)


def _couplings(data: dict, path: str | None) -> tuple[Closure, ...]:
    """``coupling``: joint couplings ``a - a0 = sum(poly[i] (b - b0)^i)``, each a mapping
    with ``a`` (joint -> coefficient), ``a0``, ``poly`` and optionally ``b``, ``b0``,
    ``name``."""
    entries = data.get("coupling") or []
    if not isinstance(entries, list):
        raise ModelError(f"'coupling' must be a list of mappings, got {entries!r}", path)
    out = []
    for i, e in enumerate(entries):
        try:
            a = tuple((str(j), float(c)) for j, c in e["a"].items())
            b = tuple((str(j), float(c)) for j, c in (e.get("b") or {}).items())
            poly = tuple(float(p) for p in e["poly"])
            a0, b0 = float(e.get("a0", 0.0)), float(e.get("b0", 0.0))
        except (KeyError, TypeError, AttributeError, ValueError) as exc:
            raise ModelError(
                f"coupling {i}: expected a mapping with 'a' (joint: coefficient), 'a0', 'poly' "
                f"and optionally 'b', 'b0', got {e!r}",
                path,
            ) from exc
        if not a or not poly:
            raise ModelError(f"coupling {i}: 'a' and 'poly' must not be empty, got {e!r}", path)
        first = a[0][0]
        out.append(
            Closure(first, b[0][0] if b else first, "coupling", terms_a=a, offset_a=a0,
                    terms_b=b, offset_b=b0, polycoef=poly, name=str(e.get("name", "")))
        )  # fmt: skip
    return tuple(out)


def _actuated(data: dict, path: str | None) -> tuple[str, ...]:
    """``name_mot``: the actuated joints, at least one, no duplicate."""
    actuated = _str_list(data, "name_mot", path)
    if not actuated:
        raise ModelError("'name_mot' is empty: at least one actuated joint is needed", path)
    if len(set(actuated)) != len(actuated):
        raise ModelError(f"'name_mot' has duplicates: {actuated}", path)
    return tuple(actuated)


def _platform(data: dict, path: str | None) -> str | None:
    platform = data.get("platform")
    if platform is not None and not isinstance(platform, str):
        raise ModelError(f"'platform' must be a link name, got {platform!r}", path)
    return platform


def _workspace(data: dict, path: str | None) -> tuple[str, ...] | None:
    """``workspace``: known coordinates, planar ``phi`` not mixed with roll/pitch/yaw."""
    if data.get("workspace") is None:
        return None
    workspace = _str_list(data, "workspace", path)
    for w in workspace:
        if w not in WORKSPACE_NAMES:
            valid = ", ".join(WORKSPACE_NAMES)
            raise ModelError(f"unknown workspace coordinate {w!r}; coordinates: {valid}", path)
    if "phi" in workspace and set(workspace) & {"roll", "pitch", "yaw"}:
        raise ModelError("workspace mixes 'phi' with roll/pitch/yaw", path)
    return tuple(workspace)


def _home(data: dict, path: str | None) -> dict[str, float]:
    """``home``: joint name -> finite value."""
    home = data.get("home") or {}
    if not isinstance(home, dict):
        raise ModelError(f"'home' must map joint names to values, got {home!r}", path)
    for k, v in home.items():
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ModelError(f"home value of {k!r} must be a finite number, got {v!r}", path)
    return {str(k): float(v) for k, v in home.items()}


def _length_unit(data: dict, path: str | None) -> str:
    unit = data.get("length_unit", DEFAULT_LENGTH_UNIT)
    if not isinstance(unit, str) or not unit.strip():
        raise ModelError(
            f"'length_unit' must name the unit of lengths (e.g. m, cm, mm), got {unit!r}", path
        )
    return unit.strip()


def _joint_edits(data: dict, path: str | None) -> tuple[tuple[str, str], ...]:
    """The ``joint_name`` / ``joint_type`` pairs (types in either case, written upper-case)."""
    if "joint_name" not in data and "joint_type" not in data:
        return ()
    names = _str_list(data, "joint_name", path)
    kinds = _str_list(data, "joint_type", path)
    if len(names) != len(kinds):
        raise ModelError(
            f"'joint_type' has {len(kinds)} entries but 'joint_name' has {len(names)}", path
        )
    if len(set(names)) != len(names):
        raise ModelError(f"'joint_name' has duplicates: {names}", path)
    for kind in kinds:
        if kind.upper() not in JOINT_EDITS:
            raise ModelError(
                f"unknown joint type {kind!r} in 'joint_type'; types: {', '.join(JOINT_EDITS)}",
                path,
            )
    return tuple((n, k.upper()) for n, k in zip(names, kinds, strict=True))
