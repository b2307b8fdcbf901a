"""PettingZoo environments of a team of bouncing robots (docs/model.md §24).

K robots in one room, each the kinematic twin of ``bouncesim/Bounce-v0`` (docs/model.md §23):
an action indexes the bouncing angles Φ, the robot turns by it (plus its turn noise) and
drives until its flight ends; it observes ``{"bumper": (left, right), "duration": [s]}``,
and ``infos[agent]`` carries its true pose and configuration. The world is
:class:`bouncesim.robots.kinematic_team.KinematicTeam`: continuous time, ``interact="off"``
(the robots pass through each other) or ``"bump"`` (robot-robot contact is a bump).
pettingzoo is the optional extra ``team``; ``import bouncesim`` never imports it.

- :func:`env` / :class:`TeamAECEnv` (``raw_env``): asynchronous. Every robot turns the moment
  its flight ends; the agent selected to act is the robot whose flight ended (ties in agent
  order), and after its action the world runs on to the next flight end of any robot.
- :func:`parallel_env` / :class:`TeamParallelEnv`: in rounds. Every live agent acts at once;
  a step lasts until every robot's flight has ended, a robot that has bumped waiting still (an
  obstacle) for the others. One step is one bounce of every robot, as one step of
  Bounce-v0 is one bounce.
- ``task="cover"``: the team's shared reward is the decrease of TV(pooled visits, target)
  (every robot's flights counted as Bounce-v0 counts them); ``task="navigate"``: each robot has
  a goal configuration and terminates when a flight reaches it (Bounce-v0's goal rule; the
  robot stops in the goal cell by the clock and stays there), −``step_cost`` per other bounce.
- Seeding: ``reset(seed=s)`` seeds one Generator that draws the goals and starts and spawns
  one child Generator per robot for its turn errors.

>>> team = parallel_env("lab", robots=3, task="cover", interact="bump", max_steps=20)
>>> obs, infos = team.reset(seed=0)
>>> team.agents
['robot_0', 'robot_1', 'robot_2']
>>> obs, rewards, terms, truncs, infos = team.step({a: 1 for a in team.agents})
>>> sorted(obs["robot_0"]), len(set(rewards.values()))     # one shared reward
(['bumper', 'duration'], 1)
"""

from __future__ import annotations

import math
import warnings

import numpy as np

try:
    from gymnasium import spaces
    from gymnasium.utils import seeding
    from pettingzoo import AECEnv, ParallelEnv
    from pettingzoo.utils import wrappers
except ModuleNotFoundError as exc:          # the optional extra is not installed
    if (exc.name or "").split(".")[0] not in ("pettingzoo", "gymnasium"):
        raise
    raise ModuleNotFoundError("bouncesim.team needs pettingzoo, the optional extra team: "
                              "pip install 'bouncesim[team]'.", name="pettingzoo") from None

import envs
from envs import Environment, UserError
from planners.cells import CellSpace
from planners.metrics import tv_distance

from .robots.kinematic_team import INTERACT, FlightEnd, KinematicTeam
from .robots.noise import NoiseModel
from .tasks import check_goal, check_task, cover_target, flight_cells, goal_stop, start_pose

__all__ = ["TASKS", "TeamAECEnv", "TeamParallelEnv", "env", "raw_env", "parallel_env"]

TASKS = ("cover", "navigate")
_MAX_STARTS = 10_000          # random starts tried per robot before giving up


