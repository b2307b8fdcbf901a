"""The exact navigation planner: plans over exact bump poses (docs/model.md §13).

The step model (:mod:`planners.navigation`) puts every bump at a cell centre; a continuous
robot drives on to the real wall. This planner keeps the robot's exact pose after every bump:
the contact point on the C-space boundary (where the robot stops, ``CONTACT_GAP`` short of
the wall) and its heading after the turn. Flights are the exact ray casts of the motion layer
(:mod:`envs.motion`, the kinematic twin's casts), so every plan replays exactly.

- Search: uniform-cost over states (contact bin × heading × current angle); the contact
  bins are the event model's (:class:`planners.boundary.Boundary`, arc-length bins of
  h/4 by default). Each state keeps the exact pose of its first settled arrival. A single
  query is A* with scalar casts (a few hundred states); all pairs use Dial's buckets as wide
  as the smallest edge weight: the lowest bucket is final as a whole, so it is expanded at
  once over many starts' trees, with one vectorised ray cast for the flights not cast yet
  (a flight depends on its pose and heading only: :mod:`planners.navigation.exact._batch`).
- Cost: w1 per step-equivalent of travel (flight length / h) and per same-angle bump, w2 per
  change of angle; the first bump costs min(w1, w2) (any start angle, as in §12).
- Goal: after the last turn the heading equals the goal heading and the flight passes through
  the goal cell; the plan ends with a final drive (``final_m``) by the clock to the point of
  that flight's chord through the cell nearest the cell's centre.
- Contact rule (optional ``contact``, docs/model.md §9): a flight whose contact is outside
  the bumper arc slides on to its bump (:func:`envs.contact.contact_flights`); it costs and
  expects its clock length, and goal arrivals stay on its straight part.
- Candidates: :meth:`ExactNavigator.plans` lists every goal arrival within a cost slack of
  the best (one per final state), for a reliability layer that ranks near-optimal plans.

Examples
--------
A 4 × 3 cell room (h = 0.34 m, K = 8): from the centre of cell (0, 0) facing east to cell
(3, 2) facing north. The robot drives east to the wall (1.02 m less the 1e-9 m contact gap),
turns 90° and drives north to the goal cell's centre, where it touches the north wall:

>>> from envs import Environment
>>> from planners.cells import CellSpace
>>> env = Environment.from_dict({"boundary": [[0, 0], [1.36, 0], [1.36, 1.02], [0, 1.02]],
...     "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}})
>>> cs = CellSpace(env)
>>> nav = ExactNavigator(cs, [90, 135])
>>> route = nav.plan(cs.z(0, 0), cs.z(11, 2))
>>> route.plan.exact_text(), round(route.cost, 6)
('000 90° 00 | flights 1.019999999 m | final 0.679999999 m', 6.0)
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from envs import UserError
from envs.contact import slide_on
from envs.motion import BUMP_RANGE, ContactParams, casters, drive_distance

from ...boundary import Boundary, bins_estimate
from ...cells import CellSpace
from ...plan import Plan
from ...resources import DEFAULT_MAX_MEMORY, MemoryEstimate, check
from ..base import PairTable, Route, check_angles, check_config, check_weights
from ._batch import FlightTable, SearchArrays, search_many
from ._cast import HeadingCaster
from ._chords import chords

__all__ = ["ExactNavigator", "ExactAllPairs", "ExactSearch", "refuse_turn_in"]

_IMPROVE = 1e-9          # a new arrival replaces a state's pose when cheaper by this
_BATCH_BYTES = 4e8       # all pairs: the search arrays of one batch of starts [bytes]
# memory estimate (bytes): per contact bin (Boundary's tables, the scalar copies), per state
# of one search (cost, pred, pos, flight, used, the heap), per distinct flight of the
# all-pairs table (its arrays, index and goal arrivals, grown by doubling), the culled casts'
# two lists per heading and fine grid cell; the all-pairs table holds about 3-26 distinct
# flights per contact state (measured on lab and complex at K = 8 and 72)
_PER_BIN, _PER_STATE, _PER_FLIGHT, _LIST_BYTES = 400, 64, 600, 2 * 200
_FLIGHTS_PER_STATE = 30


@dataclass(eq=False)
class ExactSearch:
    """One uniform-cost search from a start configuration (the settled tree).

    Attributes
    ----------
    cost : (S + 1,) float   cost of every state (inf: not reached); index S is the start
    pred : (S + 1,) int     predecessor state (−1: none)
    pos : (S + 1, 2) float  exact pose [m] of each state's best arrival
    flight : (S + 1,) float clock length [m] of the flight leaving each settled state to its
                            bump (nan: not cast); its straight length without a contact rule
    used : (S + 1,) int     bit mask of the angles used on the way to each state
    goals : dict            goal configuration -> (cost, state, final_m), best arrivals
    arrivals : list         every goal arrival (cost, state, final_m, goal z) when recorded
    """

    cost: np.ndarray
    pred: np.ndarray
    pos: np.ndarray
    flight: np.ndarray
    used: np.ndarray
    goals: dict
    arrivals: list


def refuse_turn_in(contact) -> None:
    """The exact search (§13) follows the heading kept along a slide; a contact rule that
    turns the body into the wall (``ContactParams.turn_in``, §9) is refused in one sentence.
    """
    if contact is not None and contact.turn_in:
        raise UserError("the exact plan search does not follow a contact rule that turns the "
                        "body into the wall (turn_in) yet; decide by value under turn noise "
                        "(feedback), or use the rule for coverage.")


class ExactNavigator:
    """Plans over exact bump poses (docs/model.md §13), with the shape of
    :class:`planners.navigation.Navigator`.

    Parameters
    ----------
    cells : CellSpace
    angles : sequence of float   bouncing angles Φ [deg], multiples of 360°/K, no repeats
    w1, w2 : float               weights (defaults: the paper's 1 and 100)
    bin_length : float, optional contact-bin length [m] along the C-space boundary (h/4)
    min_depth : float            [m] the final stop must lie at least this deep inside the
                                 goal cell (default 1e-3)
    contact : ContactParams, optional
        The contact rule of the robot that executes the plans (docs/model.md §9): a flight
        whose contact lies outside the bumper arc slides on (:func:`envs.contact.contact_flights`)
        to its bump, and costs and expects its clock length. Default None: every contact
        bumps (the front-half bumper).
    """

    name = "exact"
    needs = frozenset({"contact"})
    closed_loop = False

    def __init__(self, cells: CellSpace, angles: Iterable[float], w1: float = 1.0,
                 w2: float = 100.0, bin_length: float | None = None,
                 min_depth: float = 1e-3, contact: ContactParams | None = None) -> None:
        self.cells = cells
        self.angles = check_angles(cells, angles, "the exact planner")
        self.w1, self.w2 = check_weights(w1, w2)
        self.steps = np.asarray([cells.angle_steps(a) for a in self.angles], dtype=np.int64)
        """Each angle in orientation steps (angle / Δ)."""
        self.bin_length = cells.h / 4 if bin_length is None else float(bin_length)
        self.min_depth = float(min_depth)
        self.caster = casters(cells.env)[0]
        self.contact = contact

    @property
    def m(self) -> int:
        """Number of bouncing angles."""
        return len(self.angles)

    @cached_property
    def boundary(self) -> Boundary:
        """The C-space boundary cut into contact bins (the event model's)."""
        return Boundary(self.cells.env, self.bin_length)

    @cached_property
    def _heading_caster(self) -> HeadingCaster:
        """Scalar casts along the K headings with the walls culled (bitwise the caster's)."""
        return HeadingCaster(self.caster, self.cells.units, self.cells.h / 2)

    @cached_property
    def scalar_boundary(self) -> tuple:
        """The boundary's segments, candidate lists and bin tables as plain Python lists
        (for :meth:`bin_of_point`); built on first use.
        """
        bd = self.boundary
        segs = [tuple(v) for v in np.column_stack(
            [bd.A, bd.B - bd.A, bd.seg_len ** 2, bd.seg_len, bd.seg_s0, bd.seg_ring]).tolist()]
        cand = [[int(c) for c in row if c >= 0] for row in bd.candidates.tolist()]
        return segs, cand, bd.ring_bin_length.tolist(), bd.ring_bins.tolist(), \
            bd.ring_first_bin.tolist()

    def bin_of_point(self, x: float, y: float) -> int:
        """:meth:`Boundary.bin_of` for one point in plain Python (the nearest candidate
        segment of the point's fine grid cell; far points go to the vectorised lookup).
        """
        bd = self.boundary
        segs, cand, blen, nbins, first = self.scalar_boundary
        i = min(max(int((x - bd.x0) / bd.g), 0), bd.nx - 1)
        j = min(max(int((y - bd.y0) / bd.g), 0), bd.ny - 1)
        best, arc, ring = math.inf, 0.0, -1
        for c in cand[j * bd.nx + i]:
            ax, ay, ex, ey, ee, length, s0, r = segs[c]
            t = min(max(((x - ax) * ex + (y - ay) * ey) / ee, 0.0), 1.0)
            d = math.hypot(x - ax - t * ex, y - ay - t * ey)
            if d < best:
                best, arc, ring = d, s0 + t * length, int(r)
        if ring < 0 or best > 2e-3:
            return int(bd.bin_of([[x, y]])[0])
        return first[ring] + min(int(arc / blen[ring]), nbins[ring] - 1)

    @property
    def n_states(self) -> int:
        """Contact states (bin × heading × angle), without the start."""
        return self.boundary.n_bins * self.cells.K * self.m

    def flights(self, pos, k):
        """Exact flight lengths [m] from poses ``pos`` at orientations ``k`` (the twin's
        drive: no motion when the bumper is already pressed, else the cast less CONTACT_GAP).
        """
        u = self.cells.units[k]
        t = self.caster.cast(pos, u)
        if not np.all(np.isfinite(t)):
            raise UserError("a flight never meets a wall: the environment is not closed.")
        return np.where(t <= BUMP_RANGE, 0.0, drive_distance(t)), u

    # ------------------------------------------------------------------ search
    def search(self, start: int, goal: int | None = None, slack: float = 0.0) -> ExactSearch:
        """Uniform-cost search from configuration ``start``.

        With ``goal``, stops once no cheaper arrival (within ``slack``) is possible and
        records every arrival at the goal within ``slack`` of the best; without it, settles
        every reachable state and records the best arrival at every goal configuration.
        """
        refuse_turn_in(self.contact)
        if goal is not None:
            return self._search_one(int(start), int(goal), float(slack))
        out = self.search_from(np.array([int(start)]))
        reached = np.flatnonzero(np.isfinite(out.gcost[0]))
        goals = {int(z): (float(out.gcost[0, z]), int(out.gstate[0, z]), float(out.gt[0, z]))
                 for z in reached}
        return ExactSearch(out.cost, out.pred, out.pos, out.flight, out.used, goals, [])

    def _search_one(self, start: int, goal: int, slack: float) -> ExactSearch:
        """A* from one start to one goal, one state at a time (heapq, scalar ray casts):
        a single query settles a few hundred states, too few to pay for vectorising.

        Same states, costs, bound and merging as :meth:`_search` (each state keeps its
        first-settled, i.e. cheapest, arrival).
        """
        cs, K, m, h = self.cells, self.cells.K, self.m, self.cells.h
        S = self.n_states
        w1, w2 = self.w1, self.w2
        first_bump = w1 if m == 1 else min(w1, w2)
        steps = self.steps.tolist()
        units = [tuple(float(v) for v in u) for u in cs.units]
        gp, gk = (int(v) for v in cs.pk(goal))
        glo = cs.origin + cs.cells_ij[gp] * h
        gx0, gy0, gx1, gy1 = float(glo[0]), float(glo[1]), float(glo[0] + h), \
            float(glo[1] + h)
        bin_of = self.bin_of_point
        cast = self._heading_caster.cast_one

        def bound(x: float, y: float) -> float:
            dx = max(gx0 - x, x - gx1, 0.0)
            dy = max(gy0 - y, y - gy1, 0.0)
            return w1 / h * math.hypot(dx, dy)

        cost = np.full(S + 1, np.inf)
        pred = np.full(S + 1, -1, dtype=np.int64)
        pos = np.full((S + 1, 2), np.nan)
        flight = np.full(S + 1, np.nan)
        used = np.zeros(S + 1, dtype=np.int64)
        p0, k0 = (int(v) for v in cs.pk(start))
        x0, y0 = (float(v) for v in cs.centres[p0])
        # heap entries: (key, order, state, cost, x, y, k, angle index, predecessor, mask)
        heap = [(0.0, 0, S, 0.0, x0, y0, k0, -1, -1, 0)]
        order = 1
        best = math.inf
        arrivals: list = []
        while heap:
            key, _, st, c, x, y, k, a, pr, mask = heapq.heappop(heap)
            if not math.isinf(cost[st]):
                continue                                  # settled already
            if key > best + slack:
                break
            cost[st], pred[st], pos[st], used[st] = c, pr, (x, y), mask
            ux, uy = units[k]
            t = cast(x, y, k, ux, uy)
            if math.isinf(t):
                raise UserError("a flight never meets a wall: the environment is not closed.")
            D = 0.0 if t <= BUMP_RANGE else drive_distance(t)
            flight[st] = D
            if k == gk and min(x, x + D * ux) <= gx1 and max(x, x + D * ux) >= gx0 and \
                    min(y, y + D * uy) <= gy1 and max(y, y + D * uy) >= gy0:
                _, p, tt, depth = chords(cs, [[x, y]], [[ux, uy]], [D])
                for pi, ti, di in zip(p.tolist(), tt.tolist(), depth.tolist()):
                    if pi == gp and di >= self.min_depth:
                        total = c + w1 * ti / h
                        arrivals.append((total, st, ti, goal))
                        if total < best - _IMPROVE:
                            best, best_arrival = total, (total, st, ti)
            lx, ly = x + D * ux, y + D * uy
            if self.contact is not None:                # a glancing contact slides on
                lx, ly, extra = slide_on(self.caster, self.contact, lx, ly, ux, uy)
                if extra > 0:
                    flight[st] = D + extra
            lb = bin_of(lx, ly)
            cf = c + w1 * float(flight[st]) / h
            hb = bound(lx, ly)
            for b in range(m):
                k2 = (k + steps[b]) % K
                tgt = (lb * K + k2) * m + b
                if not math.isinf(cost[tgt]):
                    continue
                c2 = cf + (first_bump if a < 0 else (w1 if a == b else w2))
                heapq.heappush(heap, (c2 + hb, order, tgt, c2, lx, ly, k2, b, st,
                                      mask | (1 << b)))
                order += 1
        goals = {goal: best_arrival} if math.isfinite(best) else {}
        return ExactSearch(cost, pred, pos, flight, used, goals, arrivals)

    def search_from(self, starts: np.ndarray, table: FlightTable | None = None,
                    tree: bool = True) -> SearchArrays:
        """The search from several starts at once (independent trees, one index space:
        source i owns states i·(S + 1) … i·(S + 1) + S, the last one its start). One cost
        band of all trees is settled per round (every state cheaper than the smallest
        unsettled cost plus the smallest edge weight is final); every distinct flight is
        cast once, in a table shared by the trees (``_batch.search_many``).
        """
        refuse_turn_in(self.contact)
        return search_many(self, starts, table, tree)

    # ------------------------------------------------------------------ routes
    def _route(self, tree: ExactSearch, start: int, goal: int, c: float, state: int,
               final: float) -> Route:
        S, m, cs = self.n_states, self.m, self.cells
        chain = [state]
        while chain[-1] != S:
            chain.append(int(tree.pred[chain[-1]]))
            if chain[-1] < 0:  # pragma: no cover - a tree without its root would be a bug
                raise RuntimeError("broken search tree")
        chain.reverse()                                   # start, state 1, ..., last state
        turns = [self.angles[s % m] for s in chain[1:]]
        flights = [float(tree.flight[s]) for s in chain[:-1]]
        head = cs.pose(start)[2]
        poses = [cs.pose(start)]
        for s, a in zip(chain[1:], turns):
            head = (head + a) % 360.0
            poses.append((float(tree.pos[s, 0]), float(tree.pos[s, 1]), head))
        u = cs.units[(s_k := int(cs.pk(goal)[1]))]
        x, y = tree.pos[state] + final * u
        poses.append((float(x), float(y), float(s_k * cs.delta_deg)))
        plan = Plan.exact(turns, flights, final, cs.h)
        return Route(start, goal, plan, c, tuple(poses), self.name)

    def plan(self, start: int, goal: int) -> Route | None:
        """The minimum-cost exact plan from configuration ``start`` to ``goal``, or None."""
        s, g = check_config(self.cells, start, "start"), check_config(self.cells, goal, "goal")
        if s == g:
            return Route(s, g, Plan((), (), 0.0, "exact"), 0.0, (self.cells.pose(s),),
                         self.name)
        tree = self.search(s, g)
        if g not in tree.goals:
            return None
        return self._route(tree, s, g, *tree.goals[g])

    def policy(self, start: int, goal: int) -> Plan | None:
        """The plan :func:`bouncesim.runs.execute.execute` runs (None: no plan)."""
        route = self.plan(start, goal)
        return None if route is None else route.plan

    def plans(self, start: int, goal: int, slack: float) -> list[Route]:
        """Every exact plan within ``slack`` of the cheapest, cheapest first: one per final
        state and goal arrival (the candidates a reliability layer ranks).
        """
        s, g = check_config(self.cells, start, "start"), check_config(self.cells, goal, "goal")
        if s == g:
            return [self.plan(s, g)]
        tree = self.search(s, g, slack=float(slack))
        if g not in tree.goals:
            return []
        best = tree.goals[g][0]
        rows = sorted(a for a in tree.arrivals if a[3] == g and a[0] <= best + slack)
        return [self._route(tree, s, g, c, st, t) for c, st, t, _ in rows]

    def all_pairs(self, max_memory=DEFAULT_MAX_MEMORY, progress=None) -> ExactAllPairs:
        """Every ordered pair: one full search per start, as many starts at a time as fit in
        about 0.4 GB (the analogue of Algorithm 2; every distinct flight is cast once for
        all starts). Refuses (:class:`envs.UserError`, before searching) when
        :meth:`memory_estimate` exceeds ``max_memory`` bytes (or a size such as ``"2G"``;
        None: no limit); ``progress(done, total)`` is called after every batch.
        """
        refuse_turn_in(self.contact)
        check(self.memory_estimate(self.cells, self.angles, task="allpairs"), max_memory,
              f"exact all pairs in {self.cells.env.name} with N = {self.cells.N} "
              "configurations")
        return ExactAllPairs(self, progress=progress)

    @classmethod
    def memory_estimate(cls, cells: CellSpace, angles, task: str = "plan",
                        bin_length: float | None = None) -> MemoryEstimate:
        """Peak memory of a single query (``task="plan"``) or of all pairs
        (``"allpairs"``), from the sizes alone (nothing is built): the contact bins
        (about the C-space perimeter / bin length), the search's arrays per contact state
        (S = bins · K · m), the culled casts' per-heading tables, and for all pairs the
        batch of starts (about 0.4 GB at most, twice for its temporaries), the flight table
        (about 0.6 kB per distinct flight, about 30 per contact state at most on the maps
        measured) and the N × N results.
        """
        bins = bins_estimate(cells.env, cells.h / 4 if bin_length is None else bin_length)
        m, K = max(1, len(tuple(angles))), cells.K
        S = bins * K * m
        x0, y0, x1, y1 = cells.env.bounds
        g = max(cells.h / 2, max(x1 - x0, y1 - y0) / 64)   # HeadingCaster's fine grid
        fine = math.ceil((x1 - x0) / g) * math.ceil((y1 - y0) / g)
        base = bins * _PER_BIN + K * fine * _LIST_BYTES
        if task == "plan":
            return MemoryEstimate("the exact planner's search", base + S * _PER_STATE)
        if task != "allpairs":
            raise ValueError(f"task must be 'plan' or 'allpairs', got {task!r}.")
        N = cells.N
        per_start = 14 * (S + 1) + 24 * N
        batch = min(N, max(1, int(_BATCH_BYTES // per_start)))
        table = min(_FLIGHTS_PER_STATE * S, N * S) * _PER_FLIGHT
        return MemoryEstimate("the exact planner's all pairs",
                              base + batch * per_start * 2 + table + N * N * 9)


class ExactAllPairs(PairTable):
    """All-pairs exact plans: weights and angles used (one full search per start).

    Attributes
    ----------
    weights : (N, N) float   minimum cost, −1 where unreachable, 0 on the diagonal
    angles_used : (N, N) int8  distinct angles of the plan, −1 where unreachable or i == j
    """

    def __init__(self, nav: ExactNavigator, batch: int | None = None, progress=None) -> None:
        self.nav = nav
        N = nav.cells.N
        if batch is None:                        # starts per batch: about 0.4 GB, even split
            per_start = 14 * (nav.n_states + 1) + 24 * N
            parts = -(-N // max(1, int(_BATCH_BYTES // per_start)))
            batch = -(-N // parts)
        W = np.full((N, N), -1.0)
        used = np.full((N, N), -1, dtype=np.int8)
        bits = np.array([bin(i).count("1") for i in range(1 << nav.m)], dtype=np.int8)
        table = FlightTable(nav)                 # every distinct flight cast once, for all
        for lo in range(0, N, batch):
            starts = np.arange(lo, min(N, lo + batch))
            out = nav.search_from(starts, table, tree=False)
            ok = np.isfinite(out.gcost)
            W[lo:lo + len(starts)][ok] = out.gcost[ok]
            used[lo:lo + len(starts)][ok] = bits[out.used[out.gstate[ok]]]
            if progress is not None:
                progress(lo + len(starts), N)
        idx = np.arange(N)
        W[idx, idx] = 0.0
        used[idx, idx] = -1
        self.weights, self.angles_used, self.m = W, used, nav.m

    def route(self, i: int, j: int) -> Route | None:
        """The plan for the pair (i, j) (searched again: the same tree, the same plan)."""
        return self.nav.plan(i, j)
