"""bouncesim: plan, execute and draw bump-and-clock robots from a notebook.

The names outside code can rely on through later refactors, in the order of a session
(every name is imported on first use, so ``import bouncesim`` stays light and never needs
pybullet or pyserial):

- maps: :func:`load` (``envs.load``), :func:`env_names`, :func:`import_map`
  (``envs.map_import``: an occupancy-grid map as an environment);
- cells: :class:`CellSpace` (``planners.cells``);
- navigation: :data:`PLANNERS` and :func:`make_planner` (``planners.navigation``: one
  protocol, one :class:`Route`), the planners :class:`Navigator` (the paper's step model)
  and :class:`ExactNavigator` (exact bump poses), :class:`Plan`;
- coverage: :func:`design_mix`, :func:`model_for`, :data:`MODELS`, :class:`TurnNoise`
  (``planners.coverage``), :class:`PolicyMix`, :func:`tv_distance`,
  :func:`coverage_metrics` (``planners.coverage.cover_time``: cover times, docs/model.md §20a);
- robots: :class:`Robot` (the interface a body implements), :func:`make_robot`,
  :func:`parse_noise` (a noise spec as a body's noise model), :func:`noise_for_mix`
  (``bouncesim.robots``);
- runs: :func:`execute` (``bouncesim.runs.execute``: the one run loop, for plans, mixes and
  feedback policies), :class:`Trace`, :func:`navigate_feedback` (``bouncesim.runs.execute``:
  closed-loop navigation of any robot);
- figures: :func:`draw_trace`, :func:`draw_env`, :func:`heatmap`, :func:`save_figure`.

Examples
--------
>>> import bouncesim
>>> cs = bouncesim.CellSpace(bouncesim.load("lab"))
>>> route = bouncesim.Navigator(cs, [90, 135]).plan(8, 0)
>>> str(route.plan)
'90° 90° 00000000 90° 90°'
>>> with bouncesim.make_robot("kinematic", cs.env) as bot:
...     run = bouncesim.execute(route.plan, bot, start=8, goal=0)
>>> run.success
True
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__all__ = ["MODELS", "PLANNERS", "CellSpace", "ExactNavigator", "Navigator", "Plan", "PolicyMix",
           "Robot", "Route", "Trace", "TurnNoise", "coverage_metrics", "design_mix", "draw_env",
           "draw_trace", "env_names", "execute", "heatmap", "import_map", "load", "make_planner",
           "make_robot", "model_for", "navigate_feedback", "noise_for_mix", "parse_noise",
           "save_figure", "tv_distance"]

# public name -> (module, attribute): imported on first access (PEP 562)
_LAZY = {
    "load": ("envs", "load"),
    "env_names": ("envs", "names"),
    "import_map": ("envs.map_import", "import_map"),
    "CellSpace": ("planners.cells", "CellSpace"),
    "PLANNERS": ("planners.navigation", "PLANNERS"),
    "make_planner": ("planners.navigation", "make_planner"),
    "Route": ("planners.navigation", "Route"),
    "Navigator": ("planners.navigation", "Navigator"),
    "ExactNavigator": ("planners.navigation", "ExactNavigator"),
    "Plan": ("planners.plan", "Plan"),
    "PolicyMix": ("planners.plan", "PolicyMix"),
    "MODELS": ("planners.coverage", "MODELS"),
    "TurnNoise": ("planners.noise", "TurnNoise"),
    "design_mix": ("planners.coverage", "design_mix"),
    "model_for": ("planners.coverage", "model_for"),
    "tv_distance": ("planners.metrics", "tv_distance"),
    "Robot": ("bouncesim.robots.base", "Robot"),
    "make_robot": ("bouncesim.robots.factory", "make_robot"),
    "parse_noise": ("bouncesim.robots.noise", "parse_noise"),
    "noise_for_mix": ("bouncesim.robots.noise", "noise_for_mix"),
    "execute": ("bouncesim.runs.execute", "execute"),
    "Trace": ("bouncesim.runs.trace", "Trace"),
    "navigate_feedback": ("bouncesim.runs.execute", "navigate_feedback"),
    "draw_trace": ("bouncesim.plots", "draw_trace"),
    "draw_env": ("bouncesim.plots", "draw_env"),
    "save_figure": ("bouncesim.plots", "save_figure"),
    "heatmap": ("bouncesim.coverage_plots", "heatmap"),
    "coverage_metrics": ("planners.coverage.cover_time", "coverage_metrics"),
}

if TYPE_CHECKING:  # for type checkers and IDEs only; at run time __getattr__ imports
    from envs import load
    from envs import names as env_names
    from envs.map_import import import_map
    from planners.cells import CellSpace
    from planners.coverage import MODELS, design_mix, model_for
    from planners.coverage.cover_time import coverage_metrics
    from planners.metrics import tv_distance
    from planners.navigation import PLANNERS, ExactNavigator, Navigator, Route, make_planner
    from planners.noise import TurnNoise
    from planners.plan import Plan, PolicyMix

    from .coverage_plots import heatmap
    from .plots import draw_env, draw_trace, save_figure
    from .robots.base import Robot
    from .robots.factory import make_robot
    from .robots.noise import noise_for_mix, parse_noise
    from .runs.execute import execute, navigate_feedback
    from .runs.trace import Trace


def __getattr__(name: str) -> Any:
    """Import a public name of :data:`__all__` on first access and cache it here."""
    try:
        module, attr = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'bouncesim' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """Module attributes, the lazy public names included."""
    return sorted(set(globals()) | set(__all__))
