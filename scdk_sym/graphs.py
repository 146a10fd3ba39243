"""The block-triangular decomposition of a square sparse system (one implementation).

Used by :mod:`scdk_sym.robot.blocks` (a leg's knee, then its ankle) and by
:mod:`scdk_sym.algebraic.rootbound` (mixed volumes block by block). This module imports
nothing from the package, so every layer may use it.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence


def triangular_decomposition(uses: Sequence[set[int]]) -> list[tuple[list[int], list[int]]] | None:
    """Irreducible blocks ``(rows, variables)`` of a square system, dependencies first.

    Rows are matched to variables (augmenting paths); row ``r`` depends on row ``s`` when it
    uses the variable matched to ``s``; the blocks are the strongly connected components of
    that graph (Tarjan), each listed after every block it depends on: a block's rows use only
    its own variables and those of earlier blocks (Dulmage-Mendelsohn's fine decomposition).

    Args:
        uses: ``uses[r]``, the variables row ``r`` involves (as many rows as variables).

    Returns:
        The blocks, each ``(sorted rows, sorted variables)``; ``None`` when no perfect
        matching of rows to variables exists (a structurally singular system).
    """
    n = len(uses)
    match_var: dict[int, int] = {}  # variable -> row

    def augment(r: int, seen: set[int]) -> bool:
        for v in sorted(uses[r]):
            if v in seen:
                continue
            seen.add(v)
            if v not in match_var or augment(match_var[v], seen):
                match_var[v] = r
                return True
        return False

    for r in range(n):
        if not augment(r, set()):
            return None
    var_of = {r: v for v, r in match_var.items()}
    succ = [[match_var[v] for v in sorted(uses[r])] for r in range(n)]
    order: list[list[int]] = []
    idx: dict[int, int] = {}
    low: dict[int, int] = {}
    stack: list[int] = []
    on: set[int] = set()
    counter = itertools.count()

    def strong(v: int) -> None:
        idx[v] = low[v] = next(counter)
        stack.append(v)
        on.add(v)
        for w in succ[v]:
            if w not in idx:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], idx[w])
        if low[v] == idx[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            order.append(comp)

    for v in range(n):
        if v not in idx:
            strong(v)
    return [(sorted(c), sorted(var_of[r] for r in c)) for c in order]
