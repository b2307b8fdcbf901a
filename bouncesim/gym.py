"""A Gymnasium environment of the bouncing robot: ``bouncesim/Bounce-v0`` (docs/model.md §23).

Importing this module registers the environment (gymnasium is the optional extra ``gym``;
``import bouncesim`` never imports it)::

    import gymnasium
    import bouncesim.gym
    env = gymnasium.make("bouncesim/Bounce-v0", env="lab", task="navigate", goal=0)

- One step is one bounce: the action indexes the bouncing angles Φ; the robot turns CCW by
  Φ[action] (plus the turn noise) and drives until its bumper closes.
- The observation is what the robot senses: ``{"bumper": (left, right) in {0, 1},
  "duration": [flight time [s]]}``. The true pose and the cell are in ``info`` only.
- ``task="navigate"``: reward +1 and the end of the episode when a flight reaches the goal
  configuration (its cell with its heading, the executor's success rule, docs/model.md §21),
  ``-step_cost`` for every other bounce. That flight is stopped by the clock inside the
  goal cell (:func:`goal_stop`), so the last observation has no bump and ``info["pose"]``
  is in the goal cell when ``info["is_success"]``.
- ``task="cover"``: the reward of a bounce is the decrease of the total-variation distance
  between the visit histogram (docs/model.md §22's counted steps) and the target, so the return
  of an episode is 1 − the final TV.
- Episodes are truncated after ``max_steps`` bounces. Seeding follows Gymnasium:
  ``reset(seed=s)`` seeds ``self.np_random``, which draws the start and every turn error.

The simulator is the kinematic twin (:class:`bouncesim.robots.kinematic.KinematicRobot`),
several thousand bounces per second on ``lab``.

Examples
--------
>>> import gymnasium
>>> env = gymnasium.make("bouncesim/Bounce-v0", env="lab", task="navigate", goal=0)
>>> obs, info = env.reset(seed=0, options={"start": 8})   # bottom right, facing the east wall
>>> obs["bumper"].tolist(), float(obs["duration"][0])
([1, 1], 0.0)
>>> [float(a) for a in env.unwrapped.angles]
[45.0, 90.0, 135.0]
>>> for a in (1, 1):                  # the plan '90° 90° 00000000 90° 90°' from 8 to 0
...     obs, reward, terminated, truncated, info = env.step(a)
>>> round(float(obs["duration"][0]), 4), [round(v, 6) for v in info["pose"]]
(13.6, [0.17, 0.17, 180.0])
>>> for a in (1, 1):
...     obs, reward, terminated, truncated, info = env.step(a)
>>> reward, terminated, info["is_success"]
(1.0, True, True)
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

try:
    import gymnasium
    from gymnasium import spaces
except ModuleNotFoundError as exc:          # the optional extra is not installed
    if exc.name != "gymnasium":
        raise
    raise ModuleNotFoundError("bouncesim.gym needs gymnasium, the optional extra gym: "
                              "pip install 'bouncesim[gym]'.", name="gymnasium") from None

import envs
from envs import Environment, UserError
from planners.cells import CellSpace
from planners.measures import wrap180
from planners.metrics import tv_distance

from .robots.factory import make_robot
from .robots.noise import NoiseModel
from .tasks import (
    check_goal,
    check_task,
    cover_target,
    flight_cells,
    flight_reaches,
    goal_stop,
    start_pose,
)

__all__ = ["ENV_ID", "TASKS", "BounceEnv", "flight_reaches", "goal_stop"]

ENV_ID = "bouncesim/Bounce-v0"
"""The id under which importing this module registers :class:`BounceEnv`."""
TASKS = ("navigate", "cover")
_MAX_STARTS = 10_000          # random starts tried before giving up (navigate)
_TRAIL = 400                  # flights kept for rendering


class BounceEnv(gymnasium.Env):
    """A bump-and-clock robot in a room; one step is one bounce (docs/model.md §23).

    Parameters
    ----------
    env : str, Path or Environment
        A catalogue name (``envs.names()``), an env file, or an environment.
    task : {"navigate", "cover"}
    angles : sequence of float
        The bouncing angles Φ [deg] the actions index, multiples of 360°/K (default 45°, 90°,
        135°).
    noise : str or NoiseModel
        Turn noise: ``"none"``, ``"gauss:SIGMA"`` or ``"model:eps=E,r=R"`` (docs/model.md §16, §21).
    goal : int
        Navigate: the goal configuration z (docs/model.md §6); ``reset(options={"goal": z})``
        changes it for one episode.
    target : None, path or array of P weights
        Cover: the target over the position cells (default uniform; a file as
        ``planners.coverage.targets.TARGET_FORMATS`` describes).
    max_steps : int      bounces before the episode is truncated
    step_cost : float    navigate: the reward of a bounce that does not reach the goal is −this
    speed : float        drive speed [m/s]
    render_mode : {None, "rgb_array", "human"}
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 4}

    def __init__(self, env: str | Path | Environment = "lab", task: str = "navigate", *,
                 angles=(45.0, 90.0, 135.0), noise: str | NoiseModel = "none", goal: int = 0,
                 target=None, max_steps: int = 200, step_cost: float = 0.01,
                 speed: float = 0.2, render_mode: str | None = None) -> None:
        self.room = env if isinstance(env, Environment) else envs.load(env)
        self.cells = cells = CellSpace(self.room)
        if task not in TASKS:
            raise UserError(f"unknown task {task!r}; use navigate or cover.")
        self.task = task
        self.angles, self.noise, self.max_steps, self.step_cost, self.speed = check_task(
            cells, angles, noise, max_steps, step_cost, speed)
        self.goal = check_goal(self.cells, goal)
        self.target = cover_target(self.cells, target)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise UserError(f"unknown render mode {render_mode!r}; use None, human or "
                            "rgb_array.")
        self.render_mode = render_mode
        x0, y0, x1, y1 = self.room.bounds
        self.max_flight = math.hypot(x1 - x0, y1 - y0) + cells.h   # [m] no line is longer
        self.action_space = spaces.Discrete(len(self.angles))
        self.observation_space = spaces.Dict({
            "bumper": spaces.MultiBinary(2),
            "duration": spaces.Box(0.0, np.float32(self.max_flight / self.speed), (1,),
                                   np.float32)})
        self._robot = None
        self._fig = None

    # ------------------------------------------------------------------ checks
    # ------------------------------------------------------------------ simulation
    def _fly(self) -> tuple[dict, tuple, tuple]:
        """Drive until a bump: (observation, pose before, pose after)."""
        bot = self._robot
        before = bot.true_pose()
        ev = bot.drive_until_bump(self.speed, self.max_flight / self.speed)
        after = bot.true_pose()
        obs = {"bumper": np.array([ev.left, ev.right], dtype=np.int8),
               "duration": np.array([ev.elapsed], dtype=np.float32)}
        self._trail.append(after[:2])
        return obs, before, after

    def _stop_at(self, xy, before) -> tuple[dict, tuple]:
        """The flight that reached the goal, stopped by the clock at ``xy`` [m]: the robot
        is put there; (observation: no bump, the time to ``xy``; the pose there).
        """
        x, y = (float(v) for v in xy)
        self._robot.place(x, y, before[2])
        self._trail[-1] = (x, y)
        seconds = math.hypot(x - before[0], y - before[1]) / self.speed
        obs = {"bumper": np.zeros(2, dtype=np.int8),
               "duration": np.array([seconds], dtype=np.float32)}
        return obs, self._robot.true_pose()

    def _count(self, before, after) -> int:
        """Add the flight's counted steps to the visit histogram (docs/model.md §8, §17);
        returns the position cell of the contact (−1: none).
        """
        p = flight_cells(self.cells, before, after)
        np.add.at(self._visits, p[p >= 0], 1)
        self._dropped += int((p < 0).sum())
        return int(p[-1])

    def _info(self, pose, p: int | None = None) -> dict[str, Any]:
        x, y, deg = pose
        if p is None:
            p = int(self.cells.cell_of_point([[x, y]])[0])
        z = int(self.cells.z(p, self.cells.orientation_of(deg))) if p >= 0 else -1
        info: dict[str, Any] = {"pose": (float(x), float(y), float(deg)), "config": z,
                                "steps": self._steps}
        if self.task == "navigate":
            info["is_success"] = self._reached
            info["goal"] = self._goal
        else:
            info["tv"] = self._tv
            info["visits"] = self._visits.copy()
            info["dropped"] = self._dropped
        return info

    # ------------------------------------------------------------------ Gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode: place the robot and drive it to its first bump.

        ``options``: ``start`` (a configuration z or a pose (x [m], y [m], heading [deg]);
        default a configuration drawn uniformly from ``self.np_random``) and, for navigate,
        ``goal`` (a configuration z, for this episode). A random start whose first flight
        already reaches the goal is drawn again; a given one is refused.
        """
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - {"start", "goal"}
        if unknown:
            raise UserError(f"unknown reset option {sorted(unknown)[0]!r}; use start or goal.")
        self._goal = check_goal(self.cells, options.get("goal", self.goal))
        start = options.get("start")
        self._robot = make_robot("kinematic", self.room, noise=self.noise, rng=self.np_random)
        self._steps, self._reached, self._tv, self._dropped = 0, False, 1.0, 0
        self._visits = np.zeros(self.cells.P, dtype=np.int64)
        for _ in range(_MAX_STARTS):
            pose = start_pose(self.cells, start if start is not None
                              else int(self.np_random.integers(self.cells.N)))
            self._robot.place(*pose)
            self._trail = [pose[:2]]
            obs, before, after = self._fly()
            if self.task == "cover" or not flight_reaches(before[:2], after[:2], before[2],
                                                          self.cells, self._goal):
                break
            if start is not None:
                raise UserError("the start's first flight already reaches the goal; choose "
                                "another start.")
        else:
            raise UserError(f"no start found whose first flight misses goal {self._goal}.")
        p = self._count(before, after) if self.task == "cover" else None
        if self.render_mode == "human":
            self.render()
        return obs, self._info(after, p)

    def step(self, action):
        """One bounce: turn by Φ[action] (with the turn noise), drive until the bumper closes."""
        if self._robot is None:
            raise UserError("call reset() before step().")
        if not self.action_space.contains(action):
            raise UserError(f"action {action!r} is not an index into the "
                            f"{len(self.angles)} bouncing angles.")
        self._robot.turn(wrap180(self.angles[int(action)]))   # the shorter way (§21)
        obs, before, after = self._fly()
        self._steps += 1
        if self.task == "navigate":
            stop = goal_stop(before[:2], after[:2], before[2], self.cells, self._goal)
            self._reached = stop is not None
            if self._reached:       # the clock stops it in the goal cell, before the wall
                obs, after = self._stop_at(stop, before)
            reward = 1.0 if self._reached else -self.step_cost
            terminated, p = self._reached, None
        else:
            p = self._count(before, after)
            tv = tv_distance(self._visits, self.target) if self._visits.any() else 1.0
            reward, self._tv = self._tv - tv, tv
            terminated = False
        truncated = not terminated and self._steps >= self.max_steps
        if self.render_mode == "human":
            self.render()
        return obs, float(reward), terminated, truncated, self._info(after, p)

    def render(self):
        """``rgb_array``: an (H, W, 3) uint8 picture of the room, the flights and the robot;
        ``human``: the same in a matplotlib window; None: nothing.
        """
        if self.render_mode is None or self._robot is None:
            return None
        import matplotlib
        if self.render_mode == "rgb_array":
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure
            x0, y0, x1, y1 = self.room.bounds
            fig = Figure(figsize=(5, 0.6 + 4.4 * (y1 - y0) / (x1 - x0)), dpi=80)
            FigureCanvasAgg(fig)
        else:
            import matplotlib.pyplot as plt
            if self._fig is None:
                self._fig = plt.figure(figsize=(5, 5))
            fig = self._fig
            fig.clf()
        from .plots import draw_env
        ax = fig.add_subplot(1, 1, 1)
        draw_env(ax, self.room, self.cells)
        if self.task == "navigate":
            p, _ = self.cells.pk(self._goal)
            gx, gy = self.cells.centres[int(p)]
            h = self.cells.h
            ax.add_patch(matplotlib.patches.Rectangle((gx - h / 2, gy - h / 2), h, h,
                                                      color="green", alpha=0.3))
        trail = np.asarray(self._trail[-_TRAIL:])
        ax.plot(trail[:, 0], trail[:, 1], "-", color="#1f77b4", lw=1)
        x, y, deg = self._robot.true_pose()
        r = self.room.robot_radius
        ax.add_patch(matplotlib.patches.Circle((x, y), r, color="#d62728", alpha=0.6))
        ax.plot([x, x + r * math.cos(math.radians(deg))],
                [y, y + r * math.sin(math.radians(deg))], color="black", lw=2)
        ax.set_title(f"{self.task}, bounce {self._steps}", fontsize=9)
        if self.render_mode == "human":
            import matplotlib.pyplot as plt
            plt.pause(1.0 / self.metadata["render_fps"])
            return None
        fig.tight_layout()
        fig.canvas.draw()
        return np.asarray(fig.canvas.buffer_rgba())[:, :, :3].copy()

    def close(self) -> None:
        """Close the human-mode window, if any."""
        if self._fig is not None:
            import matplotlib.pyplot as plt
            plt.close(self._fig)
            self._fig = None


if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="bouncesim.gym:BounceEnv")
