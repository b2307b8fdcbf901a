"""The sweep runner: seeding contract, executors, journal, resume after SIGKILL, config guard."""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bouncesim.runs.executors import (
    DaskExecutor,
    PoolExecutor,
    SerialExecutor,
    add_executor_args,
    make_executor,
)
from bouncesim.runs.sweep import (
    Sweep,
    TrialError,
    demo_trial,
    grid,
    read_journal,
    run_sweep,
    trial_seed,
)
from envs import UserError

ROOT = Path(__file__).resolve().parent.parent
TRIALS = grid(mu=[0.0, 1.5, -2.0], n=[4, 30], rep=range(6))     # 36 trials


def failing_trial(params, rng):
    if params["x"] == 2:
        raise ValueError("boom")
    return {"y": params["x"] * 2}


def clashing_trial(params, rng):
    return {"x": 1}


def _run(tmp_path, name, executor, seed=11, config=None, trials=TRIALS):
    return run_sweep(demo_trial, trials, seed, tmp_path / name, config or {"what": "test"},
                     executor, progress=False)


def test_grid_order_is_the_first_axis_slowest():
    assert grid(a=[1, 2], b="xy") == [{"a": 1, "b": "x"}, {"a": 1, "b": "y"},
                                      {"a": 2, "b": "x"}, {"a": 2, "b": "y"}]
    assert len(TRIALS) == 36


def test_trial_seed_is_the_spawned_child():
    # the contract: trial i of root seed s draws from SeedSequence(s).spawn(n)[i]
    kids = np.random.SeedSequence(5).spawn(40)
    for i in (0, 1, 17, 39):
        assert np.array_equal(trial_seed(5, i).generate_state(4), kids[i].generate_state(4))


def test_serial_table_matches_an_independent_recomputation(tmp_path):
    table = _run(tmp_path, "serial", SerialExecutor())
    assert list(table["trial"]) == list(range(len(TRIALS)))
    kids = np.random.SeedSequence(11).spawn(len(TRIALS))
    for i in (0, 7, 35):
        want = demo_trial(TRIALS[i], np.random.default_rng(kids[i]))
        row = table.iloc[i]
        assert row["mean"] == want["mean"] and row["first"] == want["first"]
        assert row["mu"] == TRIALS[i]["mu"] and row["rep"] == TRIALS[i]["rep"]
    # the CSV on disk is the same table
    disk = pd.read_csv(tmp_path / "serial" / "runs.csv")
    pd.testing.assert_frame_equal(disk, table, check_exact=True)


def test_same_seed_same_table_on_serial_and_process_pool(tmp_path):
    serial = _run(tmp_path, "serial", SerialExecutor())
    pool = _run(tmp_path, "pool", PoolExecutor(2))
    pd.testing.assert_frame_equal(serial, pool, check_exact=True)
    other = _run(tmp_path, "seed12", SerialExecutor(), seed=12)
    assert not np.array_equal(other["mean"], serial["mean"])


def test_same_seed_same_table_on_dask_local_cluster(tmp_path):
    pytest.importorskip("distributed")
    dask = _run(tmp_path, "dask", DaskExecutor(local_workers=2))
    serial = _run(tmp_path, "serial", SerialExecutor())
    pd.testing.assert_frame_equal(serial, dask, check_exact=True)
    cfg = json.loads((tmp_path / "dask" / "config.json").read_text())
    assert cfg["sessions"][0]["executor"]["kind"] == "dask"
    assert cfg["sessions"][0]["executor"]["workers"] == 2


_KILL_SCRIPT = """
import sys
import time
import bouncesim.runs.sweep as sweep
from bouncesim.runs.executors import SerialExecutor
from bouncesim.runs.sweep import demo_trial, grid, run_sweep

class _Clock:
    # trials after the 12th never finish, so the kill lands part way however slow the host
    calls = 0
    def __getattr__(self, name):
        return getattr(time, name)
    def sleep(self, seconds):
        _Clock.calls += 1
        time.sleep(600 if _Clock.calls > 12 else seconds)
sweep.time = _Clock()
trials = grid(mu=[0.0, 1.0], rep=range(20), sleep=[0.04])
run_sweep(demo_trial, trials, 3, sys.argv[1], {"kind": "kill test"}, SerialExecutor(),
          progress=False)
"""


def _kill_trials():
    return grid(mu=[0.0, 1.0], rep=range(20), sleep=[0.04])


