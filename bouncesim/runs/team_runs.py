"""Coverage runs of a team of K bouncing robots in one room (docs/model.md §24, §22):
:func:`team_coverage` runs :class:`bouncesim.robots.kinematic_team.KinematicTeam` with one
bouncing angle and counts every robot's steps as the single-robot validation counts them.

Each robot starts at a configuration drawn uniformly (distinct position cells, so that no two
start overlapped), bounces by φ plus the turn noise after every bump (a wall's or, with
``interact="bump"``, another robot's) and counts the steps of each flight
(:func:`bouncesim.tasks.flight_cells`: forward steps of h, then the bump step) once its own
burn-in is over, until it has counted ``steps``. The team keeps moving until every robot has
counted its share, so a robot that finished early is still an obstacle for the others.

With ``interact="off"`` the robots pass through each other: the team is K independent twins,
and its pooled histogram predicts like one robot's (the model's limit). With ``"bump"`` the
difference from that prediction is the effect of the robots meeting; ``meetings`` counts the
flights another robot ended.

>>> import envs
>>> from bouncesim.robots.noise import parse_noise
>>> res = team_coverage(envs.load("lab"), 90.0, parse_noise("model:eps=45,r=0.9", 1.0),
...                     robots=3, steps=200, burn_in=0, rng=np.random.default_rng(0))
>>> int(res.counts.sum()), res.counts.shape
(600, (48,))
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs import Environment, UserError
from planners.cells import CellSpace

from ..robots.kinematic_team import INTERACT, KinematicTeam
from ..robots.noise import NoiseModel
from ..tasks import flight_cells

__all__ = ["TeamCoverage", "team_coverage"]


@dataclass(frozen=True)
class TeamCoverage:
    """The counted steps of one team run.

    Attributes
    ----------
    counts : (P,) int array     steps counted in each position cell, all robots pooled
    per_robot : (K, P) int array the same, robot by robot
    dropped : int               counted steps whose point lies in no free cell
    flights : int               counted flights (a flight counts when its steps do)
    meetings : int              counted flights that another robot ended
    seconds : float             the team's clock at the end [s]
    first_visit : (P,) int array   for each cell, the smallest own-step index (burn-in
                                included) at which any robot counted a step in it; −1 never
    first_meeting : int         the first own-step index (burn-in included) at which two
                                robots counted their steps in one cell, the model's meeting
                                (docs/model.md §20a); −1 none
    colocations : int           (pair of robots, own step) meetings in that sense, over the
                                own steps 0 … burn_in + steps − 1
    first_contact : int         the own-step index of the first bump step that another robot
                                ended (−1 none; always −1 with ``interact="off"``)
    """

    counts: np.ndarray
    per_robot: np.ndarray
    dropped: int
    flights: int
    meetings: int
    seconds: float
    first_visit: np.ndarray | None = None
    first_meeting: int = -1
    colocations: int = 0
    first_contact: int = -1

    def covered(self, t) -> np.ndarray:
        """The team's covered fraction after each robot's first ``t`` own steps (§20a, burn-in
        included): the share of the cells with a first visit before t.
        """
        fv = self.first_visit
        seen = np.where(fv >= 0, fv, np.iinfo(np.int64).max)
        return (seen[None, :] < np.asarray(t, dtype=np.int64)[:, None]).mean(axis=1)

    @property
    def meetings_per_1000_steps(self) -> float:
        """Robot-robot bumps per 1000 counted steps of one robot."""
        total = int(self.per_robot.sum()) + self.dropped
        return 1000.0 * self.meetings / total if total else 0.0


def team_coverage(env: Environment, angle_deg: float, noise: NoiseModel | None, *,
                  robots: int, steps: int, burn_in: int = 0, interact: str = "bump",
                  rng: np.random.Generator, cells: CellSpace | None = None,
                  speed: float = 0.2, starts=None) -> TeamCoverage:
    """Run a team of ``robots`` bouncing by ``angle_deg`` until each has counted ``steps``
    steps after ``burn_in`` uncounted ones (see the module docstring); ``starts``: the
    robots' start configurations z (default: drawn uniformly, in distinct cells).
    """
    if interact not in INTERACT:
        raise UserError(f"interact must be off or bump, got {interact!r}.")
    cells = cells if cells is not None else CellSpace(env)
    k = int(robots)
    if k < 1 or k > cells.P:
        raise UserError(f"a team needs 1 to {cells.P} robots in {env.name} (one per cell at "
                        f"the start), got {robots}.")
    rngs = list(rng.spawn(k))
    team = KinematicTeam(env, k, interact=interact, noise=noise, rngs=rngs, speed=speed)
    if starts is None:
        cells_at = rng.choice(cells.P, size=k, replace=False)
        headings = rng.integers(0, cells.K, size=k) * cells.delta_deg
    else:
        if len(starts) != k:
            raise UserError(f"give one start per robot: {k} robots, {len(starts)} starts.")
        cells_at, ks = cells.pk(np.asarray(starts, dtype=np.int64))
        headings = ks * cells.delta_deg
    for i, (p, h) in enumerate(zip(cells_at, headings)):
        x, y = cells.centres[p]
        team.place(i, float(x), float(y), float(h))
    per_robot = np.zeros((k, cells.P), dtype=np.int64)
    first = np.full(cells.P, np.iinfo(np.int64).max, dtype=np.int64)
    made = np.zeros(k, dtype=np.int64)             # steps made, burn-in included
    dropped = flights = meetings = 0
    contact = np.iinfo(np.int64).max
    walk: list[list] = [[] for _ in range(k)]      # each robot's cells, own step by step
    for i in range(k):
        team.launch(i)                             # the first flight: no turn before it
    while (made < burn_in + steps).any():
        ends = team.advance()
        if not ends:
            raise RuntimeError("the team stopped moving before its robots counted their steps.")
        for e in ends:
            i = e.robot
            z = flight_cells(cells, e.start, e.end)
            seen = z >= 0
            np.minimum.at(first, z[seen], int(made[i]) + np.flatnonzero(seen))
            walk[i].append(z)
            if e.by == "robot":
                contact = min(contact, int(made[i]) + len(z) - 1)
            lo = max(0, burn_in - int(made[i]))
            hi = max(0, min(len(z), burn_in + steps - int(made[i])))
            made[i] += len(z)
            if hi > lo:
                part = z[lo:hi]
                ok = part >= 0
                np.add.at(per_robot[i], part[ok], 1)
                dropped += int((~ok).sum())
                flights += 1
                meetings += e.by == "robot"
            team.launch(i, angle_deg)
    first[first == np.iinfo(np.int64).max] = -1
    met, pairs = _colocations([np.concatenate(w)[:burn_in + steps] for w in walk])
    return TeamCoverage(per_robot.sum(0), per_robot, dropped, flights, meetings, team.time,
                        first, met, pairs,
                        -1 if contact == np.iinfo(np.int64).max else contact)


def _colocations(walks: list) -> tuple[int, int]:
    """(first own step at which two robots are counted in one cell or −1, and the number of
    (pair, step) such meetings) of equally long cell walks (−1: a dropped step).
    """
    if len(walks) < 2:
        return -1, 0
    w = np.sort(np.stack(walks), axis=0)
    same = (w[1:] == w[:-1]) & (w[1:] >= 0)        # robots beside each other, sorted by cell
    # a cell held by m robots has m − 1 adjacent equal entries but m (m − 1) / 2 pairs
    pairs = 0
    run = np.zeros(w.shape[1], dtype=np.int64)
    for row in same:
        run = np.where(row, run + 1, 0)
        pairs += int(run.sum())
    hit = np.flatnonzero(same.any(axis=0))
    return (int(hit[0]) if hit.size else -1), pairs
