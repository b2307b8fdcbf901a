"""The pre-flight memory estimates (planners.resources): close to what the code allocates,
and a refusal is one sentence with exit status 2, before anything large is allocated.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import envs
from bouncesim.cli import main
from planners import resources as res
from planners.cells import CellSpace
from planners.coverage import MODELS, TurnNoise, clear_cache, default_settings, model_for
from planners.navigation import Navigator
from planners.navigation.step import all_pairs_bytes, roadmap_bytes, search_bytes

from .conftest import room, traced_peak


def within(est: float, measured: float, factor: float = 2.0) -> bool:
    return measured / factor <= est <= measured * factor


CASES = [("lab", 8), ("lab", 72), ("complex", 8), ("complex", 72)]


@pytest.mark.parametrize("name,K", CASES)
def test_step_table_and_grid_estimates(name, K):
    env = envs.load(name, orientations=K)
    rows, cols = env.grid_shape
    measured = traced_peak(env.grid_centres_free)
    assert within(res.grid_bytes(rows, cols).traced, measured)
    cs = CellSpace(env)
    _ = cs.index_grid
    measured = traced_peak(lambda: cs.forward)
    assert within(res.step_table_bytes(cs.N).traced, measured)


@pytest.mark.parametrize("name,K", CASES)
def test_roadmap_and_search_estimates(name, K):
    cs = CellSpace(envs.load(name, orientations=K))
    _ = cs.forward
    nav = Navigator(cs, [90, 135] if K == 8 else [30, 75, 315])
    m = nav.roadmap.m
    measured = traced_peak(lambda: nav.roadmap.graph)
    assert within(roadmap_bytes(cs.N, m, cs.forward).traced, measured)
    measured = traced_peak(lambda: nav.plan(0, cs.N - 1))
    assert within(search_bytes(cs.N, m).traced, measured)
    # the whole pipeline's estimate is at least its largest stage
    assert Navigator.memory_estimate(cs, nav.angles, "plan", searches=1).total >= \
        roadmap_bytes(cs.N, m, cs.forward).traced


@pytest.mark.parametrize("name,angles", [("lab", [90, 135]), ("lab", [45, 90, 135]),
                                         ("fig1", [45, 90, 135])])
def test_all_pairs_estimate(name, angles):
    cs = CellSpace(envs.load(name))
    nav = Navigator(cs, angles)
    _ = nav.roadmap.graph
    measured = traced_peak(nav.all_pairs)
    assert within(all_pairs_bytes(cs.N, nav.roadmap.m).traced, measured)


@pytest.mark.parametrize("name,K,eps", [("lab", 8, 45), ("lab", 72, 10), ("complex", 72, 5),
                                        ("complex", 8, 0)])
def test_step_chain_estimate(name, K, eps):
    cs = CellSpace(envs.load(name, orientations=K))
    _ = cs.forward
    measured = traced_peak(lambda: model_for(cs, "step").analyse(90, TurnNoise(eps, 0.8)))
    assert within(MODELS["step"].memory_estimate(cs, [90], eps).traced, measured)


@pytest.mark.parametrize("model,K", [("sampled", 72), ("event", 72), ("event", 36)])
def test_continuous_model_estimates(model, K):
    cs = CellSpace(envs.load("lab", orientations=K))
    _ = cs.forward
    from planners.boundary import Boundary
    Boundary(cs.env, 0.1).bin_of(cs.centres[:1])   # compile the bin lookup outside the peak
    clear_cache()
    measured = traced_peak(lambda: model_for(cs, model).analyse(90, TurnNoise(0.0, 1.0)))
    clear_cache()
    assert within(MODELS[model].memory_estimate(cs, [90],
                                                settings=default_settings(model)).traced, measured)


def test_estimates_scale_with_orientations():
    a = Navigator.memory_estimate(CellSpace(envs.load("complex", orientations=8)), [45, 90],
                                  searches=64)
    b = Navigator.memory_estimate(CellSpace(envs.load("complex", orientations=800)), [45, 90],
                                  searches=64)
    assert 50 < b.total / a.total < 200


@pytest.mark.parametrize("text,expected", [("500M", 500 * 2**20), ("2G", 2 * 2**30),
                                           ("2 GiB", 2 * 2**30), ("1.5k", 1536),
                                           ("1e6", 10**6), ("4096", 4096)])
def test_parse_memory(text, expected):
    assert res.parse_memory(text) == expected


@pytest.mark.parametrize("text", ["", "abc", "12Q", "-1G", "0", "nan", "inf", "1e400G"])
def test_parse_memory_rejects(text):
    with pytest.raises(envs.UserError):
        res.parse_memory(text)


def _one_sentence(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("bouncesim: error: ") and lines[0].endswith("."), err
    assert "Traceback" not in err
    return lines[0]


def test_plan_refused_before_allocating(capsys):
    """The issue's example (it used to die in numpy after allocating 6.9 GB)."""
    tracemalloc.start()
    try:
        code = main(["plan", "complex", "--angles", "45,90", "--orientations", "100000",
                     "--start", "0", "--goal", "1"])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert code == 2
    line = _one_sentence(capsys.readouterr().err)
    assert "GiB" in line and "4 GiB" in line
    assert peak < 50 * 2**20                     # refused, not allocated then failed


