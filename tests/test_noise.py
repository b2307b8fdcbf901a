"""Rotation-noise models: distributions, determinism and the CLI parser (docs/model.md §16, §21).

Statistical bounds: with n draws a frequency p̂ of an event of probability p is checked to
lie within 5 standard errors sqrt(p (1 - p) / n) (two-sided tail below 1e-6 per check; the
draws are seeded, so the tests are deterministic anyway).
"""

from __future__ import annotations

import numpy as np
import pytest

from bouncesim.robots.noise import GaussianNoise, NoNoise, SteppedNoise, noise_for_mix, parse_noise
from envs import UserError
from planners.plan import PolicyMix

N = 200_000


def _within(p_hat: float, p: float, n: int, k: float = 5.0) -> bool:
    return abs(p_hat - p) <= k * np.sqrt(p * (1 - p) / n)


def test_no_noise_is_exact():
    rng = np.random.default_rng(0)
    m = NoNoise()
    assert m.sample(rng, 135.0) == 135.0
    assert np.array_equal(m.sample_many(rng, 90.0, 5), np.full(5, 90.0))
    assert np.array_equal(m.sample_many(rng, np.array([45.0, 90.0])), [45.0, 90.0])
    assert m.exact


@pytest.mark.parametrize("eps,r,delta", [(3, 0.6, 1.0), (45, 0.8, 45.0), (90, 0.0, 45.0)])
def test_stepped_noise_distribution(eps, r, delta):
    m = SteppedNoise(eps, r, delta)
    out = m.sample_many(np.random.default_rng(1), 90.0, N)
    err = out - 90.0
    k = np.round(err / delta)
    assert np.allclose(err, k * delta), "errors must be multiples of delta"
    mq = int(round(eps / delta))
    assert set(np.unique(k).astype(int)) <= set(range(-mq, mq + 1))
    assert _within(np.mean(k == 0), r, N)
    for j in [*range(-mq, 0), *range(1, mq + 1)]:
        assert _within(np.mean(k == j), (1 - r) / (2 * mq), N), j


def test_stepped_noise_offsets_match_model():
    vals, probs = SteppedNoise(2, 0.5, 1).offsets()
    assert dict(zip(vals.tolist(), probs.tolist())) == {0.0: 0.5, -2.0: 0.125, -1.0: 0.125,
                                                         1.0: 0.125, 2.0: 0.125}


def test_stepped_noise_degenerate_cases_are_exact():
    rng = np.random.default_rng(2)
    assert np.all(SteppedNoise(0, 0.1, 1).sample_many(rng, 90.0, 1000) == 90.0)
    assert np.all(SteppedNoise(5, 1.0, 1).sample_many(rng, 90.0, 1000) == 90.0)
    never = SteppedNoise(1, 0.0, 1).sample_many(rng, 90.0, 1000)
    assert set(never.tolist()) == {89.0, 91.0}


def test_stepped_noise_rejects_bad_parameters():
    with pytest.raises(UserError, match="multiple"):
        SteppedNoise(5, 0.8, 45)
    with pytest.raises(UserError, match="reliability"):
        SteppedNoise(1, 1.5, 1)
    with pytest.raises(UserError, match="non-negative"):
        SteppedNoise(-1, 0.5, 1)


def test_gaussian_noise_distribution():
    out = GaussianNoise(2.0).sample_many(np.random.default_rng(3), 135.0, N) - 135.0
    assert abs(out.mean()) <= 5 * 2.0 / np.sqrt(N)
    # the sample standard deviation has standard error ~ sigma / sqrt(2 n)
    assert abs(out.std() - 2.0) <= 5 * 2.0 / np.sqrt(2 * N)
    assert abs(np.mean(np.abs(out) <= 2.0) - 0.6827) <= 5 * np.sqrt(0.68 * 0.32 / N)
    assert GaussianNoise(0).sample(np.random.default_rng(0), 45.0) == 45.0
    with pytest.raises(UserError):
        GaussianNoise(-1)


