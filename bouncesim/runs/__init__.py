"""Runs: executing policies on robots, and what comes of it.

- :mod:`.execute`: :func:`~.execute.execute`, the one loop that runs a plan or a policy mix on
  a robot, and its records :class:`~.execute.PlanRun`, :class:`~.execute.MixRun`;
- :mod:`.trace`: :class:`~.trace.Trace`, the event log of a run;
- :mod:`.sweep`: seeded, resumable parameter sweeps (:func:`~.sweep.run_sweep`), run by the
  executors of :mod:`.executors` (serial, process pool, Dask);
- :mod:`.metadata`: :func:`~.metadata.versions`, :func:`~.metadata.git_revision` and
  ``config.json`` for every run's output folder.

Import from the modules (``from bouncesim.runs.execute import execute``): the package itself
stays empty, so running a plan does not import the sweep machinery.
"""
