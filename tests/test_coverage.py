"""Coverage chains of bouncing robots and the policy mix (planners.coverage: the noise, the
step model, targets and the mix).
"""

from __future__ import annotations

import itertools
import subprocess
import sys

import numpy as np
import pytest

import envs
from envs import Environment, UserError
from planners.cells import AngleError, CellSpace
from planners.coverage import (
    StepModel,
    StepSettings,
    TargetError,
    TurnNoise,
    design_mix,
    load_target,
    model_for,
    solve_mix,
    transition_matrix,
    uniform_target,
)
from planners.coverage import mix as cov_mix


def corridor(K=4):
    """A 1 x 3 corridor (cells p = 0, 1, 2 from west to east)."""
    return CellSpace(Environment.from_dict(
        {"boundary": [[0, 0], [1.02, 0], [1.02, 0.34], [0, 0.34]], "robot_radius": 0.17,
         "discretization": {"cell_size": 0.34, "orientations": K}}))


@pytest.fixture(scope="module")
def lab():
    return CellSpace(envs.load("lab"))


@pytest.fixture(scope="module")
def complex72():
    cs = CellSpace(envs.load("complex", orientations=72))
    _ = cs.forward
    return cs


# ---------------------------------------------------------------------------- bump model
def test_bump_turns_probabilities():
    steps, probs = TurnNoise(5, 0.8).turns(360, 30)
    assert steps.tolist() == list(range(25, 36))
    assert probs[5] == 0.8
    np.testing.assert_allclose(np.delete(probs, 5), 0.2 / 10)
    assert probs.sum() == pytest.approx(1.0)


def test_bump_turns_wraps_and_allows_self_loops():
    # 270° with ε = 90° at K = 4: φ + δ = 180°, 270°, 360° ≡ 0° (keeps its heading).
    steps, probs = TurnNoise(90, 0.5).turns(4, 270)
    assert steps.tolist() == [2, 3, 0]
    np.testing.assert_allclose(probs, [0.25, 0.5, 0.25])


@pytest.mark.parametrize("angle, eps, r, match", [
    (30, 0, 1, "bouncing angle 30° is not allowed with 8 orientations"),
    (0, 0, 1, "bouncing angle 0°"),
    (90, 5, 1, "error range eps 5° is not allowed"),
    (90, -45, 1, "error range eps -45°"),
    (90, 45, 1.2, "reliability r must lie in"),
    (90, 45, -0.1, "reliability r must lie in"),
])
def test_bad_parameters_are_user_errors(angle, eps, r, match):
    with pytest.raises(UserError, match=match):
        TurnNoise(eps, r).turns(8, angle)


def test_angle_error_is_the_cells_error():
    with pytest.raises(AngleError):
        TurnNoise().turns(8, 100)


# ---------------------------------------------------------------------------- matrices
def _expected_nnz_per_row(cs, angle, eps, r):
    steps, probs = TurnNoise(eps, r).turns(cs.K, angle)
    n_bump = len(set(steps[probs > 0].tolist()))
    return np.where(cs.forward < 0, n_bump, 1)


@pytest.mark.parametrize("angle, eps, r", [(30, 5, 0.8), (75, 5, 0.8), (315, 5, 0.8),
                                           (90, 0, 1.0), (30, 5, 1.0), (30, 10, 0.0)])
def test_rows_sum_to_one_on_complex(complex72, angle, eps, r):
    M = transition_matrix(complex72, angle, TurnNoise(eps, r))
    assert M.shape == (complex72.N, complex72.N)
    np.testing.assert_allclose(np.asarray(M.sum(axis=1)).ravel(), 1.0, atol=1e-12)
    assert (M.data > 0).all()
    np.testing.assert_array_equal(np.diff(M.indptr),
                                  _expected_nnz_per_row(complex72, angle, eps, r))
    fwd = complex72.forward
    z = np.flatnonzero(fwd >= 0)
    assert (M[z, fwd[z]] == 1).all()


def test_bump_rows_by_hand(lab):
    cs = lab
    zb = int(np.flatnonzero(cs.forward < 0)[0])
    p, k = zb % cs.P, zb // cs.P
    row = transition_matrix(cs, 135, TurnNoise(45, 0.6))[zb].toarray().ravel()
    expected = np.zeros(cs.N)
    for d, pr in [(-1, 0.2), (0, 0.6), (1, 0.2)]:
        expected[((k + 3 + d) % 8) * cs.P + p] += pr
    np.testing.assert_allclose(row, expected)


