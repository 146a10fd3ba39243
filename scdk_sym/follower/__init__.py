"""The curve follower: one implementation of following solution curves of the closures.

- :mod:`~scdk_sym.follower.calls`: the CasADi Functions it calls (SX or generated C);
- :mod:`~scdk_sym.follower.cvodes`: CVODES on the stabilised singularity-consistent field;
- :mod:`~scdk_sym.follower.curve`: :func:`~scdk_sym.follower.curve.follow`, the walk along one
  curve (its loop and step control), with the parts it is made of:

  - :mod:`~scdk_sym.follower.options`: how a walk is made
    (:class:`~scdk_sym.follower.options.FollowOptions`);
  - :mod:`~scdk_sym.follower.walk`: what a walk is given and reports (line, hits, walk, path);
  - :mod:`~scdk_sym.follower.context`: the fixed data of one walk (model, line, kernels,
    metric);
  - :mod:`~scdk_sym.follower.state`: the state of one walk and the moves that change it;
  - :mod:`~scdk_sym.follower.predictors`: explicit predictor-corrector steps and CVODES
    chunks, and the declared list of predictors;
  - :mod:`~scdk_sym.follower.events`: judging a chunk's segments (folds, bifurcations,
    level crossings);
  - :mod:`~scdk_sym.follower.levels`: levels of ``s`` passed or hidden in a step, and the
    solution at a level;
  - :mod:`~scdk_sym.follower.locate`: folds and bifurcations located between samples and told
    apart;
  - :mod:`~scdk_sym.follower.step_over`: stepping over a point where branches cross;
  - :mod:`~scdk_sym.follower.tangent`: the oriented tangent, ``det J_p`` and the metric at a
    point;
  - :mod:`~scdk_sym.follower.follow_rule`: the rule's constants the generated C follower
    mirrors;
- :mod:`~scdk_sym.follower.finish`: the answer at ``s = 1`` of a walk (a fold touching it, the
  parity check);
- :mod:`~scdk_sym.follower.singular`: crossing the nearest singular surface (the divergent
  branch);
- :mod:`~scdk_sym.follower.other_sheet`: the solution at ``theta0`` on the other side of a
  singular point;
- :mod:`~scdk_sym.follower.nearest`: a singular configuration near a given one;
- :mod:`~scdk_sym.follower.surface`: the singular surface at a point (side, crossing
  branches, normal, grazing);
- :mod:`~scdk_sym.follower.geometry`: chart-free comparison of configurations;
- :mod:`~scdk_sym.follower.track_rule`: the constants of the tracking rule.
"""
