"""An upper bound on the isolated roots of a model's algebraic form: the BKK bound.

Bernstein's theorem (Bernstein 1975, Kushnirenko 1976; Li and Wang 1996 for roots with zero
coordinates): whatever its coefficients, a square system ``f_1 .. f_n`` of Laurent
polynomials has at most ``MV(Q_1, ..., Q_n)`` isolated roots in ``(C*)^a x C^b`` (``a``
variables with negative exponents allowed, ``b`` ordinary ones), where ``Q_i`` is the convex
hull of the exponents of ``f_i`` and the origin and ``MV`` the mixed volume. The bound holds
for every offset ``b`` of the homotopy family ``G(z, p) + b`` at once (the origin stands for
the offset). When a complete-looking set of ``R`` distinct nonsingular roots is known and
``MV = R``, no isolated root is missing: the set is complete, with no random step (beyond
the numerical zero test of coefficients below).

Taken as written the bound of a form is far too large (two circles ``c^2 + s^2 = 1`` count
as two general conics), so the form is first rewritten, keeping its roots one to one:

1. isotropic coordinates: each angle's ``(c, s)`` becomes ``u = c + i s`` in ``C*``, with
   ``c = (u + 1/u) / 2`` and ``s = (u - 1/u) / (2 i)``; the circle row then holds identically
   and is dropped. A product of rotations about one axis keeps only ``u1 u2`` and
   ``1 / (u1 u2)`` where ``(c, s)`` had every cross term.
2. the rows are replaced by an invertible linear combination of sparse vectors of their
   span (``y + i z`` and ``y - i z`` for a planar point; differences of distance rows, which
   cancel ``|t|^2``): the candidates cancel ``k - 1`` monomials of a closure's ``k`` rows in
   every (or a sample of) ways, or are the reduced row echelon forms of all rows with the
   monomials taken densest first and in random orders; the sparsest independent ones are kept.
3. the mixed volume is a product over the irreducible blocks of the system (its block
   triangular form: a block of rows that uses only its own variables and those of blocks
   already counted, projected away), and in each block the sum of ``|det|`` over the fine
   mixed cells of a random lifting (Huber and Sturmfels 1995), enumerated depth first,
   branching on the support with the fewest compatible edges (dynamic enumeration,
   Mizutani, Takeda and Kojima 2007), one linear-programming feasibility test per partial
   cell. Two independent liftings must give the same number.

Where a block's mixed volume is out of reach (its budget spent, or a support whose lower hull
is too large), that block is bounded by a multihomogeneous Bezout number instead
(:func:`multihomogeneous_bezout`: each row multiplied by the monomial that makes its exponents
non-negative, which keeps its roots in the torus; the least over a few partitions of the
block's variables), a weaker bound that always finishes. ``RootBound.bezout`` names those
blocks.

Coefficients below :data:`ZERO_COEFFICIENT` times a row's largest are taken as exact zeros
(the rounding residue of a cancellation such as ``c1 c2 - s1 s2`` in ``u1 / u2``).
"""

from .bezout import BEZOUT_MAX_STATES, multihomogeneous_bezout
from .bound import BUDGET, RootBound, mixed_volume, root_bound
from .isotropic import isotropic_rows
from .laurent import MAX_TERMS, ZERO_COEFFICIENT
from .mixedcells import HULL_MAX_SIZE
from .sparsify import SPARSIFY_SUBSETS

__all__ = [
    "BEZOUT_MAX_STATES",
    "BUDGET",
    "HULL_MAX_SIZE",
    "MAX_TERMS",
    "SPARSIFY_SUBSETS",
    "ZERO_COEFFICIENT",
    "RootBound",
    "isotropic_rows",
    "mixed_volume",
    "multihomogeneous_bezout",
    "root_bound",
]
