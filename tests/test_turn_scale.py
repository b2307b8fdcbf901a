"""An unknown turn scale and bias (the noise spec's ``scale=S``, ``bias=B``) and a body's known
turn factor and offset (``factor=F``, ``offset=O``): the one grammar, TurnNoise, the
simulated bodies' :class:`~bouncesim.robots.noise.ScaledNoise`, and the coverage models'
refusal.

Independent evidence: hand-computed turns (90° · 1.08 = 97.2°), the factor a seeded
generator's first ``uniform`` gives, and the existing noise models for the scatter.
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

import envs
from bouncesim.robots import make_robot
from bouncesim.robots.kinematic import KinematicBatch, KinematicRobot
from bouncesim.robots.noise import (
    GaussianNoise,
    NoNoise,
    ScaledNoise,
    SteppedNoise,
    body_noise,
    noise_and_rng,
    noise_for_mix,
    parse_noise,
)
from bouncesim.runs.execute import execute
from envs import UserError
from planners.cells import CellSpace
from planners.coverage import design_mix, model_for
from planners.noise import NoiseSpec, TurnNoise, parse_noise_spec
from planners.plan import Plan, PolicyMix

HAVE_PYBULLET = importlib.util.find_spec("pybullet") is not None


@pytest.fixture(scope="module")
def lab():
    return envs.load("lab")


@pytest.fixture(scope="module")
def cs(lab):
    return CellSpace(lab)


def _one_sentence(err) -> str:
    msg = str(err.value)
    assert msg.endswith(".") and "\n" not in msg, msg
    return msg


def _turned(noise, angle=90.0, rng=0, turns=1, env=None) -> list[float]:
    """Heading changes [deg] of a twin at (0.51, 0.51) facing east over ``turns`` turns."""
    bot = KinematicRobot(env or envs.load("lab"), noise, rng)
    bot.place(0.51, 0.51, 0.0)
    out = []
    for _ in range(turns):
        h0 = bot.true_pose()[2]
        bot.turn(angle)
        out.append((bot.true_pose()[2] - h0) % 360.0)
    return out


# ================================================================================ grammar
@pytest.mark.parametrize("text,canonical", [
    ("gauss:2,scale=0.1", "gauss:2,scale=0.1"),
    ("gauss:sigma=2,scale=0.1,bias=1", "gauss:2,scale=0.1,bias=1"),
    ("Gaussian: sigma=2, bias=1, scale=0.1", "gauss:2,scale=0.1,bias=1"),
    ("model:eps=5,r=0.8,scale=0.05", "model:eps=5,r=0.8,scale=0.05"),
    ("stepped:scale=0.05,r=0.8,eps=5,delta=0.5", "model:eps=5,r=0.8,delta=0.5,scale=0.05"),
    ("none:factor=1.08", "none:factor=1.08"),
    ("none,factor=1.08", "none:factor=1.08"),
    ("off:offset=-2,factor=0.92", "none:factor=0.92,offset=-2"),
    ("exact:scale=0.2", "none:scale=0.2"),
    ("gauss:0,factor=1.08", "gauss:0,factor=1.08"),
    ("model:eps=2,r=0.5,factor=0.9,bias=3", "model:eps=2,r=0.5,bias=3,factor=0.9"),
    ("gauss:1,scale=0.1,offset=2", "gauss:1,scale=0.1,offset=2"),
])
def test_spec_round_trips(text, canonical):
    spec = parse_noise_spec(text)
    assert str(spec) == canonical
    assert parse_noise_spec(str(spec)) == spec


def test_fields_of_the_turn_keys():
    spec = parse_noise_spec("gauss:sigma=2,scale=0.1,bias=1")
    assert spec == NoiseSpec("gauss", TurnNoise(sigma_deg=2, scale=0.1, bias_deg=1))
    assert (spec.factor, spec.offset_deg) == (None, None)
    spec = parse_noise_spec("none:factor=1.08,offset=-1.5")
    assert spec.noise == TurnNoise() and (spec.factor, spec.offset_deg) == (1.08, -1.5)
    spec = parse_noise_spec("model:eps=5,r=0.8,scale=0.05")
    assert spec.noise == TurnNoise(5, 0.8, scale=0.05) and spec.kind == "model"


@pytest.mark.parametrize("noise", [TurnNoise(sigma_deg=2, scale=0.1),
                                   TurnNoise(5, 0.8, scale=0.05, bias_deg=1),
                                   TurnNoise(scale=0.2), TurnNoise(bias_deg=2.5),
                                   TurnNoise(sigma_deg=0.3), TurnNoise(5, 0.8), TurnNoise()])
def test_turn_noise_str_round_trips(noise):
    assert TurnNoise.from_spec(str(noise)) == noise


def test_existing_forms_unchanged():
    assert parse_noise_spec("gauss:2") == NoiseSpec("gauss", TurnNoise.gauss(2))
    assert parse_noise_spec("model:eps=5,r=0.8,delta=1") == \
        NoiseSpec("model", TurnNoise(5, 0.8), 1.0)
    for text in ("", "none", "off", "exact", " NONE "):
        assert parse_noise_spec(text) == NoiseSpec("none", TurnNoise())
    assert repr(parse_noise_spec("model:eps=5,r=0.8")) == (
        "NoiseSpec(kind='model', noise=TurnNoise(eps_deg=5.0, r=0.8, sigma_deg=0.0), "
        "delta_deg=None)")
    assert repr(TurnNoise(5, 0.8)) == "TurnNoise(eps_deg=5.0, r=0.8, sigma_deg=0.0)"
    assert str(TurnNoise.gauss(2)) == "gauss:2" and str(TurnNoise(5, 0.8)) == "model:eps=5,r=0.8"
    assert parse_noise("gauss:2") == GaussianNoise(2.0)
    assert parse_noise("model:eps=5,r=0.8", 1.0) == SteppedNoise(5, 0.8, 1.0)
    assert parse_noise("none") == NoNoise()


@pytest.mark.parametrize("text,words", [
    ("gauss:2,scale=0.1,scale=0.2", "twice"),
    ("model:eps=5,r=0.8,bias=1,bias=1", "twice"),
    ("gauss:2,skew=1", "not understood"),
    ("none:eps=5", "not understood"),
    ("none:3", "not understood"),
    ("gauss:2,3", "not understood"),
    ("gauss:2,scale=x", "not a number"),
    ("none:factor=", "not a number"),
    ("gauss:2,scale=0.5", "[0, 0.5)"),
    ("gauss:2,scale=-0.1", "[0, 0.5)"),
    ("none:scale=nan", "[0, 0.5)"),
    ("gauss:2,bias=-1", "non-negative"),
    ("gauss:2,bias=inf", "non-negative"),
    ("none:factor=0", "positive"),
    ("none:factor=-1.08", "positive"),
    ("none:factor=inf", "positive"),
    ("none:offset=nan", "finite"),
    ("none:", "unknown noise"),
    (":factor=1.08", "unknown noise"),
    ("gauss,2", "unknown noise"),
    ("gauss:scale=0.1", "needs a number of degrees"),
    ("model:eps=5,scale=0.1", "needs both eps and r"),
])
def test_spec_errors_are_one_sentence_naming_the_forms(text, words):
    with pytest.raises(UserError) as err:
        parse_noise_spec(text)
    msg = _one_sentence(err)
    assert words in msg and "use none, gauss:SIGMA or model:eps=E,r=R" in msg, msg
    with pytest.raises(UserError):
        parse_noise(text, 1.0)


def test_turn_noise_fields_are_validated():
    for kw, words in (({"scale": 0.5}, "[0, 0.5)"), ({"scale": -0.01}, "[0, 0.5)"),
                      ({"bias_deg": -1}, "non-negative"), ({"scale": "x"}, "number"),
                      ({"bias_deg": float("inf")}, "finite")):
        with pytest.raises(UserError) as err:
            TurnNoise(**kw)
        assert words in _one_sentence(err)
    n = TurnNoise(5, 0.8, 0.0, 0.1, 2)                 # positional order kept, new ones after
    assert (n.eps_deg, n.r, n.sigma_deg, n.scale, n.bias_deg) == (5.0, 0.8, 0.0, 0.1, 2.0)
    assert repr(n) == "TurnNoise(eps_deg=5.0, r=0.8, sigma_deg=0.0, scale=0.1, bias_deg=2.0)"
    assert not TurnNoise(scale=0.1).exact and not TurnNoise(bias_deg=1).exact
    assert TurnNoise(scale=0.0, bias_deg=0.0).exact and TurnNoise(scale=0.0) == TurnNoise()
    assert n.scatter == TurnNoise(5, 0.8) and not n.unbiased and n.scatter.unbiased


def test_from_spec_takes_scale_and_bias_but_not_a_bodys_known_values():
    assert TurnNoise.from_spec("gauss:2,scale=0.1,bias=1") == \
        TurnNoise(sigma_deg=2, scale=0.1, bias_deg=1)
    for text in ("gauss:2,factor=1.08", "none:offset=2"):
        with pytest.raises(UserError) as err:
            TurnNoise.from_spec(text)
        assert "known" in _one_sentence(err)


# ========================================================================== coverage models
def test_coverage_models_refuse_scale_and_bias(cs):
    for noise in (TurnNoise(scale=0.1), TurnNoise(bias_deg=1), TurnNoise.from_spec(
            "gauss:2,scale=0.1")):
        with pytest.raises(UserError) as err:
            design_mix(model_for(cs, "step"), [90], noise)
        assert "the coverage models assume an unbiased turn" in _one_sentence(err)
        for method, args, kw in (("support", (cs.K,), {}), ("turns", (cs.K, 90), {}),
                                 ("quanta", (cs.K,), {}), ("support", (), {"delta_deg": 1.0})):
            with pytest.raises(UserError, match="unbiased"):
                getattr(noise, method)(*args, **kw)
        with pytest.raises(UserError) as err:
            noise.sample(np.random.default_rng(0), 90.0, 3, delta_deg=1.0)
        _one_sentence(err)


def test_coverage_models_unchanged_without_scale_and_bias(cs):
    plain, zero = TurnNoise(45, 0.8), TurnNoise(45, 0.8, 0.0, 0.0, 0.0)
    assert plain == zero and hash(plain) == hash(zero)
    a = design_mix(model_for(cs, "step"), [90, 135], plain)
    b = design_mix(model_for(cs, "step"), [90, 135], zero)
    assert np.array_equal(a.alpha, b.alpha)
    s, p = plain.turns(cs.K, 90)
    assert s.tolist() == [1, 2, 3] and np.allclose(p, [0.1, 0.8, 0.1])


# ================================================================================ bodies
@pytest.mark.parametrize("text,expected", [
    ("gauss:0,factor=1.08", 97.2), ("none:factor=0.92", 82.8), ("none,factor=0.92", 82.8),
    ("none:offset=3", 93.0), ("none:factor=1.1,offset=-2", 97.0),
    ("model:eps=1,r=1,factor=1.08", 97.2)])
def test_twin_applies_a_known_factor_and_offset(lab, cs, text, expected):
    noise = parse_noise(text, cs.delta_deg)
    assert isinstance(noise, ScaledNoise) and not noise.exact
    assert _turned(noise, env=lab, turns=3) == pytest.approx([expected] * 3, abs=1e-9)
    # a known factor draws nothing: no rng needed
    assert _turned(noise, env=lab, rng=None) == pytest.approx([expected], abs=1e-9)


def test_known_factor_of_one_is_the_plain_model():
    assert parse_noise("gauss:2,factor=1,offset=0") == GaussianNoise(2.0)
    assert parse_noise("none:factor=1").exact


def test_scale_draws_one_factor_per_body(lab):
    noise = parse_noise("none:scale=0.1")
    assert str(noise) == "none:scale=0.1" and not noise.exact and noise.drawn_factor is None
    turns = _turned(noise, env=lab, rng=7, turns=5)
    f = np.random.default_rng(7).uniform(0.9, 1.1)          # the body's rng, first draw
    assert turns == pytest.approx([90 * f] * 5, abs=1e-9)
    assert noise.drawn_factor == pytest.approx(f) and noise.drawn_offset_deg == 0.0
    # the same seed: the same factor, also from a fresh model; other seeds: others
    assert _turned(parse_noise("none:scale=0.1"), env=lab, rng=7) == pytest.approx([90 * f])
    factors = [_turned(noise, env=lab, rng=s)[0] / 90 for s in range(8)]
    assert all(0.9 <= x <= 1.1 for x in factors) and len(set(factors)) == 8
    assert noise.drawn_factor == pytest.approx(factors[-1])   # the body that turned last


def test_bias_draws_one_offset_per_body(lab):
    noise = parse_noise("none:bias=2")
    turns = _turned(noise, env=lab, rng=3, turns=4)
    b = np.random.default_rng(3).uniform(-2, 2)
    assert turns == pytest.approx([90 + b] * 4, abs=1e-9)
    assert noise.drawn() == pytest.approx((1.0, b))
    offsets = {round(_turned(noise, env=lab, rng=s)[0] - 90, 12) for s in range(8)}
    assert len(offsets) == 8 and all(-2 <= o <= 2 for o in offsets)
    # both: the factor first, then the offset, from the same rng
    g = np.random.default_rng(4)
    f, b = g.uniform(0.8, 1.2), g.uniform(-3, 3)
    both = parse_noise("none:scale=0.2,bias=3")
    assert _turned(both, env=lab, rng=4, turns=2) == pytest.approx([90 * f + b] * 2)


def test_scale_with_scatter_is_reproducible_per_seed(lab, cs):
    def run(seed):
        noise = parse_noise("gauss:2,scale=0.1", cs.delta_deg)
        return _turned(noise, env=lab, rng=seed, turns=6), noise.drawn_factor

    (a, fa), (b, fb), (c, fc) = run(0), run(0), run(1)
    assert a == b and fa == fb and a != c and fa != fc
    assert 0.9 <= fa <= 1.1 and np.std(a) > 0              # the scatter still scatters
    # the scatter is the base's draw on the scaled command
    g = np.random.default_rng(0)
    f = g.uniform(0.9, 1.1)
    assert a[0] == pytest.approx((90 * f + g.normal(0.0, 2.0)) % 360.0)


def test_sample_many_is_vectorised_and_shares_the_factor():
    noise = parse_noise("none:scale=0.1,bias=1")
    rng = np.random.default_rng(5)
    c = np.array([45.0, 90.0, 135.0])
    out = noise.sample_many(rng, c)
    f, b = noise.drawn(rng)
    assert out == pytest.approx(f * c + b)
    assert noise.sample_many(rng, 90.0, 4) == pytest.approx(np.full(4, 90 * f + b))
    assert noise.sample(rng, 30.0) == pytest.approx(30 * f + b)
    g = parse_noise("model:eps=2,r=0.0,scale=0.1", 1.0)
    x = g.sample_many(np.random.default_rng(6), 90.0, 1000)
    f = g.drawn_factor
    assert set(np.round(x - 90 * f, 9).tolist()) == {-2.0, -1.0, 1.0, 2.0}


def test_kinematic_batch_applies_it_through_sample_many(lab, cs):
    noise = parse_noise("none:factor=1.08")
    batch = KinematicBatch(lab, 50, np.random.default_rng(0), cells=cs)
    h0 = batch.heading.copy()
    _, bumped = batch.step(90.0, noise)
    assert bumped.any()
    assert ((batch.heading - h0) % 360)[bumped] == pytest.approx(97.2)
    scaled = parse_noise("none:scale=0.1")
    batch = KinematicBatch(lab, 50, np.random.default_rng(1), cells=cs)
    h0 = batch.heading.copy()
    _, bumped = batch.step(90.0, scaled)
    f = scaled.drawn(batch.rng)[0]                          # one rng: one factor per batch
    assert ((batch.heading - h0) % 360)[bumped] == pytest.approx(90 * f)


def test_body_noise_and_noise_for_mix(cs):
    m = body_noise(TurnNoise(sigma_deg=2, scale=0.1), cs.delta_deg)
    assert m == ScaledNoise(GaussianNoise(2.0), scale=0.1) and str(m) == "gauss:2,scale=0.1"
    m = body_noise(TurnNoise(45, 0.8, bias_deg=1), cs.delta_deg)
    assert m == ScaledNoise(SteppedNoise(45, 0.8, cs.delta_deg), bias_deg=1.0)
    assert m.drawn_factor is None and m.sample(np.random.default_rng(0), 90.0) is not None
    assert m.drawn_factor == 1.0 and -1 <= m.drawn_offset_deg <= 1
    assert body_noise(TurnNoise(45, 0.8), cs.delta_deg) == SteppedNoise(45, 0.8, cs.delta_deg)
    assert noise_for_mix(PolicyMix((90.0,), (1.0,), sigma=3.0), 1.0) == GaussianNoise(3.0)


@pytest.mark.parametrize("text", ["gauss:2,scale=0.1", "none:factor=1.08",
                                  "model:eps=2,r=0.8,bias=1,factor=0.9",
                                  "gauss:0.5,offset=-2"])
def test_scaled_noise_str_round_trips(text):
    m = parse_noise(text, 1.0)
    assert str(m) == text and parse_noise(str(m), 1.0) == m
    assert hash(m) == hash(parse_noise(text, 1.0))


def test_scaled_noise_validation_and_rng_contract():
    with pytest.raises(UserError):
        ScaledNoise(NoNoise(), factor=0)
    with pytest.raises(UserError):
        ScaledNoise(NoNoise(), scale=0.6)
    with pytest.raises(UserError) as err:                # a drawn factor needs an rng
        noise_and_rng(parse_noise("none:scale=0.1"), None)
    _one_sentence(err)
    with pytest.raises(UserError):
        noise_and_rng(parse_noise("gauss:1,factor=1.1"), None)
    noise, rng = noise_and_rng(parse_noise("none:factor=1.1"), None)
    assert rng is None and not noise.exact
    with pytest.raises(UserError):
        parse_noise("none:scale=0.1").sample(None, 90.0)


def test_execute_a_plan_with_an_unknown_scale(lab, cs):
    noise = parse_noise("gauss:2,scale=0.1", cs.delta_deg)
    robot = make_robot("kinematic", lab, noise=noise, rng=0)
    with robot:
        run = execute(Plan.parse("90° 90° 00000000 90° 90°"), robot, start=8, goal=0, cells=cs)
    assert run.bumps >= 1 and 0.9 <= noise.drawn_factor <= 1.1


@pytest.mark.skipif(not HAVE_PYBULLET, reason="pybullet is not installed")
@pytest.mark.physics
def test_pybullet_robot_applies_a_known_factor(lab):
    from bouncesim.robots.pybullet import PyBulletRobot
    with PyBulletRobot(lab, noise=parse_noise("none:factor=1.08"), rng=0) as bot:
        bot.place(0.68, 0.68, 0.0)
        h0 = bot.true_pose()[2]
        bot.turn(90)
        turned = (bot.true_pose()[2] - h0) % 360.0
    assert turned == pytest.approx(97.2, abs=1.5)


def test_a_known_factor_and_offset_centre_the_unknown_ranges():
    # factor=F with scale=S and offset=O with bias=B: the body draws f within F ± S and b
    # within O ± B (200 bodies: every draw inside, both ends of each range reached within
    # 10 % of its width); the filter starts its particles within the same ranges
    from planners.navigation.feedback.planner import declared_turn
    m = parse_noise("gauss:0,factor=1.05,scale=0.02,offset=-0.8,bias=0.5", 1.0)
    assert str(m) == "gauss:0,scale=0.02,bias=0.5,factor=1.05,offset=-0.8"
    assert parse_noise(str(m), 1.0) == m
    draws = np.array([m.draw(np.random.default_rng(i)) for i in range(200)])
    f, b = draws[:, 0], draws[:, 1]
    assert 1.03 <= f.min() <= 1.034 and 1.066 <= f.max() <= 1.07
    assert -1.3 <= b.min() <= -1.2 and -0.4 <= b.max() <= -0.3
    t = declared_turn("gauss:0.55,offset=-0.77,bias=0.5")
    assert (t["sigma"], t["offset"], t["bias"], t["scale"]) == (0.55, -0.77, 0.5, 0.0)
