"""Krawczyk certificates of a point's real configurations, in one common chart.

Each real configuration is proven unique in its Krawczyk box on the model's rows ``g``
(:func:`scdk_sym.algebraic.certify_configuration_sets`, the C tests of several points in one
call), the boxes pairwise disjoint; the floating joints are charted where no configuration
is near a half turn (:func:`_common_chart`).
"""

from __future__ import annotations

import functools

import numpy as np

from ..errors import ScdkError
from ..model.rotations import rot_exp
from ..results import Configuration
from ..robot import Model


def certifier(model: Model, theta0: np.ndarray):
    """``(configurations, reasons) -> certificates`` at ``theta0`` (see :func:`certificates`)."""

    def certify(cfgs: list[Configuration], reasons: list[str]) -> tuple:
        return certificates(model, cfgs, theta0, reasons)

    return certify


def certificates(model, cfgs, theta0: np.ndarray, reasons: list[str]) -> tuple:
    """Krawczyk certificates of the real configurations in one common chart (a failure
    appended to ``reasons``)."""
    ys = np.vstack([c.y for c in cfgs] or [np.zeros((0, model.m))])
    return certificates_many(model, [ys], theta0[None], [reasons])[0]


def certificates_many(model, ys_list, thetas: np.ndarray, reasons: list[list[str]]) -> list:
    """:func:`certificates` of several points' configurations, each point's canonical
    unknowns (N_w, m) in ``ys_list``, the C tests of all in one call."""
    from ..algebraic import CertificateSet, certify_configuration_sets

    out: list[tuple] = [() for _ in ys_list]
    todo, sets = [], []
    for w, ys in enumerate(ys_list):
        if len(ys):
            todo.append(w)
            sets.append((ys, thetas[w], _common_chart(model, ys)))
    done: list[CertificateSet | None]
    try:
        done = list(certify_configuration_sets(model, sets))
    except ScdkError:  # which set: each on its own, as a single query makes them
        done = []
        for w, st in zip(todo, sets, strict=True):
            try:
                done.append(certify_configuration_sets(model, [st])[0])
            except ScdkError as exc:
                reasons[w].append(f"certificates not computed: {exc}")
                done.append(None)
    for w, cs in zip(todo, done, strict=True):
        if cs is None:
            continue
        out[w] = cs.certificates
        if not cs.proven:
            reasons[w].append(f"certificates: {cs.reason}")
    return out


def _common_chart(model: Model, ys: np.ndarray) -> np.ndarray | None:
    """A chart of the floating joints far from a half turn of every configuration.

    Candidates: each configuration's own rotations and 32 random ones; the one with the
    largest ``min 1 + trace(R_c^T R)`` over the configurations (0 at a half turn) is taken.
    """
    rots = model.chart.rotations
    if not rots or not len(ys):
        return None
    # (N, F, 3, 3) rotations of the configurations
    R = np.stack([rot_exp(ys[:, list(idx)]) for idx in rots], axis=1)
    cands = np.concatenate([R, _random_rotations(len(rots))])
    # score[c] = min over configurations and joints of 1 + trace(C^T R)
    score = (1.0 + np.einsum("cfij,nfij->cnf", cands, R)).min(axis=(1, 2))
    best = cands[int(np.argmax(score))]
    return np.concatenate([C.flatten(order="F") for C in best])


@functools.cache
def _random_rotations(count: int) -> np.ndarray:
    """(32, count, 3, 3) rotations of random axes and angles in [0, pi) (seeded: the same
    candidates for every query)."""
    rng = np.random.default_rng(0)
    w = rng.normal(size=(32, count, 3))
    w *= (np.pi * rng.uniform(size=(32, count, 1))) / np.linalg.norm(w, axis=2, keepdims=True)
    rand = np.array([[rot_exp(v) for v in row] for row in w])
    rand.flags.writeable = False
    return rand
