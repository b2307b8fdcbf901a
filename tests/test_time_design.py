"""Mixes designed for time (planners.coverage.time_design, docs/model.md §20b)."""

from __future__ import annotations

import numpy as np
import pytest

import envs
from envs import UserError
from planners.cells import CellSpace
from planners.coverage import design_mix, model_for
from planners.coverage.cover_time import coverage_metrics
from planners.coverage.time_design import objective_value, simplex_grid
from planners.noise import TurnNoise
from planners.plan import PolicyMix


def test_simplex_grid():
    g = simplex_grid(3, 10)
    assert g.shape == (66, 3) and np.allclose(g.sum(1), 1.0) and (g >= 0).all()
    assert {tuple(r) for r in simplex_grid(2, 4)} == {(0, 1), (.25, .75), (.5, .5), (.75, .25),
                                                      (1, 0)}


class _Rec:
    horizon = 1000
    idleness_worst, idleness_se = 640.0, 12.0

    def __init__(self, mean, miss):
        self.T = {"0.9": {"mean": mean, "not_reached": miss, "mean_se": 8.0}}


def test_objective_counts_a_run_that_does_not_cover_at_the_horizon():
    assert objective_value(_Rec(100.0, 0.25), "cover90") == (0.75 * 100 + 0.25 * 1000,
                                                            0.75 * 8.0)
    assert objective_value(_Rec(None, 1.0), "cover90") == (1000.0, 0.0)
    assert objective_value(_Rec(100.0, 0.0), "idleness") == (640.0, 12.0)


def test_design_for_time_evaluates_every_candidate_with_one_seed():
    cs = CellSpace(envs.load("lab"))
    model, noise = model_for(cs, "event"), TurnNoise(45, 0.9)
    d = design_mix(model, (90, 135), noise, objective="cover90", horizon=400, epoch=100,
                   runs=40, grid=4, rng=3, refine=0)
    assert d.candidates.shape == (5, 2) and d.value == d.values.min()
    assert tuple(d.alpha) == tuple(d.candidates[int(np.argmin(d.values))])
    # a second stage re-samples the best two with 3 × the runs and picks among them
    r = design_mix(model, (90, 135), noise, objective="cover90", horizon=400, epoch=100,
                   runs=40, grid=4, rng=3, refine=2, refine_factor=3)
    assert np.array_equal(r.values, d.values) and len(r.refined) == 2
    assert set(r.refined) == set(np.argsort(d.values, kind="stable")[:2].tolist())
    best = min(r.refined, key=lambda i: r.refined[i][0])
    assert tuple(r.alpha) == tuple(r.candidates[best]) and r.value == r.refined[best][0]
    # the plumbing, independently: candidate i's value is coverage_metrics' with that seed
    for i in (0, 2):
        mix = PolicyMix((90.0, 135.0), tuple(d.candidates[i]), 45, 0.9)
        rec, = coverage_metrics(model, mix, noise, horizon=400, epoch=100, runs=40,
                                rng=d.seed, exact=False, times=[400])
        assert objective_value(rec, "cover90")[0] == pytest.approx(d.values[i])
    assert d.mix.alpha == tuple(d.alpha)
    idle = design_mix(model, (90, 135), noise, objective="idleness", horizon=400, epoch=100,
                      runs=40, grid=2, rng=3)
    assert idle.objective == "idleness" and 0 < idle.value <= 400


def test_design_mix_refuses_what_a_time_objective_does_not_use():
    cs = CellSpace(envs.load("lab"))
    model = model_for(cs, "step")
    with pytest.raises(UserError, match="unknown time objective 'speed'"):
        design_mix(model, (90,), objective="speed")
    with pytest.raises(UserError, match="drop the target"):
        design_mix(model, (90,), objective="cover90", target=np.ones(cs.P))
    with pytest.raises(UserError, match="with a time objective only"):
        design_mix(model, (90,), runs=5)


@pytest.mark.slow
def test_cover_design_quick(tmp_path):
    import pandas as pd

    from experiments import cover_design
    assert cover_design.main(["--quick", "--out", str(tmp_path)]) == 0
    t = pd.read_csv(tmp_path / "designs.csv")
    assert t.objective.tolist() == ["tv", "cover90", "idleness"]
    alphas = t[[c for c in t.columns if c.startswith("alpha_")]].to_numpy()
    assert np.allclose(alphas.sum(1), 1.0)
    # the shape design promises the lowest long-run TV of the three, by construction
    assert t.limit_tv_to_uniform[0] <= t.limit_tv_to_uniform.min() + 1e-9
    assert (t.twin_C_T > 0).all() and (t.model_C_T > 0).all()
