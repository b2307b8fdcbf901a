"""Planners: everything computed from a map alone, with no robot (docs/model.md).

Two wings share one floor of concepts; neither wing imports the other (tests/test_layering.py):

- shared floor: :mod:`.cells` (position cells, configuration indices z = k·P + p, the step
  table), :mod:`.boundary` (the C-space boundary in contact bins), :mod:`.noise`
  (:class:`~.noise.TurnNoise` and the one noise-spec grammar), :mod:`.measures` (the goal
  rule, the flight cap, the heading wrap, a step plan's flights), :mod:`.plan`
  (:class:`~.plan.Plan` and :class:`~.plan.PolicyMix`: what a robot executes),
  :mod:`.metrics` (TV distance), :mod:`.resources` (memory estimates and refusals),
  :mod:`.registry` (names checked once, with "did you mean");
- :mod:`.navigation`: one :class:`~.navigation.Planner` protocol, one
  :class:`~.navigation.Route`, the registry :data:`~.navigation.PLANNERS` and
  :func:`~.navigation.make_planner` (step, exact, reliable, feedback);
- :mod:`.coverage`: one :class:`~.coverage.CoverageModel` protocol, the registry
  :data:`~.coverage.MODELS` and :func:`~.coverage.model_for` (step, sampled, event), the
  chains (:mod:`.coverage.markov`), mixes in epochs (:mod:`.coverage.timeshare`), horizons
  and the mix design α.

Nothing here imports ``bouncesim``, pybullet, pyserial or matplotlib.
"""