def test_sigkill_then_rerun_loses_and_duplicates_no_row(tmp_path):
    out = tmp_path / "killed"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-c", _KILL_SCRIPT, str(out)], cwd=ROOT, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    journal = out / "runs.jsonl"
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline:
            if journal.exists() and journal.read_bytes().count(b"\n") >= 8:
                break
            if proc.poll() is not None:
                pytest.fail(f"the sweep ended early: {proc.stderr.read().decode()}")
            time.sleep(0.01)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    before = read_journal(journal, repair=False)
    assert 8 <= len(before) <= 12, "the kill should land part way"
    assert not (out / "runs.csv").exists()

    sweep = Sweep(demo_trial, _kill_trials(), 3, out, {"kind": "kill test"})
    res = sweep.run(SerialExecutor(), progress=False)
    assert res.n_resumed == len(before) and res.n_run == 40 - len(before)
    lines = [json.loads(s) for s in journal.read_text().splitlines()]
    ids = [r["trial"] for r in lines]
    assert sorted(ids) == list(range(40)), "every trial exactly once in the journal"
    fresh = run_sweep(demo_trial, _kill_trials(), 3, tmp_path / "fresh", {"kind": "kill test"},
                      SerialExecutor(), progress=False)
    pd.testing.assert_frame_equal(res.table, fresh, check_exact=True)


def test_torn_last_line_is_dropped_and_that_trial_rerun(tmp_path):
    out = tmp_path / "torn"
    full = _run(tmp_path, "torn", SerialExecutor())
    journal = out / "runs.jsonl"
    data = journal.read_bytes()
    assert data.endswith(b"\n")
    journal.write_bytes(data[:-9])                       # cut the last row mid-write
    rows = read_journal(journal, repair=False)
    assert len(rows) == len(TRIALS) - 1
    res = Sweep(demo_trial, TRIALS, 11, out, {"what": "test"}).run(SerialExecutor(),
                                                                    progress=False)
    assert (res.n_resumed, res.n_run) == (len(TRIALS) - 1, 1)
    pd.testing.assert_frame_equal(res.table, full, check_exact=True)
    text = journal.read_text()
    assert text.endswith("\n") and len(text.splitlines()) == len(TRIALS)
    for line in text.splitlines():
        json.loads(line)                                  # the torn fragment is gone


def test_broken_line_before_the_end_is_refused(tmp_path):
    _run(tmp_path, "broken", SerialExecutor())
    journal = tmp_path / "broken" / "runs.jsonl"
    lines = journal.read_text().splitlines(keepends=True)
    lines[3] = '{"trial": 3, "mu"\n'
    journal.write_text("".join(lines))
    with pytest.raises(UserError, match="broken line"):
        _run(tmp_path, "broken", SerialExecutor())


def test_resume_with_a_different_config_is_refused_in_one_sentence(tmp_path):
    _run(tmp_path, "cfg", SerialExecutor(), config={"sigma": 1.0})
    with pytest.raises(UserError) as e:
        _run(tmp_path, "cfg", SerialExecutor(), config={"sigma": 2.0})
    msg = str(e.value)
    assert "different sweep" in msg and "config" in msg and "\n" not in msg
    assert msg.count(". ") == 0 and msg.endswith(".")
    with pytest.raises(UserError, match="root_seed"):
        _run(tmp_path, "cfg", SerialExecutor(), seed=99, config={"sigma": 1.0})
    with pytest.raises(UserError, match="trials_sha256"):
        _run(tmp_path, "cfg", SerialExecutor(), config={"sigma": 1.0}, trials=TRIALS[:-1])
    # the same arguments resume (nothing left to run) and give the same table
    again = Sweep(demo_trial, TRIALS, 11, tmp_path / "cfg", {"sigma": 1.0}).run(
        SerialExecutor(), progress=False)
    assert (again.n_run, again.n_resumed) == (0, len(TRIALS))


def test_journal_without_config_is_refused(tmp_path):
    _run(tmp_path, "nocfg", SerialExecutor())
    (tmp_path / "nocfg" / "config.json").unlink()
    with pytest.raises(UserError, match="without its config.json"):
        _run(tmp_path, "nocfg", SerialExecutor())


def test_config_json_records_seed_parameters_versions_and_sessions(tmp_path):
    _run(tmp_path, "meta", SerialExecutor(), config={"sigma": 1.0, "envs": ["lab"]})
    cfg = json.loads((tmp_path / "meta" / "config.json").read_text())
    assert cfg["sigma"] == 1.0 and cfg["envs"] == ["lab"]
    assert cfg["sweep"]["root_seed"] == 11 and cfg["sweep"]["n_trials"] == len(TRIALS)
    assert cfg["sweep"]["trial_fn"] == "bouncesim.runs.sweep.demo_trial"
    assert cfg["versions"]["numpy"] == np.__version__
    assert "git_revision" in cfg
    assert cfg["sessions"][0]["trials_run"] == len(TRIALS)


