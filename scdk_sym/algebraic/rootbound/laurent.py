"""Sparse Laurent polynomials with complex coefficients, the arithmetic a form's rows are
expanded in, and their supports with rounding residues dropped."""

from __future__ import annotations

import numpy as np

from ...errors import AlgebraicFormError, HomotopyError

#: Coefficients below this fraction of a row's largest one are rounding residues (zero).
ZERO_COEFFICIENT = 1e-11
#: Largest product of term counts in one multiplication of the expansion (a larger model's
#: rows are not expanded: no bound).
MAX_TERMS = 200_000


class LaurentPolynomial:
    """A sparse Laurent polynomial with complex coefficients: exponent tuple -> coefficient."""

    __slots__ = ("terms", "nvars")

    def __init__(self, terms: dict[tuple[int, ...], complex], nvars: int) -> None:
        self.terms = terms
        self.nvars = nvars

    @classmethod
    def constant(cls, value: complex, nvars: int) -> LaurentPolynomial:
        """The constant ``value`` in ``nvars`` variables (no term when 0)."""
        return cls({(0,) * nvars: complex(value)} if value != 0 else {}, nvars)

    def is_constant(self) -> bool:
        """Whether every term is the constant monomial (or there is none)."""
        return all(not any(e) for e in self.terms)

    def value(self) -> complex:
        """The constant term."""
        return self.terms.get((0,) * self.nvars, 0j)

    def __add__(self, other: LaurentPolynomial) -> LaurentPolynomial:
        out = dict(self.terms)
        for e, c in other.terms.items():
            out[e] = out.get(e, 0j) + c
        return LaurentPolynomial(out, self.nvars)

    def __neg__(self) -> LaurentPolynomial:
        return LaurentPolynomial({e: -c for e, c in self.terms.items()}, self.nvars)

    def __sub__(self, other: LaurentPolynomial) -> LaurentPolynomial:
        return self + (-other)

    def __mul__(self, other: LaurentPolynomial) -> LaurentPolynomial:
        if len(self.terms) * len(other.terms) > MAX_TERMS:
            raise HomotopyError(
                f"expanding the algebraic form multiplies polynomials of {len(self.terms)} and "
                f"{len(other.terms)} terms (more than {MAX_TERMS}); no root bound for it"
            )
        out: dict[tuple[int, ...], complex] = {}
        for e1, c1 in self.terms.items():
            for e2, c2 in other.terms.items():
                e = tuple(a + b for a, b in zip(e1, e2, strict=True))
                out[e] = out.get(e, 0j) + c1 * c2
        return LaurentPolynomial(out, self.nvars)

    def __truediv__(self, other: LaurentPolynomial) -> LaurentPolynomial:
        if not other.is_constant() or other.value() == 0:
            raise AlgebraicFormError(
                "the algebraic form divides by a non-constant expression; its rows must be "
                "polynomials in the unknowns"
            )
        inv = 1.0 / other.value()
        return LaurentPolynomial({e: c * inv for e, c in self.terms.items()}, self.nvars)

    def _const_fn(self, f) -> LaurentPolynomial:
        if not self.is_constant():
            raise AlgebraicFormError(
                "the algebraic form takes cos or sin of an unknown; only parameters may "
                "enter through cos and sin"
            )
        return LaurentPolynomial.constant(f(self.value()), self.nvars)

    def cos(self) -> LaurentPolynomial:
        """``cos`` of a constant (of a parameter; an unknown's raises AlgebraicFormError)."""
        return self._const_fn(np.cos)

    def sin(self) -> LaurentPolynomial:
        """``sin`` of a constant (of a parameter; an unknown's raises AlgebraicFormError)."""
        return self._const_fn(np.sin)


def support(poly: LaurentPolynomial) -> tuple[list[tuple[int, ...]], np.ndarray]:
    """Monomials and coefficients of a polynomial, rounding residues (below
    :data:`ZERO_COEFFICIENT` times the largest) dropped."""
    if not poly.terms:
        return [], np.zeros(0, dtype=complex)
    mons = list(poly.terms)
    coef = np.array([poly.terms[e] for e in mons])
    keep = np.abs(coef) > ZERO_COEFFICIENT * np.abs(coef).max()
    return [m for m, k in zip(mons, keep, strict=True) if k], coef[keep]