def test_overlapping_turns_add_up():
    # ε = 270° at K = 4: seven turns land on four headings; probabilities add up.
    cs = corridor()
    M = transition_matrix(cs, 90, TurnNoise(270, 0.4))
    np.testing.assert_allclose(np.asarray(M.sum(axis=1)).ravel(), 1.0)
    zb = int(np.flatnonzero(cs.forward < 0)[0])
    assert M[zb].nnz == 4


# ---------------------------------------------------------------------------- by hand
def test_corridor_90_degrees_by_hand():
    # K = 4, φ = 90°, no noise. The cycle (2,E) (2,N) (2,W) (1,W) (0,W) (0,S) (0,E) (1,E)
    # holds 8 configurations; (0,N), (1,N), (1,S) and (2,S) are transient (each bumps or
    # runs into the cycle). π is uniform 1/8 on the cycle, so q = (3/8, 2/8, 3/8).
    cs = corridor()
    res = StepModel(cs).analyse(90)
    assert res.group_sizes.tolist() == [8]
    assert res.transient_fraction == pytest.approx(4 / 12)
    np.testing.assert_allclose(res.q, [3 / 8, 2 / 8, 3 / 8], atol=1e-14)
    transient = np.setdiff1d(np.arange(12), res.groups[0])
    N_, E_, S_ = 1, 0, 3
    assert sorted(transient.tolist()) == sorted([cs.z(0, N_), cs.z(1, N_), cs.z(1, S_),
                                                 cs.z(2, S_)])
    assert cs.z(2, E_) in res.groups[0]


def test_corridor_180_degrees_by_hand():
    # East/west: one periodic group of 6 (a_g = 6/12); north/south: a 2-cycle per cell
    # (a_g = 2/12 each). q = 1/2 * 1/3 + 1/6 = 1/3 in every cell.
    res = StepModel(corridor()).analyse(180)
    assert sorted(res.group_sizes.tolist()) == [2, 2, 2, 6]
    np.testing.assert_allclose(sorted(res.analysis.absorption), [1 / 6] * 3 + [1 / 2])
    np.testing.assert_allclose(res.q, 1 / 3, atol=1e-14)


def test_self_loop_bump_by_hand():
    # φ = 270° with ε = 90°, r = 0 at K = 4: a bump turns by 180° or by 360° ≡ 0° (keeps
    # its heading: a self-loop), each with probability 1/2. East/west is one closed class of
    # 6 states, north/south a class of 2 per cell. Balance equations in the east/west class
    # with x = π(1,E): π(0,E) = x, π(2,E) = x + π(2,E)/2 = 2x, π(2,W) = π(1,W) = π(2,E)/2 = x,
    # π(0,W) = x + π(0,W)/2 = 2x; the total 8x = 1 gives x = 1/8. Uniform start: the
    # east/west class gets a = 6/12, each north/south pair 2/12, so
    # q = (1/2)(3/8, 1/4, 3/8) + 1/6 = (17/48, 14/48, 17/48).
    cs = corridor()
    res = StepModel(cs).analyse(270, TurnNoise(90, 0.0))
    assert sorted(res.group_sizes.tolist()) == [2, 2, 2, 6]
    st = res.analysis.stationary
    E, W = 0, 2
    np.testing.assert_allclose([st[cs.z(p, E)] for p in range(3)], [1 / 8, 1 / 8, 1 / 4])
    np.testing.assert_allclose([st[cs.z(p, W)] for p in range(3)], [1 / 4, 1 / 8, 1 / 8])
    np.testing.assert_allclose(res.q, np.array([17, 14, 17]) / 48, atol=1e-14)


# ---------------------------------------------------------------------------- consistency
@pytest.mark.parametrize("env_name, K, angle, eps, r", [
    ("lab", 8, 45, 0, 1.0), ("lab", 8, 135, 45, 0.7), ("fig1", 8, 90, 45, 0.0),
    ("fig1", 24, 75, 15, 0.8), ("complex", 8, 315, 45, 0.9)])
