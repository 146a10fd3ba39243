"""The fixed data of one walk: the curve's model, line and kernels, the metric, the options."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .geometry import periodic
from .options import FollowOptions
from .walk import Line

if TYPE_CHECKING:
    from ..robot import Model


class WalkContext:
    """What stays fixed along one walk of :func:`~scdk_sym.follower.curve.follow`.

    Attributes:
        model: the model.
        line: the line in joint space.
        kern: the follower's kernels (:class:`~scdk_sym.follower.calls.FollowerCalls`).
        options: the walk's options.
        m: number of unknowns.
        scale: ``max(1, model length scale)`` [model length unit].
        tol: the model's residual tolerance.
        dtheta: (k,) direction of the line.
        p: (2k,) kernel parameters ``(theta1, dtheta)``.
        w: ``|dtheta|``.
        weight: (m+1,) diagonal of the metric ``|dy|^2 + (|dtheta| ds)^2``.
        rots: index groups of the floating rotations of the chart.
        rot_idx: their indices, flat.
        per: indices of the revolute angles (equal modulo 2 pi).
    """

    def __init__(self, model: Model, line: Line, kern, options: FollowOptions) -> None:
        self.model, self.line, self.kern, self.options = model, line, kern, options
        self.m = model.m
        self.scale = max(1.0, float(model.length_scale))
        self.tol = float(model.tolerance)
        self.dtheta = np.asarray(line.dtheta, float)
        self.p = np.concatenate([np.asarray(line.theta1, float), self.dtheta])
        w2 = float(self.dtheta @ self.dtheta)
        self.w = math.sqrt(w2)
        self.weight = np.append(np.ones(self.m), w2)
        self.rots = model.chart.rotations
        self.rot_idx = [i for idx in self.rots for i in idx]
        self.per = periodic(model)
