"""Navigation (docs/model.md §12): hand-checked plans, replay, networkx cross-check, all pairs,
CLI.
"""

from __future__ import annotations

import itertools
import json

import networkx as nx
import numpy as np
import pytest

import envs
from bouncesim.cli import main
from envs import UserError
from planners.cells import CellSpace
from planners.navigation import Navigator
from planners.plan import Plan, PlanParseError

from .conftest import random_room, room


def replay(cs: CellSpace, start: int, plan: Plan, angles, w1=1.0, w2=100.0):
    """Run a plan through the step model; return (final z, cost), or None if it is
    inconsistent (a 0 where the robot bumps or an angle where it moves).
    """
    z, cost, cur = start, 0.0, None
    for lab in plan.labels:
        if lab == 0:
            if cs.forward[z] < 0:
                return None
            z, cost = int(cs.forward[z]), cost + w1
        else:
            if cs.forward[z] >= 0:
                return None
            z = int(cs.rotate(z, lab))
            cost += w1 if cur in (None, lab) else w2
            cur = lab
    return z, cost


def nx_costs(cs: CellSpace, angles, w1=1.0, w2=100.0) -> np.ndarray:
    """docs/model.md §12 built independently as a networkx graph over (z, a) nodes."""
    G = nx.DiGraph()
    m = len(angles)
    steps = [int(round(a / (360 / cs.K))) for a in angles]
    for z in range(cs.N):
        p, k = z % cs.P, z // cs.P
        for a in range(m):
            f = cs.forward[z]
            if f >= 0:
                G.add_edge((z, a), (int(f), a), weight=w1)
            else:
                for b in range(m):
                    G.add_edge((z, a), (((k + steps[b]) % cs.K) * cs.P + p, b),
                               weight=w1 if a == b else w2)
    L = np.full((cs.N, cs.N), -1.0)
    for s in range(cs.N):
        srcs = [(s, a) for a in range(m) if (s, a) in G]
        d = nx.multi_source_dijkstra_path_length(G, srcs) if srcs else {}
        for (z, _b), v in d.items():
            if L[s, z] < 0 or v < L[s, z]:
                L[s, z] = v
        L[s, s] = 0.0
    return L


def test_corridor_plans_by_hand(corridor):
    cs = CellSpace(corridor)            # 3 cells in a row, K = 4
    nav = Navigator(cs, [90, 180])
    # from p0 facing east to p2 facing east: two steps
    r = nav.plan(0, 2)
    assert r.plan.labels == (0, 0) and r.cost == 2 and r.path == (0, 1, 2)
    # from p2 facing east to p0 facing east: bump-180 (west), 2 steps, bump-180 (east)
    r = nav.plan(2, 0)
    assert str(r.plan) == "180° 00 180°" and r.cost == 4
    # p1 facing north (z=4) to p1 facing west (z=7): one bump with 90°
    assert nav.plan(4, 7).plan.labels == (90,)


def test_angle_change_costs_w2(corridor):
    cs = CellSpace(corridor)
    # only by mixing 90° and 180°: p0 facing east -> p0 facing north needs
    # east..bump(180 -> west)..bump(90 -> south)? No: check the optimum against replay.
    nav = Navigator(cs, [90, 180], w1=1, w2=10)
    for s, g in itertools.permutations(range(cs.N), 2):
        r = nav.plan(s, g)
        if r is not None:
            assert replay(cs, s, r.plan, nav.angles, 1, 10) == (g, r.cost)


def test_fig3_plans_in_lab():
    cs = CellSpace(envs.load("lab"))
    nav = Navigator(cs, [90, 135])
    r1 = nav.plan(8, 0)
    assert str(r1.plan) == "90° 90° 00000000 90° 90°" and r1.cost == 12
    r2 = nav.plan(103, 8)
    assert replay(cs, 103, r2.plan, nav.angles) == (8, r2.cost)


@pytest.mark.parametrize("seed", range(6))
def test_costs_match_networkx(seed):
    rng = np.random.default_rng(100 + seed)
    K = int(rng.choice([4, 8]))
    cs = CellSpace(random_room(rng, K=K))
    delta = 360 // K
    m = int(rng.integers(1, 4))
    angles = sorted(rng.choice(np.arange(1, K), size=m, replace=False) * delta)
    w2 = float(rng.choice([1.0, 3.0, 100.0]))
    nav = Navigator(cs, angles, 1.0, w2)
    ap = nav.all_pairs()
    ref = nx_costs(cs, angles, 1.0, w2)
    np.testing.assert_allclose(ap.weights, ref)
    # every stored plan replays to its goal at exactly its cost
    for s, g in itertools.product(range(cs.N), repeat=2):
        r = ap.route(s, g)
        assert (r is None) == (ref[s, g] < 0)
        if r is not None:
            assert replay(cs, s, r.plan, angles, 1.0, w2) == (g, r.cost)
            if s != g:
                assert ap.angles_used[s, g] == r.angles_used
                assert ap.n_labels[s, g] == len(r.plan)