def test_runs_method_matches_full_matrix(env_name, K, angle, eps, r):
    cs = CellSpace(envs.load(env_name, orientations=K))
    a = StepModel(cs, StepSettings(method="runs")).analyse(angle, TurnNoise(eps, r))
    b = StepModel(cs, StepSettings(method="matrix")).analyse(angle, TurnNoise(eps, r))
    assert [g.tolist() for g in a.groups] == [g.tolist() for g in b.groups]
    np.testing.assert_allclose(a.pi, b.pi, atol=1e-12)
    np.testing.assert_allclose(a.q, b.q, atol=1e-12)
    assert a.q.sum() == pytest.approx(1.0)
    assert (a.q >= 0).all()


def test_limiting_distribution_is_stationary(complex72):
    res = StepModel(complex72).analyse(75, TurnNoise(5, 0.8))
    M = transition_matrix(complex72, 75, TurnNoise(5, 0.8))
    np.testing.assert_allclose(M.T @ res.pi, res.pi, atol=1e-12)
    for g in res.groups:                       # closed: no mass leaves a group
        assert np.setdiff1d(M[g].indices, g).size == 0


def test_unknown_method_is_rejected():
    with pytest.raises(ValueError, match="method"):
        StepModel(corridor(), StepSettings(method="dense")).analyse(90)


# ---------------------------------------------------------------------------- the mix
def _grid_search(A, b, step):
    m = A.shape[1]
    ticks = np.round(np.arange(0, 1 + step / 2, step), 12)
    best, best_v = None, np.inf
    for head in itertools.product(ticks, repeat=m - 1):
        last = 1 - sum(head)
        if last < -1e-12:
            continue
        al = np.array(list(head) + [max(last, 0.0)])
        v = np.linalg.norm(A @ al - b)
        if v < best_v:
            best, best_v = al, v
    return best, best_v


@pytest.mark.parametrize("m, step", [(2, 1e-3), (3, 5e-3)])
def test_mix_matches_brute_force_grid_search(m, step):
    rng = np.random.default_rng(100 + m)
    for _ in range(15):
        A = rng.random((12, m))
        A /= A.sum(axis=0)
        b = rng.random(12)
        b /= b.sum()
        res = solve_mix(A, b)
        g_alpha, g_val = _grid_search(A, b, step)
        assert res.alpha.min() >= 0 and res.alpha.sum() == pytest.approx(1.0)
        # exact optimum is never worse than the grid, and the grid is within its spacing
        assert res.residual <= g_val + 1e-12
        assert np.abs(res.alpha - g_alpha).max() <= 0.05
        assert res.residual == pytest.approx(np.linalg.norm(A @ res.alpha - b))
        assert res.tv == pytest.approx(0.5 * np.abs(A @ res.alpha - b).sum())


def test_mix_reaches_a_target_in_the_hull():
    A = np.array([[0.5, 0.0, 0.2], [0.5, 0.2, 0.3], [0.0, 0.8, 0.5]])
    alpha = np.array([0.3, 0.7, 0.0])
    res = solve_mix(A, A @ alpha)
    np.testing.assert_allclose(res.alpha, alpha, atol=1e-12)
    assert res.residual < 1e-14 and res.tv < 1e-14


def test_mix_with_identical_columns_keeps_smaller_support():
    A = np.array([[1.0, 1.0], [0.0, 0.0]])
    res = solve_mix(A, [0.5, 0.5])
    assert res.alpha.tolist() == [1.0, 0.0]


def test_slsqp_path_agrees_with_enumeration(monkeypatch):
    rng = np.random.default_rng(5)
    A = rng.random((30, 13))
    b = rng.random(30)
    res = solve_mix(A, b)                       # m = 13 > 12: SLSQP + KKT polish
    assert res.method == "slsqp"
    monkeypatch.setattr(cov_mix, "_ENUM_MAX", 13)   # 8191 supports: the exact answer
    exact = solve_mix(A, b)
    assert exact.method == "enumeration"
    assert res.residual <= exact.residual + 1e-9
    np.testing.assert_allclose(res.alpha, exact.alpha, atol=1e-5)


# ---------------------------------------------------------------------------- targets
def test_uniform_targets(lab):
    np.testing.assert_allclose(uniform_target(lab), 1 / lab.P)
    assert uniform_target(lab, "configurations").shape == (lab.N,)