class _Team:
    """What both environments share: the room, the task, the world and its bookkeeping."""

    def __init__(self, env, robots, task, interact, angles, noise, goals, target, max_steps,
                 step_cost, speed) -> None:
        self.room = env if isinstance(env, Environment) else envs.load(env)
        self.cells = cells = CellSpace(self.room)
        try:
            self.k = int(robots)
        except (TypeError, ValueError):
            raise UserError(f"robots must be a number of robots, got {robots!r}.") from None
        if self.k < 1:
            raise UserError(f"a team needs at least one robot, got {robots}.")
        if task not in TASKS:
            raise UserError(f"unknown task {task!r}; use cover or navigate.")
        if interact not in INTERACT:
            raise UserError(f"interact must be off or bump, got {interact!r}.")
        self.task, self.interact = task, interact
        self.angles, self.noise, self.max_steps, self.step_cost, self.speed = check_task(
            cells, angles, noise, max_steps, step_cost, speed)
        self.goals = None if goals is None else self._check_goals(goals)
        self.target = cover_target(self.cells, target)
        x0, y0, x1, y1 = self.room.bounds
        self.max_flight = math.hypot(x1 - x0, y1 - y0) + cells.h   # Bounce-v0's cap [m]
        self.names = [f"robot_{i}" for i in range(self.k)]
        self.world: KinematicTeam | None = None

    # ------------------------------------------------------------------ spaces and checks
    def observation_space(self) -> spaces.Dict:
        return spaces.Dict({
            "bumper": spaces.MultiBinary(2),
            "duration": spaces.Box(0.0, np.float32(self.max_flight / self.speed), (1,),
                                   np.float32)})

    def _check_goals(self, goals) -> list[int]:
        goals = [goals] * self.k if np.ndim(goals) == 0 else list(goals)
        if len(goals) != self.k:
            raise UserError(f"give one goal per robot: {self.k} robots, {len(goals)} goals.")
        return [check_goal(self.cells, g) for g in goals]

    def action(self, action) -> float:
        """The angle [deg] an action indexes (one-sentence error otherwise)."""
        if isinstance(action, (bool, np.bool_)) or not isinstance(action, (int, np.integer)) \
                or not 0 <= int(action) < len(self.angles):
            raise UserError(f"action {action!r} is not an index into the {len(self.angles)} "
                            "bouncing angles.")
        return self.angles[int(action)]

    # ------------------------------------------------------------------ episode
    def reset(self, rng: np.random.Generator, options: dict | None) -> None:
        """Goals, starts and every robot's first flight (no turn) launched at time 0."""
        options = dict(options or {})
        unknown = sorted(set(options) - {"starts", "goals"})
        if unknown:
            warnings.warn(f"reset ignores the unknown option {unknown[0]!r}; the options are "
                          "starts and goals.", stacklevel=3)
        goals = options.get("goals", self.goals)
        self.goal = (self._check_goals(goals) if goals is not None
                     else [int(g) for g in rng.integers(self.cells.N, size=self.k)])
        starts = options.get("starts")
        if starts is not None and (np.ndim(starts) == 0 or len(starts) != self.k):
            raise UserError(f"give one start per robot ({self.k}).")
        world = self.world = KinematicTeam(self.room, self.k, interact=self.interact,
                                           noise=self.noise, rngs=rng.spawn(self.k),
                                           speed=self.speed, max_flight=self.max_flight)
        placed: list[tuple] = []
        for i in range(self.k):
            for _ in range(_MAX_STARTS):
                given = starts[i] if starts is not None else None
                pose = start_pose(self.cells, given if given is not None
                                  else int(rng.integers(self.cells.N)))
                if self.interact == "bump" and any(
                        math.hypot(pose[0] - x, pose[1] - y) < 2 * world.radius - 1e-9
                        for x, y, _ in placed):
                    if given is not None:
                        raise UserError(f"robot {i}'s start overlaps another robot.")
                    continue
                world.place(i, *pose)
                flight = world.launch(i)
                if self.task == "cover" or goal_stop(flight.start[:2], flight.end,
                                                     flight.start[2], self.cells,
                                                     self.goal[i]) is None:
                    break
                if given is not None:
                    raise UserError(f"robot {i}'s first flight already reaches its goal; "
                                    "choose another start.")
                world.place(i, *pose)
            else:
                raise UserError(f"no start found for robot {i} (its disk overlaps the others "
                                "or its first flight reaches its goal).")
            placed.append(pose)
        self.steps = [0] * self.k
        self.reached = [False] * self.k
        self.visits = np.zeros(self.cells.P, dtype=np.int64)
        self.dropped, self.tv = 0, 1.0
        self.obs = [self._obs(False, False, 0.0) for _ in range(self.k)]
        self.infos = [self._info(i, world.robots[i].true_pose()) for i in range(self.k)]

    @staticmethod
    def _obs(left: bool, right: bool, seconds: float) -> dict:
        return {"bumper": np.array([left, right], dtype=np.int8),
                "duration": np.array([seconds], dtype=np.float32)}

    def launch(self, i: int, action) -> None:
        """Robot i turns by the action's angle and drives; navigate: a flight that reaches
        the goal is stopped there by the clock (Bounce-v0's rule, on the wall flight).
        """
        flight = self.world.launch(i, self.action(action))
        self.steps[i] += 1
        if self.task == "navigate":
            stop = goal_stop(flight.start[:2], flight.end, flight.start[2], self.cells,
                             self.goal[i])
            if stop is not None:
                self.world.clock_stop(i, stop)

    def end(self, e: FlightEnd) -> float:
        """Book a flight's end; its reward (navigate: the robot's; cover: the team's)."""
        i = e.robot
        self.obs[i] = self._obs(e.left, e.right, e.elapsed)
        if self.task == "navigate":
            self.reached[i] = e.by == "clock"
            reward = 1.0 if self.reached[i] else -self.step_cost if self.steps[i] else 0.0
        else:       # a first flight is counted; TV and rewards start at its first bounce
            p = flight_cells(self.cells, e.start, e.end)
            np.add.at(self.visits, p[p >= 0], 1)
            self.dropped += int((p < 0).sum())
            reward = 0.0
            if self.steps[i]:
                tv = tv_distance(self.visits, self.target) if self.visits.any() else 1.0
                reward, self.tv = self.tv - tv, tv
        self.infos[i] = self._info(i, e.end, e.by)
        return float(reward)

    def _info(self, i: int, pose, by: str = "") -> dict:
        x, y, deg = pose
        p = int(self.cells.cell_of_point([[x, y]])[0])
        z = int(self.cells.z(p, self.cells.orientation_of(deg))) if p >= 0 else -1
        info = {"pose": (float(x), float(y), float(deg)), "config": z, "steps": self.steps[i],
                "time": float(self.world.time), "by": by}
        if self.task == "navigate":
            info["is_success"] = self.reached[i]
            info["goal"] = self.goal[i]
        else:
            info["tv"] = self.tv
            info["visits"] = self.visits.copy()
            info["dropped"] = self.dropped
        return info


