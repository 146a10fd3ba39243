"""Closure Jacobians from the joints' screw axes (scdk_sym.symbolic.screws) against CasADi's
differentiation of the same residuals, in the world frame and in each loop's root frame."""

from __future__ import annotations

import warnings

import casadi as ca
import numpy as np
import pytest
from factories import ROOT, shipped

import scdk_sym as sc
from scdk_sym.errors import ModelWarning
from scdk_sym.symbolic.kinematics import closure_residual, link_placements
from scdk_sym.symbolic.screws import closure_joint_jacobian

GEPETTO = ROOT / "tests" / "fixtures" / "gepetto"


def _model(name: str) -> sc.Model:
    if (GEPETTO / name).exists():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ModelWarning)
            return sc.load_model(GEPETTO / name)
    return shipped(name)


def _roots(tree, closure) -> list[str]:
    """The world root and the deepest link above both frames (a loop's root)."""
    parent = {j.child: j.parent for j in tree.joints}
    above, link = [closure.frame_a], closure.frame_a
    while link in parent:
        link = parent[link]
        above.append(link)
    link, seen = closure.frame_b, {closure.frame_b}
    while link in parent:
        link = parent[link]
        seen.add(link)
    return sorted({tree.root, next(x for x in above if x in seen)})


@pytest.mark.parametrize(
    "name, kinds",
    [("digit_like", {"6d"}), ("5bar_linkage_iso3d", {"3d"}), ("delta", {"distance"}),
     ("wl16_like", {"6d"}), ("stewart_gough", set())],
)  # fmt: skip
def test_screw_columns_equal_casadi_differentiation(name, kinds):
    model = _model(name)
    tree = model.tree
    joints = [j for j in tree.joints if j.type in ("revolute", "continuous", "prismatic")]
    q = {j.name: ca.SX.sym(j.name) for j in joints}
    values = {n: q.get(n, v) for n, v in model.symbolic.values.items()}
    rng = np.random.default_rng(5)
    written = set()
    for cl in model.closures:
        for base in _roots(tree, cl):
            T = link_placements(tree, values, model.symbolic.charts, base=base)
            cols = closure_joint_jacobian(tree, cl, T, base)
            if cols is None:
                continue
            written.add(cl.type)
            g = closure_residual(cl, T[cl.frame_a], T[cl.frame_b], values)
            names = sorted(q)
            ours = ca.horzcat(*[cols.get(n, ca.SX(cl.rows, 1)) for n in names])
            ref = ca.jacobian(g, ca.vertcat(*[q[n] for n in names]))
            free = sorted(set(ca.symvar(ca.vertcat(ca.vec(ours), ca.vec(ref)))), key=str)
            f = ca.Function("f", free, [ca.densify(ours), ca.densify(ref)])
            for _ in range(4):
                args = [rng.uniform(-1.0, 1.0) for _ in free]
                a, b = (np.array(v) for v in f(*args))
                assert np.max(np.abs(a - b)) <= 1e-12 * max(1.0, np.max(np.abs(b))), (
                    name, cl.frame_a, base)  # fmt: skip
    assert written == kinds, (name, written)  # stewart_gough: a floating platform