def test_long_csv_target(tmp_path, lab):
    f = tmp_path / "t.csv"
    f.write_text("p,weight\n0,3\n5,1\n")
    b = load_target(f, lab)
    assert b[0] == 0.75 and b[5] == 0.25 and b.sum() == pytest.approx(1.0)


def test_grid_target_is_read_top_row_first(tmp_path, lab):
    rows, cols = lab.env.grid_shape
    grid = np.zeros((rows, cols))
    grid[0, 0] = 2.0          # printed first = the top row of the map
    grid[-1, -1] = 1.0        # last line = bottom row
    jn, in_ = np.argwhere(lab.index_grid < 0)[0]          # a cell that is not free
    grid[rows - 1 - jn, in_] = np.nan                       # ignored: not a free cell
    f = tmp_path / "grid.txt"
    f.write_text("\n".join(" ".join("nan" if np.isnan(v) else f"{v:g}" for v in r)
                           for r in grid))
    free = lab.index_grid
    b = load_target(f, lab)
    top, bottom = free[rows - 1, 0], free[0, cols - 1]
    assert top >= 0 and bottom >= 0
    assert b[top] == pytest.approx(2 / 3) and b[bottom] == pytest.approx(1 / 3)


def test_configuration_target(tmp_path, lab):
    f = tmp_path / "z.csv"
    f.write_text("z,weight\n10,1\n300,1\n")
    b = load_target(f, lab, "configurations")
    assert b.shape == (lab.N,) and b[10] == b[300] == 0.5


@pytest.mark.parametrize("text, space, match", [
    ("p,weight\n0,-1\n1,2\n", "positions", "negative weight"),
    ("p,weight\n0,0\n", "positions", "sum to zero"),
    ("p,weight\n999,1\n", "positions", "outside 0..47"),
    ("p,weight\n1,1\n1,2\n", "positions", "listed twice"),
    ("p,weight\n1,abc\n", "positions", "does not hold a number"),
    ("q,w\n1,1\n", "positions", "needs columns p and weight"),
    ("p;weight\n1;1\n", "positions", "needs columns p and weight"),
    ("1 2 3\n4 5 6\n", "positions", "must have 6 rows x 9 columns"),
    ("1 2 x\n", "positions", "not a number"),
    ("p,weight\n1,1\n", "configurations", "needs columns z and weight"),
    ("1 2\n", "configurations", "no header row"),
    ("# only a comment\n", "positions", "is empty"),
])
def test_bad_targets(tmp_path, lab, text, space, match):
    f = tmp_path / "bad.csv"
    f.write_text(text)
    with pytest.raises(TargetError, match=match):
        load_target(f, lab, space)


def test_missing_and_binary_target_files(tmp_path, lab):
    with pytest.raises(TargetError, match="no target file"):
        load_target(tmp_path / "nope.csv", lab)
    f = tmp_path / "bin.csv"
    f.write_bytes(b"\xff\xfe\x00\x81")
    with pytest.raises(TargetError, match="cannot read"):
        load_target(f, lab)


# ---------------------------------------------------------------------------- pipeline
def test_pipeline_on_complex(complex72):
    res = design_mix(model_for(complex72), (30, 75, 315), TurnNoise(5, 0.8))
    assert res.A.shape == (complex72.P, 3)
    np.testing.assert_allclose(res.A.sum(axis=0), 1.0)
    assert res.mixed_q().sum() == pytest.approx(1.0)
    assert res.alpha.sum() == pytest.approx(1.0)
    conf = design_mix(model_for(complex72), (30, 75, 315), TurnNoise(5, 0.8),
                      space="configurations")
    assert conf.A.shape == (complex72.N, 3)
    assert conf.target.sum() == pytest.approx(1.0)


def test_pipeline_rejects_wrong_target_length(lab):
    with pytest.raises(TargetError, match="entries"):
        design_mix(model_for(lab), (90,), target=np.ones(3))
    with pytest.raises(UserError, match="target space"):
        design_mix(model_for(lab), (90,), space="cells")


def test_planners_do_not_import_matplotlib():
    code = ("import sys, planners.coverage, planners.coverage.markov; "
            "sys.exit(1 if 'matplotlib' in sys.modules else 0)")
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0