class _Base:
    """The spaces, seeding and set-up of both environments."""

    metadata = {"name": "bouncesim_team_v0", "render_modes": []}

    def _setup(self, env, robots, task, interact, angles, noise, goals, target, max_steps,
               step_cost, speed, render_mode) -> None:
        if render_mode is not None:
            raise UserError("the team environments do not render; use render_mode=None.")
        self.render_mode = None
        self.core = _Team(env, robots, task, interact, angles, noise, goals, target,
                          max_steps, step_cost, speed)
        self.possible_agents = list(self.core.names)
        self.agents = []
        self._index = {a: i for i, a in enumerate(self.possible_agents)}
        self.observation_spaces = {a: self.core.observation_space() for a in self.possible_agents}
        self.action_spaces = {a: spaces.Discrete(len(self.core.angles))
                              for a in self.possible_agents}
        self.np_random = None

    def observation_space(self, agent):
        """The agent's observation space (the same object every time)."""
        return self.observation_spaces[agent]

    def action_space(self, agent):
        """The agent's action space (the same object every time)."""
        return self.action_spaces[agent]

    def _seed(self, seed) -> None:
        if seed is not None or self.np_random is None:
            self.np_random, _ = seeding.np_random(seed)

    def close(self) -> None:
        """Nothing to release."""