@pytest.mark.parametrize("argv", [
    ["allpairs", "lab", "--angles", "45,90,135", "--max-memory", "2M", "--out", "{tmp}/o"],
    ["coverage", "lab", "--angles", "90", "--orientations", "360", "--model", "event",
     "--max-memory", "20M"],
    ["coverage", "lab", "--angles", "90", "--orientations", "720", "--max-memory", "10M"],
    ["info", "lab", "--cell-size", "0.0001", "--max-memory", "1G"],
    ["run-plan", "lab", "--angles", "90", "--start", "0", "--goal", "1",
     "--orientations", "4000", "--max-memory", "50M"],
    ["plan", "lab", "--angles", "90", "--start", "0", "--goal", "1", "--max-memory", "lots"],
])
def test_cli_refusals_are_one_sentence(argv, tmp_path, capsys):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    _one_sentence(capsys.readouterr().err)


def test_max_memory_keyword_in_python():
    cs = CellSpace(envs.load("lab"))
    with pytest.raises(envs.UserError, match="memory limit"):
        Navigator(cs, [90, 135], max_memory=10_000)
    with pytest.raises(envs.UserError, match="memory limit"):
        Navigator(cs, [90, 135]).all_pairs(max_memory="100K")
    with pytest.raises(envs.UserError, match="memory limit"):
        _ = CellSpace(envs.load("lab", orientations=400), max_memory="1M").forward
    assert Navigator(cs, [90, 135], max_memory=None).plan(8, 0).cost == 12


def test_search_cache_fits_the_limit():
    cs = CellSpace(envs.load("lab"))
    nav = Navigator(cs, [90, 135], max_memory=None)
    small = Navigator(cs, [90, 135], max_memory=Navigator.memory_estimate(cs, [90, 135],
                                                              searches=3).total)
    assert nav._cache_size == 64 and 1 <= small._cache_size <= 4


def test_grid_guard_in_envs():
    with pytest.raises(envs.InvalidEnvironment, match="use a larger cell size"):
        room(3, 2).with_discretization(cell_size=1e-5)
    with pytest.raises(envs.InvalidEnvironment):
        envs.Environment.from_dict({"boundary": [[-1e308, 0], [1e308, 0], [0, 1e308]]})
    assert np.isfinite(room(3, 2).cell_size)


def test_grid_limit_follows_max_memory():
    n = res.max_grid_cells("100M")
    assert n * res.grid_bytes(1, 1).total <= 100 * 2**20 < (n + 1) * res.grid_bytes(1, 1).total
    env = envs.load("lab", cell_size=0.01, max_grid_cells=n)        # 306 x 204 cells: fits
    assert env.grid_shape == (204, 306)
    with pytest.raises(envs.InvalidEnvironment, match="larger cell size"):
        envs.load("lab", cell_size=0.001, max_grid_cells=n)
