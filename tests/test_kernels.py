"""Compiled kernels (numba) against their numpy references on random points in rooms with
slanted walls and pillars: the feedback filter's flights and side probabilities
(planners/navigation/feedback/_kernels.py: the same drives to the bit, the same touched
features, bearings and side probabilities to 1e-12) and the contact bins' nearest ring point
(planners/boundary.py: the same to the bit).
"""

from __future__ import annotations

import numpy as np
import pytest

from envs import generated
from planners.cells import CellSpace
from planners.navigation.exact import ExactNavigator
from planners.navigation.feedback import FeedbackConfig
from planners.navigation.feedback.observe import (
    flights,
    flights_reference,
    side_probs,
    side_probs_reference,
)


def _room(seed: int, n: int):
    """(rng, caster, poses (n, 3)): a generated room with slanted walls and pillars, its
    full caster and n random free poses.
    """
    rng = np.random.default_rng(seed)
    env = generated.slanted_room(rng, orientations=8)
    caster = ExactNavigator(CellSpace(env), [45, 90, 135]).caster
    return rng, caster, np.array([env.random_pose(rng) for _ in range(n)])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_flights_and_side_probabilities_match_the_numpy_reference(seed):
    rng, caster, poses = _room(seed, 400)
    # poses at contact too: every pose flown to its bump, then turned (features touched at
    # once, corners, the knife edges of the bearings' ±90° cut)
    D, u, _ = flights_reference(caster, poses[:, :2], poses[:, 2])
    bumped = poses[:, :2] + D[:, None] * u
    heads = poses[:, 2] + rng.choice([0.0, 45.0, 90.0, 135.0, 180.0], len(poses))
    pos = np.vstack([poses[:, :2], bumped])
    head = np.concatenate([poses[:, 2], heads])
    for bearings in (False, True):
        D1, u1, b1 = flights(caster, pos, head, bearings)
        D0, u0, b0 = flights_reference(caster, pos, head, bearings)
        np.testing.assert_array_equal(D1, D0)
        np.testing.assert_array_equal(u1, u0)
        if bearings:
            np.testing.assert_array_equal(np.isnan(b1), np.isnan(b0))
            np.testing.assert_allclose(b1, b0, atol=1e-12)
            assert np.isfinite(b1).any(axis=1)[len(poses):].mean() > 0.95   # at contact
            for cfg in (FeedbackConfig(), FeedbackConfig(side_union=0.0, p_side=0.2,
                                                         side_blur_deg=3.0)):
                np.testing.assert_allclose(side_probs(b1, cfg), side_probs_reference(b0, cfg),
                                           atol=1e-12)
        else:
            assert b1 is None and b0 is None