class TeamAECEnv(_Base, AECEnv):
    """A team of bouncing robots, asynchronous (docs/model.md §24): the agent to act is the
    robot whose flight ended; after its action the world runs to the next flight end of any
    robot. Truncation after K·max_steps bounces of the team.

    Parameters
    ----------
    env : str, Path or Environment     a catalogue name, an env file or an environment
    robots : int                       K, the number of robots (agents ``robot_0`` ...)
    task : {"cover", "navigate"}
    interact : {"bump", "off"}         robot-robot contact is a bump, or the robots pass
                                       through each other (docs/model.md §24)
    angles : sequence of float         the bouncing angles Φ [deg] the actions index
    noise : str or NoiseModel          turn noise (``"none"``, ``"gauss:S"``, ``"model:eps=E,r=R"``)
    goals : None, int or K ints        navigate: goal configurations (None: drawn per episode)
    target : None, path or P weights   cover: the target (default uniform)
    max_steps : int                    bounces per robot before truncation
    step_cost : float                  navigate: −this for a bounce that misses the goal
    speed : float                      drive speed [m/s]
    """

    def __init__(self, env="lab", robots: int = 2, task: str = "cover", *,
                 interact: str = "bump", angles=(45.0, 90.0, 135.0),
                 noise: str | NoiseModel = "none", goals=None, target=None,
                 max_steps: int = 200, step_cost: float = 0.01, speed: float = 0.2,
                 render_mode: str | None = None) -> None:
        AECEnv.__init__(self)
        self._setup(env, robots, task, interact, angles, noise, goals, target, max_steps,
                    step_cost, speed, render_mode)

    def reset(self, seed: int | None = None, options: dict | None = None) -> None:
        """Place the robots and run the world to the first flight end."""
        self._seed(seed)
        self.core.reset(self.np_random, options)
        self.agents = list(self.possible_agents)
        self.rewards = dict.fromkeys(self.agents, 0.0)
        self._cumulative_rewards = dict.fromkeys(self.agents, 0.0)
        self.terminations = dict.fromkeys(self.agents, False)
        self.truncations = dict.fromkeys(self.agents, False)
        self._waiting: list[int] = []
        self._bounces = 0
        self.infos = {a: self.core.infos[i] for a, i in self._index.items()}
        self._run()
        self._clear_rewards()                   # the first flights are not paid (Bounce-v0)
        self.agent_selection = self.possible_agents[self._waiting[0]]

    def observe(self, agent):
        """The agent's last observation (its last flight's end)."""
        obs = self.core.obs[self._index[agent]]
        return {k: v.copy() for k, v in obs.items()}

    def _run(self) -> None:
        """Run the world until a live robot waits for its action."""
        core = self.core
        while not self._waiting:
            ends = core.world.advance()
            if not ends:
                return
            for e in ends:
                reward = core.end(e)
                agent = self.possible_agents[e.robot]
                self.infos[agent] = core.infos[e.robot]
                if core.task == "cover":
                    for a in self.agents:
                        self.rewards[a] += reward
                else:
                    self.rewards[agent] += reward
                if core.reached[e.robot]:
                    self.terminations[agent] = True
                else:
                    self._waiting.append(e.robot)

    def step(self, action) -> None:
        """The selected robot turns by ``angles[action]`` and drives; the world runs on."""
        agent = self.agent_selection
        if self.terminations[agent] or self.truncations[agent]:
            self._was_dead_step(action)
            return
        i = self._index[agent]
        self._cumulative_rewards[agent] = 0.0
        self._clear_rewards()
        self.core.launch(i, action)
        self._waiting.remove(i)
        self._bounces += 1
        if self._bounces >= self.core.max_steps * self.core.k:
            for a in self.agents:
                self.truncations[a] = not self.terminations[a]
        else:
            self._run()
        if self._waiting:
            self.agent_selection = self.possible_agents[self._waiting[0]]
        self._accumulate_rewards()
        self._deads_step_first()