def test_single_queries_agree_with_all_pairs():
    cs = CellSpace(envs.load("fig1"))
    nav = Navigator(cs, [45, 90, 135])
    ap = nav.all_pairs()
    rng = np.random.default_rng(3)
    for s, g in rng.integers(0, cs.N, size=(100, 2)):
        r = nav.plan(s, g)
        assert (-1 if r is None else r.cost) == ap.weights[s, g]
    h = ap.histogram()
    assert h.sum() == (ap.weights[~np.eye(cs.N, dtype=bool)] >= 0).sum()


def test_unreachable_is_none():
    cs = CellSpace(room(3, 1, K=4))
    nav = Navigator(cs, [180])   # can never face north or south from an east/west start
    assert nav.plan(0, 3) is None
    assert nav.all_pairs().weights[0, 3] == -1


def test_determinism():
    cs = CellSpace(envs.load("fig1"))
    a = Navigator(cs, [45, 90, 135]).all_pairs()
    b = Navigator(CellSpace(envs.load("fig1")), [45, 90, 135]).all_pairs()
    np.testing.assert_array_equal(a.weights, b.weights)
    np.testing.assert_array_equal(a.angles_used, b.angles_used)


def test_bad_roadmap_inputs(corridor):
    cs = CellSpace(corridor)
    with pytest.raises(UserError, match="multiple of 90°"):
        Navigator(cs, [45])
    with pytest.raises(UserError, match="repeat"):
        Navigator(cs, [90, 90])
    with pytest.raises(UserError, match="w2 must be a positive"):
        Navigator(cs, [90], w2=0)
    with pytest.raises(UserError, match="out of range"):
        Navigator(cs, [90]).plan(0, 99)


@pytest.mark.parametrize("text,labels", [
    ("000000 135° 135° 00000 90°", (0,) * 6 + (135, 135) + (0,) * 5 + (90,)),
    ("0 0 0 135 135 0 90", (0, 0, 0, 135, 135, 0, 90)),
    ("90°,0,0", (90, 0, 0)),
    ("", ()),
])
def test_plan_parse(text, labels):
    p = Plan.parse(text)
    assert p.labels == labels
    assert Plan.parse(str(p)) == p and Plan.parse(p.plain()) == p


def test_plan_parse_errors():
    for bad in ("0 x 90", "400", "12a"):
        with pytest.raises(PlanParseError):
            Plan.parse(bad)


# ---------------------------------------------------------------------------- CLI
def test_cli_info_json(capsys):
    assert main(["info", "lab", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert {"P", "N", "K", "cell_size", "bounds", "robot_radius"} <= set(info)
    assert (info["P"], info["N"], info["K"]) == (48, 384, 8)


def test_cli_plan_on_hand_written_file(tmp_path, capsys):
    f = tmp_path / "mine.json"
    f.write_text(json.dumps({"name": "mine", "boundary": [[0, 0], [1.02, 0], [1.02, 0.34],
                                                         [0, 0.34]],
                             "robot_radius": 0.17,
                             "discretization": {"cell_size": 0.34, "orientations": 4}}))
    assert main(["plan", str(f), "--angles", "90,180", "--start", "2", "--goal", "0",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["plan"] == [180, 0, 0, 180] and out["plan_text"] == "180° 00 180°"
    assert out["cost"] == 4 and out["path"] == [2, 8, 7, 6, 0] and out["angles_used"] == 1
    # a pose mapped to its cell; no path -> exit 3 and a null plan
    assert main(["plan", str(f), "--angles", "180", "--start", "0.2,0.2,0", "--goal", "3",
                 "--json"]) == 3
    out = json.loads(capsys.readouterr().out)
    assert out["plan"] is None and out["cost"] is None


def test_cli_pairs_file(tmp_path, capsys):
    pairs = tmp_path / "q.csv"
    pairs.write_text("start,goal\n8,0\n103,8\n\"0.17,0.17,0\",8\n")
    assert main(["plan", "lab", "--angles", "90,135", "--pairs", str(pairs), "--json"]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [x["start"] for x in lines] == [8, 103, 0]


@pytest.mark.parametrize("argv,needle", [
    (["plan", "lab", "--angles", "100", "--start", "0", "--goal", "1"], "multiple of 45"),
    (["plan", "lab", "--angles", "90", "--start", "9.9,9.9,0", "--goal", "1"], "not in a free"),
    (["plan", "lab", "--angles", "90", "--start", "0"], "give --start and --goal"),
    (["plan", "nowhere", "--angles", "90", "--start", "0", "--goal", "1"], "neither"),
    (["info", "lab", "--orientations", "2"], "at least 4"),
])
def test_cli_errors(argv, needle, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_cli_allpairs(tmp_path, capsys):
    assert main(["allpairs", "lab", "--angles", "90,135", "--out", str(tmp_path)]) == 0
    W = np.load(tmp_path / "weights.npy")
    assert W.shape == (384, 384)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert sum(summary["histogram"]) == int((W[~np.eye(384, dtype=bool)] >= 0).sum())
    assert (tmp_path / "angles_used.png").stat().st_size > 1000
