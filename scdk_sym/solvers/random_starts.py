"""Random assembled starts of the real-curve search (the paper's kind: ``theta1 = IK(y1)``).

The starts of :func:`scdk_sym.solvers.curve_modes.explore` that no curve through a known
solution reaches: random unknowns near the fibre over ``theta0``, away from the solutions
already known, given ``theta`` by Newton on the closure rows.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ScdkError
from ..follower.geometry import features, kinds
from ..model.rotations import quaternion_matrix
from ..results import Configuration
from ..robot import Model

#: Random starts: coordinates other than angles within this many model sizes of home.
RANDOM_SPREAD = 1.5


class RandomStarts:
    """Random assembled starts (the paper's kind: ``theta1 = IK(y1)``) for the search.

    With as many unknowns as actuators, batches of random unknowns (revolute angles and
    rotations uniform, other coordinates within ``RANDOM_SPREAD`` model sizes of home) are
    ranked by their closure residual at ``theta0`` (the nearer the fibre over ``theta0``, the
    likelier the curve from there reaches ``s = 1``); a candidate near a known solution is
    skipped, the others get ``theta`` by Newton on ``g(y, theta) = 0``. Otherwise the inverse
    kinematics of random poses near home.

    Args:
        model: the model.
        rng: random generator.
        theta0: (k,) target actuated values.
        batch: candidates drawn at a time.
    """

    def __init__(self, model: Model, rng: np.random.Generator, theta0: np.ndarray, batch=256):
        self.model, self.rng, self.theta0, self.batch = model, rng, theta0, batch
        self.queue: list[np.ndarray] = []
        self.drawn = 0

    def _refill(self) -> None:
        model, n = self.model, self.batch
        Y = np.tile(np.array(model.home.y, dtype=float), (n, 1))
        per, _, plain = kinds(model)
        Y[:, per] = self.rng.uniform(-math.pi, math.pi, (n, per.size))
        spread = RANDOM_SPREAD * model.length_scale
        Y[:, plain] += self.rng.uniform(-spread, spread, (n, len(plain)))
        C = np.zeros((n, model.chart.size))
        for r, idx in enumerate(model.chart.rotations):
            quat = self.rng.normal(size=(n, 4))
            quat /= np.linalg.norm(quat, axis=1)[:, None]
            # uniform rotations, as charts (local rotation parameters 0), column-major
            C[:, 9 * r : 9 * r + 9] = quaternion_matrix(quat).transpose(0, 2, 1).reshape(n, 9)
            Y[:, list(idx)] = 0.0
        G = np.array(model.kernels.g.map(n)(Y.T, np.tile(self.theta0[:, None], (1, n)), C.T))
        score = np.max(np.abs(G), axis=0)
        score[~np.isfinite(score)] = np.inf
        order = np.argsort(score, kind="stable")
        self.queue = [model.chart.to_canonical(Y[j], C[j]) for j in order if np.isfinite(score[j])]
        self.queue.reverse()  # pop() takes the best

    def next(self, known: np.ndarray, radius: float) -> Configuration | None:
        """The next start away from the known solutions' features (None if it fails)."""
        model = self.model
        self.drawn += 1
        if model.m != model.k:
            return self._by_inverse_kinematics()
        while True:
            if not self.queue:
                self._refill()
            y = self.queue.pop()
            if (
                not known.size
                or np.min(np.max(np.abs(known - features(model, y)), axis=1)) > radius
            ):
                break
        y_loc, c = model.chart.to_local(y)
        theta = np.array(self.theta0, dtype=float)
        for _ in range(30):
            g = np.array(model.kernels.g(y_loc, theta, c)).ravel()
            if not np.all(np.isfinite(g)):
                return None
            if np.max(np.abs(g)) <= 0.1 * model.tolerance:
                break
            Js = np.array(model.kernels.jac(y_loc, theta, c)[1])
            try:
                theta = theta + np.linalg.solve(Js, g)
            except np.linalg.LinAlgError:
                return None
        return self._checked(model.configuration(y, theta))

    def _by_inverse_kinematics(self) -> Configuration | None:
        model = self.model
        x = np.array(model.home.x, dtype=float)
        for i, name in enumerate(model.workspace):
            if name in ("phi", "roll", "pitch", "yaw"):
                x[i] += self.rng.uniform(-math.pi, math.pi) * (0.5 if name == "pitch" else 1.0)
            else:
                x[i] += self.rng.uniform(-0.3, 0.3) * model.length_scale
        try:
            return self._checked(model.inverse_kinematics(x))
        except ScdkError:
            return None

    def _checked(self, cfg: Configuration) -> Configuration | None:
        ok = cfg.residual <= self.model.tolerance and np.all(np.isfinite(cfg.theta))
        return cfg if ok else None