@pytest.mark.parametrize("seed", [0, 1])
def test_boundary_locate_matches_the_numpy_reference(seed):
    # contact points on the ring (nudged), points a little off it, and points far from it
    # (the full search): the same segment and arc length, to the bit
    from planners.boundary import Boundary
    rng = np.random.default_rng(seed)
    env = generated.slanted_room(rng, orientations=8)
    bd = Boundary(env, 0.085)
    on = bd.points(rng.integers(0, bd.n_bins, 500), rng.random(500))
    near = on + rng.normal(0, 0.003, on.shape)
    lo, hi = np.asarray(env.bounds[:2]), np.asarray(env.bounds[2:])
    far = lo + rng.random((300, 2)) * (hi - lo)
    for pts in (on, near, far):
        ring, s = bd.locate(pts)
        ring0, s0 = bd.locate_reference(pts)
        np.testing.assert_array_equal(ring, ring0)
        np.testing.assert_array_equal(s, s0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_slides_match_advance(seed):
    # flights into walls of rooms with slanted walls and pillars under PyBullet's rule and a
    # wide arc with friction: glancing contacts slide along sides and wrap around corners;
    # the compiled slides end where advance (plain Python, the reference) ends them
    from envs.contact import advance, advance_many, contact_flights
    from envs.motion import MUJOCO_CONTACT, PYBULLET_CONTACT, ContactParams
    rng, caster, poses = _room(seed, 300)
    # most flights head for the nearest wall at a glancing incidence (0.5°-12°, either way
    # along it): they slide along sides and wrap around its ends' corners
    p = poses[:, :2]
    lam = np.clip(((p[:, None] - caster.A[None]) * caster.e[None]).sum(2), 0, caster.L[None])
    foot = caster.A[None] + lam[..., None] * caster.e[None]
    j = np.argmin(np.hypot(*(p[:, None] - foot).transpose(2, 0, 1)), axis=1)
    nrm = p - foot[np.arange(len(p)), j]
    nrm /= np.hypot(nrm[:, 0], nrm[:, 1])[:, None]
    alpha = np.radians(rng.uniform(0.5, 12.0, len(p)))[:, None]
    u = np.cos(alpha) * caster.e[j] * rng.choice([-1.0, 1.0], (len(p), 1)) - np.sin(alpha) * nrm
    poses[:240, 2] = np.degrees(np.arctan2(u[:, 1], u[:, 0]))[:240]
    D, u, _ = flights_reference(caster, poses[:, :2], poses[:, 2])
    for contact in (PYBULLET_CONTACT, ContactParams(40.0, 0.2), MUJOCO_CONTACT):
        fl = contact_flights(caster, poses[:, :2], u, D, contact)
        fk = contact_flights(caster, poses[:, :2], u, D, contact, legs=False)
        assert fl.slid.sum() >= 20                  # the case is exercised
        np.testing.assert_array_equal(fk.slid, fl.slid)
        np.testing.assert_allclose(fk.end, fl.end, rtol=0, atol=1e-9)
        np.testing.assert_allclose(fk.clock, fl.clock, rtol=0, atol=1e-9)
        np.testing.assert_allclose(fk.u_end, fl.u_end, rtol=0, atol=1e-9)
        assert fk.legs == {}
        with pytest.raises(ValueError, match="without their legs"):
            fk.points(np.flatnonzero(fk.slid)[:1], np.zeros(1))
        # each flight one at a time, from its first contact, both ways
        end = poses[:, :2] + D[:, None] * u
        x, y, used, bumped, vx, vy = advance_many(caster, end, u, contact)
        for i in range(len(end)):
            rx, ry, rused, rb, _, rv = advance(caster, float(end[i, 0]), float(end[i, 1]),
                                               float(u[i, 0]), float(u[i, 1]), contact)
            assert bumped[i] == rb
            assert abs(x[i] - rx) <= 1e-9 and abs(y[i] - ry) <= 1e-9
            assert abs(used[i] - rused) <= 1e-9
            assert abs(vx[i] - rv[0]) <= 1e-9 and abs(vy[i] - rv[1]) <= 1e-9
        if contact.turn_in:                         # the turn-in case is exercised
            assert (np.hypot(vx - u[:, 0], vy - u[:, 1]) > 1e-3).sum() >= 20


def _turn_matrix_reference(n, K, steps, probs):
    """Pre-turn (b, k) → (b, (k + step) mod K): one COO entry per state and turn, duplicates
    summed by scipy.
    """
    import scipy.sparse as sp
    i = np.arange(n)
    cols = ((i // K)[:, None] * K + ((i % K)[:, None] + steps[None, :]) % K).ravel()
    M = sp.csr_matrix((np.tile(probs, n), (np.repeat(i, len(steps)), cols)), shape=(n, n))
    M.sum_duplicates()
    return M


@pytest.mark.parametrize("K,noise", [(8, None), (72, "model:eps=5,r=0.8"),
                                      (72, "gauss:60"), (8, "gauss:200"),
                                      (360, "model:eps=5,r=0.8+body")])
def test_event_turn_matrix_equals_the_plain_construction(K, noise):
    # the event model builds its turn matrix in CSR form directly; against one COO entry per
    # (state, turn) with duplicates summed: the same sorted columns and the same values,
    # including supports wider than the circle (gauss:200 at K = 8 wraps several times)
    import envs
    from planners.cells import CellSpace
    from planners.coverage import TurnNoise, model_for
    from planners.noise import parse_noise_spec
    env = envs.Environment.from_dict({"boundary": [[0, 0], [1.8, 0], [1.8, 1.5], [0, 1.5]],
                                      "obstacles": [[[0.8, 0.7], [1.0, 0.65], [0.9, 0.85]]],
                                      "robot_radius": 0.17,
                                      "discretization": {"cell_size": 0.3, "orientations": K}})
    m = model_for(CellSpace(env), "event")
    if noise is None:
        nz = TurnNoise()
    elif noise.endswith("+body"):
        nz = parse_noise_spec(noise[:-5]).noise.with_body("gauss:0.6,offset=-1.26")
    else:
        nz = parse_noise_spec(noise).noise
    for angle in (45.0, 90.0, 315.0):
        got = m.turn_matrix(angle, nz)
        steps, probs = nz.turns(K, angle, positive=True)
        ref = _turn_matrix_reference(m.n_states, K, steps, probs)
        assert got.shape == ref.shape and got.nnz == ref.nnz
        assert np.array_equal(got.indptr, ref.indptr) and np.array_equal(got.indices, ref.indices)
        assert np.allclose(got.data, ref.data, rtol=0, atol=1e-15)
        assert np.allclose(np.asarray(got.sum(axis=1)).ravel(), 1.0)


def test_block_cumsum_matches_numpy_per_block():
    # the compiled restartable cumulative sum of the coverage sampler against np.cumsum
    # block by block, on random blocks with empty ones and all-zero ones
    from planners.coverage.cover_sample import _block_cumsum
    rng = np.random.default_rng(5)
    ptr = np.concatenate([[0], np.cumsum(rng.integers(0, 6, 400))])
    w = rng.random(int(ptr[-1]))
    w[rng.random(w.size) < 0.3] = 0.0
    got = _block_cumsum(w, ptr)
    for lo, hi in zip(ptr[:-1], ptr[1:]):
        if hi == lo:
            continue
        c = np.cumsum(w[lo:hi])
        want = c / c[-1] if c[-1] > 0 else c.copy()
        want[-1] = 1.0
        assert np.allclose(got[lo:hi], want, rtol=1e-12, atol=1e-15)