class TeamParallelEnv(_Base, ParallelEnv):
    """A team of bouncing robots in rounds (docs/model.md §24): every live agent acts at once
    and a step lasts until every robot's flight has ended (a robot that bumped waits still);
    truncation after max_steps steps.

    Parameters are :class:`TeamAECEnv`'s (``max_steps``: steps of the team here).
    """

    def __init__(self, env="lab", robots: int = 2, task: str = "cover", *,
                 interact: str = "bump", angles=(45.0, 90.0, 135.0),
                 noise: str | NoiseModel = "none", goals=None, target=None,
                 max_steps: int = 200, step_cost: float = 0.01, speed: float = 0.2,
                 render_mode: str | None = None) -> None:
        self._setup(env, robots, task, interact, angles, noise, goals, target, max_steps,
                    step_cost, speed, render_mode)

    def _round(self) -> dict[str, float]:
        """Run the world until no robot moves; the rewards of the flights that ended."""
        core, rewards = self.core, dict.fromkeys(self.agents, 0.0)
        tv0 = core.tv
        while True:
            ends = core.world.advance()
            if not ends:
                break
            for e in ends:
                reward = core.end(e)
                if core.task == "navigate":
                    rewards[self.possible_agents[e.robot]] += reward
        if core.task == "cover":
            rewards = dict.fromkeys(self.agents, float(tv0 - core.tv))
        return rewards

    def _out(self, agents) -> tuple[dict, dict]:
        core = self.core
        obs = {a: {k: v.copy() for k, v in core.obs[self._index[a]].items()} for a in agents}
        return obs, {a: core.infos[self._index[a]] for a in agents}

    def reset(self, seed: int | None = None, options: dict | None = None):
        """Place the robots and run every first flight (no turn) to its end."""
        self._seed(seed)
        self.core.reset(self.np_random, options)
        self.agents = list(self.possible_agents)
        self._steps = 0
        self._round()
        return self._out(self.agents)

    def step(self, actions: dict):
        """One bounce of every live robot: each turns by ``angles[actions[agent]]`` and
        drives until its flight ends, those that end first waiting still.
        """
        live = list(self.agents)
        if not live:
            raise UserError("call reset() before step(): no agent is live.")
        missing = [a for a in live if a not in actions]
        if missing:
            raise UserError(f"every live agent acts each step; no action for {missing[0]}.")
        for a in live:                          # all checked before any robot moves
            self.core.action(actions[a])
        for a in live:
            self.core.launch(self._index[a], actions[a])
        rewards = self._round()
        self._steps += 1
        terms = {a: bool(self.core.reached[self._index[a]]) for a in live}
        truncs = {a: not terms[a] and self._steps >= self.core.max_steps for a in live}
        obs, infos = self._out(live)
        self.agents = [a for a in live if not (terms[a] or truncs[a])]
        return obs, rewards, terms, truncs, infos


def raw_env(env="lab", robots: int = 2, task: str = "cover", **kwargs) -> TeamAECEnv:
    """The AEC environment without wrappers (:class:`TeamAECEnv`)."""
    return TeamAECEnv(env, robots, task, **kwargs)


def env(env="lab", robots: int = 2, task: str = "cover", **kwargs):
    """The AEC environment (:class:`TeamAECEnv`) in PettingZoo's usual wrappers (actions in
    bounds, reset before step).
    """
    e = TeamAECEnv(env, robots, task, **kwargs)
    return wrappers.OrderEnforcingWrapper(wrappers.AssertOutOfBoundsWrapper(e))


def parallel_env(env="lab", robots: int = 2, task: str = "cover",
                 **kwargs) -> TeamParallelEnv:
    """The parallel environment (:class:`TeamParallelEnv`)."""
    return TeamParallelEnv(env, robots, task, **kwargs)