@pytest.mark.parametrize("model", [SteppedNoise(3, 0.5, 1), GaussianNoise(1.5)])
def test_same_seed_same_draws(model):
    a = [model.sample(np.random.default_rng(7), 90.0) for _ in range(3)]
    b = [model.sample(np.random.default_rng(7), 90.0) for _ in range(3)]
    assert a == b
    x = model.sample_many(np.random.default_rng(8), np.array([45.0, 90.0, 135.0]))
    y = model.sample_many(np.random.default_rng(8), np.array([45.0, 90.0, 135.0]))
    assert np.array_equal(x, y)
    z = model.sample_many(np.random.default_rng(9), 90.0, 50)
    assert len(set(z.tolist())) > 1, "different draws should differ"


def test_sample_many_per_element_commands():
    out = SteppedNoise(1, 0.0, 1).sample_many(np.random.default_rng(0),
                                               np.array([10.0, 200.0, 300.0]))
    assert np.allclose(np.abs(out - [10.0, 200.0, 300.0]), 1.0)


@pytest.mark.parametrize("text,expected", [
    ("none", NoNoise()),
    ("gauss:2", GaussianNoise(2.0)),
    ("gauss:sigma=0.5", GaussianNoise(0.5)),
    ("model:eps=5,r=0.8", SteppedNoise(5.0, 0.8, 1.0)),
    ("model:r=0.8,eps=3,delta=0.5", SteppedNoise(3.0, 0.8, 0.5)),
])
def test_parse_noise(text, expected):
    assert parse_noise(text, delta_deg=1.0) == expected


@pytest.mark.parametrize("text", ["gauss", "gauss:x", "model:eps=5", "model:eps=5,r=a",
                                  "model:eps=5,r=0.5,q=1", "uniform:3", "model:eps=5,r=2"])
def test_parse_noise_errors_are_one_sentence(text):
    with pytest.raises(UserError) as err:
        parse_noise(text, delta_deg=1.0)
    msg = str(err.value)
    assert msg.endswith(".") and "\n" not in msg


def test_parse_noise_model_uses_the_environment_step():
    with pytest.raises(UserError, match="45"):
        parse_noise("model:eps=5,r=0.8", delta_deg=45.0)
    assert parse_noise("model:eps=45,r=0.8", delta_deg=45.0) == SteppedNoise(45, 0.8, 45)


def test_noise_for_mix():
    mix = PolicyMix((90.0,), (1.0,), eps=2.0, r=0.9)
    assert noise_for_mix(mix, 1.0) == SteppedNoise(2.0, 0.9, 1.0)
    assert noise_for_mix(PolicyMix((90.0,), (1.0,)), 1.0) == NoNoise()


def test_a_gaussian_designed_mix_keeps_its_sigma():
    # a mix designed for Gaussian turn noise is executed with that noise: design_mix's
    # PolicyMix carries σ and noise_for_mix turns it into the body's Gaussian noise model
    # (it used to carry eps=0, r=1 and noise_for_mix returned exact turns)
    import envs
    from planners.cells import CellSpace
    from planners.coverage import design_mix, model_for
    from planners.noise import TurnNoise
    cs = CellSpace(envs.load("lab", orientations=72))
    mix = design_mix(model_for(cs, "step"), [30, 75], TurnNoise.gauss(3)).mix
    assert (mix.eps, mix.r, mix.sigma) == (0.0, 1.0, 3.0)
    assert mix.noise == TurnNoise.gauss(3)
    assert noise_for_mix(mix, cs.delta_deg) == GaussianNoise(3.0)
    # the §11 noise is unchanged, and one kind at a time
    assert noise_for_mix(PolicyMix((90.0,), (1.0,), eps=2.0, r=0.9), 1.0) == \
        SteppedNoise(2.0, 0.9, 1.0)
    with pytest.raises(UserError):
        PolicyMix((90.0,), (1.0,), eps=2.0, r=0.9, sigma=1.0)