def test_trial_errors_name_the_trial_and_keep_finished_rows(tmp_path):
    trials = grid(x=[0, 1, 2, 3])
    with pytest.raises(TrialError, match=r"trial 2 \{'x': 2\} raised ValueError: boom"):
        run_sweep(failing_trial, trials, 0, tmp_path / "fail", None, SerialExecutor(),
                  progress=False)
    assert sorted(read_journal(tmp_path / "fail" / "runs.jsonl")) == [0, 1]
    with pytest.raises(TrialError, match="repeat parameter names"):
        run_sweep(clashing_trial, trials, 0, tmp_path / "clash", None, SerialExecutor(),
                  progress=False)


def test_local_functions_and_reserved_names_are_refused(tmp_path):
    def local(params, rng):
        return {}
    with pytest.raises(UserError, match="module level"):
        Sweep(local, [{}], 0, tmp_path)
    with pytest.raises(UserError, match="reserved"):
        Sweep(demo_trial, [{"trial": 1}], 0, tmp_path)
    with pytest.raises(UserError, match="must be a str"):
        Sweep(demo_trial, [{"mu": [1, 2]}], 0, tmp_path)


def test_a_function_of_a_module_run_as_main_is_sent_by_its_module_name(monkeypatch):
    # ``python -m experiments.x`` runs the module as __main__: the sweep must refer to its
    # trial function by the importable name (workers, a remote scheduler and resume need it)
    import importlib.machinery
    import types

    def demo_trial(params, rng):               # stands in for the __main__ copy
        return {}
    demo_trial.__module__ = "__main__"
    demo_trial.__qualname__ = "demo_trial"
    fake_main = types.ModuleType("__main__")
    fake_main.__spec__ = importlib.machinery.ModuleSpec("bouncesim.runs.sweep", None)
    monkeypatch.setitem(sys.modules, "__main__", fake_main)
    sweep = Sweep(demo_trial, [{}], 0, "unused")
    from bouncesim.runs import sweep as module
    assert sweep.trial_fn is module.demo_trial
    assert sweep.identity["trial_fn"] == "bouncesim.runs.sweep.demo_trial"


def test_executor_flags():
    p = add_executor_args(argparse.ArgumentParser())
    assert isinstance(make_executor(p.parse_args(["--workers", "1"])), SerialExecutor)
    pool = make_executor(p.parse_args([]))
    assert isinstance(pool, PoolExecutor) and pool.workers == (os.cpu_count() or 1)
    assert make_executor(p.parse_args(["--workers", "3"])).workers == 3
    dl = make_executor(p.parse_args(["--dask-local", "2"]))
    assert isinstance(dl, DaskExecutor) and dl.local_workers == 2
    remote = make_executor(p.parse_args(["--dask", "tcp://127.0.0.1:8786"]))
    assert remote.address == "tcp://127.0.0.1:8786"
    with pytest.raises(SystemExit):
        p.parse_args(["--workers", "2", "--dask-local", "2"])
    with pytest.raises(UserError, match="at least one"):
        make_executor(p.parse_args(["--workers", "0"]))


def test_docstring_examples_run():
    import doctest

    import bouncesim.runs.sweep as module
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.attempted >= 3 and result.failed == 0


def _fake_server(reply: bytes | None) -> str:
    """A local TCP server that sends ``reply`` on every connection (None: never answers)
    and keeps it open; its address.
    """
    import socket
    import threading
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen()
    held = []

    def serve():
        while True:
            conn, _ = srv.accept()
            held.append(conn)                     # kept open: the client must give up itself
            if reply is not None:
                conn.sendall(reply)

    threading.Thread(target=serve, daemon=True).start()
    return f"tcp://127.0.0.1:{srv.getsockname()[1]}"


@pytest.mark.parametrize("reply", [b"HTTP/1.0 200 OK\r\n\r\n" + bytes(range(256)) * 8, None],
                         ids=["garbage", "silent"])
def test_a_dask_address_that_is_not_a_scheduler_is_one_sentence(reply):
    # a server answering in another protocol (dask would read its bytes as a frame of
    # exabytes) or never answering: one sentence within the probe's 10 s (bound: 30 s)
    address = _fake_server(reply)
    t0 = time.monotonic()
    with pytest.raises(UserError) as err:
        with DaskExecutor(address=address):
            pass
    assert time.monotonic() - t0 < 30
    msg = str(err.value)
    assert address in msg and "Dask scheduler" in msg
    assert "\n" not in msg and msg.endswith(".")


def test_a_real_scheduler_passes_the_probe():
    from distributed import LocalCluster

    from bouncesim.runs.executors import probe_scheduler
    with LocalCluster(n_workers=1, processes=False, dashboard_address=":0") as cluster:
        probe_scheduler(cluster.scheduler_address)          # no error
