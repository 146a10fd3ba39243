"""A form's rows in isotropic coordinates: each angle's ``(c, s)`` becomes ``u = c + i s`` in
``C*`` (``c = (u + 1/u) / 2``, ``s = (u - 1/u) / (2 i)``), the circle rows hold identically
and are dropped, the roots kept one to one."""

from __future__ import annotations

import numpy as np

from ...errors import AlgebraicFormError
from .laurent import LaurentPolynomial


def isotropic_rows(
    form, p: np.ndarray
) -> tuple[list[LaurentPolynomial], list[str], tuple[str, ...]]:
    """The closure and non-circle structural rows of a form at parameters ``p``, expanded in
    isotropic coordinates (see the module docs).

    Args:
        form: an :class:`~scdk_sym.algebraic.form.AlgebraicForm` (or a scaled one).
        p: (n_params,) complex parameters.

    Returns:
        ``(rows, labels, variables)``: the rows as sparse polynomials, their labels, and the
        variable names (``joint.u`` for an angle, the form's names otherwise).

    Raises:
        AlgebraicFormError: a row that is no polynomial, or a circle row that does not vanish
            identically.
    """
    from ..pairs import replay

    form = getattr(form, "form", form)  # a ScaledForm's rows have the same roots
    rows = form.rows
    variables: list[str] = []
    index: dict[int, int] = {}  # z index -> variable (lengths, floating parts)
    angles: dict[int, tuple[int, int]] = {}  # z index of c -> (variable, z index of s)
    for s in rows.slots:
        if s.kind == "angle":
            angles[s.z[0]] = (len(variables), s.z[1])
            variables.append(f"{s.joint}.u")
        else:
            for zi in s.z:
                index[zi] = len(variables)
                variables.append(rows.names[zi])
    nv = len(variables)

    def var(j: int, power: int = 1) -> LaurentPolynomial:
        e = [0] * nv
        e[j] = power
        return LaurentPolynomial({tuple(e): 1.0 + 0j}, nv)

    z: list[LaurentPolynomial | None] = [None] * form.n
    for zc, (j, zs) in angles.items():
        u, ui = var(j), var(j, -1)
        z[zc] = LaurentPolynomial.constant(0.5, nv) * (u + ui)
        z[zs] = LaurentPolynomial.constant(-0.5j, nv) * (u - ui)
    for zi, j in index.items():
        z[zi] = var(j)
    params = [LaurentPolynomial.constant(complex(v), nv) for v in np.asarray(p, dtype=complex)]
    (G,) = replay(form.G_real, [z, params], lambda v: LaurentPolynomial.constant(v, nv))
    out, labels = [], []
    for g, label in zip(G, rows.labels, strict=True):
        if label.endswith(".circle"):
            coef = np.array(list(g.terms.values())) if g.terms else np.zeros(1)
            if np.abs(coef).max() > 1e-12:
                raise AlgebraicFormError(
                    f"circle row {label} does not vanish in isotropic coordinates "
                    f"(|coefficient| {np.abs(coef).max():.1e}); the form's angles must be "
                    "(cos, sin) pairs"
                )
            continue
        out.append(g)
        labels.append(label)
    if len(out) != nv:
        raise AlgebraicFormError(
            f"isotropic rewrite has {len(out)} rows for {nv} variables; the form is not square"
        )
    return out, labels, tuple(variables)
