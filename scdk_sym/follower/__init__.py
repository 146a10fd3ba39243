"""The curve follower: one implementation of following solution curves of the closures.

- :mod:`~scdk_sym.follower.kernels`: the CasADi Functions it calls (SX or generated C);
- :mod:`~scdk_sym.follower.cvodes`: CVODES on the stabilised singularity-consistent field;
- :mod:`~scdk_sym.follower.curve`: :func:`~scdk_sym.follower.curve.follow`, the walk along one
  curve (predictors, step control, folds, bifurcations, level crossings);
- :mod:`~scdk_sym.follower.finish`: the answer at ``s = 1`` of a walk (a fold touching it, the
  parity check);
- :mod:`~scdk_sym.follower.singular`: the nearest singular surface and the solution across it
  (the divergent branch);
- :mod:`~scdk_sym.follower.geometry`: chart-free comparison of configurations.
"""
