"""posicast.sweep (issue #19): Dask execution, persistence and resumption, labelled results, bad input.

The swept functions here are posicast's own (the seed 000 inverse-ZV loop's certified
stability, residual vibration of a ZV shaper), so every value compared is a real
computation; the references are the serial run (for the cluster) and an uninterrupted
run (for the resumed one).
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import posicast
from posicast.sweeps import SchedulerUnreachable, StoreMismatch, load, make_space, sweep
from posicast.sweeps.charts import seed000_loop, stability_point
from posicast.sweeps.engine import _DaskRunner

GAINS = [0.3, 0.7, 0.9, 1.2]
ERRORS = [-0.5, 0.0, 0.5]


def chart_point(gain: float, delay_error: float) -> dict:
    return stability_point(seed000_loop, gain=gain, delay_error=delay_error)


@pytest.fixture(scope="module")
def cluster():
    """One LocalCluster of 2 worker processes for this module, started as ``sweep(workers=2)`` starts its
    own (posicast.sweeps.local_cluster); the tests reach it through a Client, its scheduler address and
    the cluster object."""
    runner = _DaskRunner(workers=2)
    runner.start()
    yield runner
    runner.close()


# ---------------------------------------------------------------------- acceptance 1: cluster == serial
def test_local_cluster_of_two_processes_gives_the_serial_result(tmp_path: Path, cluster) -> None:
    import functools

    f = functools.partial(stability_point, seed000_loop)  # importable on the workers
    params = {"gain": GAINS, "delay_error": ERRORS}
    serial = sweep(f, params, client="serial")
    info = cluster.client.scheduler_info()["workers"]
    assert len(info) == 2 and all(w["nthreads"] == 1 for w in info.values()) and cluster.own_cluster.processes
    parallel = sweep(f, params, client=cluster.client, batch_size=2, store=tmp_path / "chart.zarr")
    assert parallel.timing.workers == 2 and parallel.timing.tasks == 6
    assert serial.complete and parallel.complete
    assert parallel.same_as(serial)
    assert load(tmp_path / "chart.zarr").same_as(serial)
    again = sweep(f, params, client=cluster.own_cluster, batch_size=3)  # the cluster object itself
    assert again.same_as(serial) and again.timing.workers == 2
    # the verdicts themselves: stable below the D-decomposition edge (0.769 .. 0.795 here), unstable above
    assert serial["stable"].tolist() == [[True] * 3, [True] * 3, [False] * 3, [False] * 3]
    assert np.all(serial["unstable_roots"][2:] > 0)


# ---------------------------------------------------------------------- acceptance 2: kill and resume
_SCRIPT = """
import os, sys, time
import posicast
from posicast.sweeps import sweep

LOG = sys.argv[2]

def vibration(ratio, zeta):
    with open(LOG, "a") as fh:
        fh.write(f"{ratio!r} {zeta!r}\\n")
    time.sleep(0.02)
    S = posicast.design("zv", posicast.Mode(10.0, 0.05))
    return {"v": float(posicast.residual_vibration(S, 10.0 * ratio, zeta)), "ratio_sq": ratio * ratio}

if __name__ == "__main__":
    import numpy as np
    sweep(vibration, {"ratio": list(np.linspace(0.5, 1.5, 12)), "zeta": [0.0, 0.05, 0.1, 0.2, 0.3]},
          client="serial", batch_size=4, store=sys.argv[1])
"""


def _log_points(path: Path) -> list[tuple[float, float]]:
    if not path.exists():
        return []
    return [tuple(float(x) for x in line.split()) for line in path.read_text().splitlines() if line.strip()]


def test_killed_sweep_resumes_without_recomputing_and_loses_nothing(tmp_path: Path, cluster) -> None:
    script = tmp_path / "run_sweep.py"
    script.write_text(textwrap.dedent(_SCRIPT))
    store, log1, log2 = tmp_path / "vib.zarr", tmp_path / "log1", tmp_path / "log2"
    proc = subprocess.Popen([sys.executable, str(script), str(store), str(log1)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    deadline = time.monotonic() + 180  # a loaded machine may take long to start python and import posicast
    while len(_log_points(log1)) < 30 and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)  # a real kill: no cleanup, no flush
    proc.wait()
    assert proc.returncode == -signal.SIGKILL, proc.stderr.read().decode()[-2000:]

    before = load(store)
    stored = before.status.ravel() != "missing"
    assert 0 < stored.sum() < stored.size, "the kill must land half-way"
    assert np.all(before.status.ravel()[stored] == "ok")

    # resume with the same function (same name) on a 2-process LocalCluster reached by its scheduler address,
    # the workers counting their evaluations in log2 (the function is pickled by value: its module is not
    # importable there)
    ns: dict = {"__name__": "resume_script"}
    exec(compile(textwrap.dedent(_SCRIPT).replace("LOG = sys.argv[2]", f"LOG = {str(log2)!r}"), "resume", "exec"), ns)
    grid = {"ratio": list(np.linspace(0.5, 1.5, 12)), "zeta": [0.0, 0.05, 0.1, 0.2, 0.3]}
    address = cluster.own_cluster.scheduler_address
    resumed = sweep(ns["vibration"], grid, client=address, batch_size=4, store=store)
    assert resumed.timing.workers == 2
    points = [tuple(p) for p in zip(before["ratio"].ravel(), before["zeta"].ravel())]
    stored_points = {p for p, s in zip(points, stored) if s}
    second = _log_points(log2)
    assert len(second) == len(set(second)) == resumed.computed == stored.size - stored.sum()
    assert not stored_points & set(second), "a stored point was recomputed"
    assert stored_points | set(second) == set(points), "a point was lost"
    # nothing lost: the stored values are unchanged, and the whole equals an uninterrupted run
    for k in ("v", "ratio_sq"):
        assert np.array_equal(resumed[k].ravel()[stored], before[k].ravel()[stored])
    fresh = sweep(ns["vibration"], grid, client="serial", batch_size=4)
    assert resumed.complete and resumed.same_as(fresh)
    # a second resume computes nothing
    again = sweep(ns["vibration"], grid, client="serial", store=store)
    assert again.computed == 0 and again.same_as(fresh)
    # residual vibration of a ZV at its own mode is 0 (seed 004 eq. 1-3), ratio_sq is ratio^2
    i = int(np.argmin(np.abs(fresh.space.axes[0] - 1.0)))
    assert fresh["ratio_sq"][i, 1] == pytest.approx(fresh.space.axes[0][i] ** 2)


# ---------------------------------------------------------------------- labelled results, failures
def test_failing_point_is_recorded_with_its_message_not_fatal() -> None:
    r = sweep(chart_point, {"gain": [0.5, 0.6], "delay_error": [0.0, -2.0]}, client="serial")
    assert r.status.tolist() == [["ok", "error"], ["ok", "error"]]
    assert r.errors[0, 1] == "ValueError: delay_error must be in (-1, 10], got -2"
    assert r.failures[0].point == {"gain": 0.5, "delay_error": -2.0}
    assert r["stable"][0, 0] and not r["stable"][0, 1]  # fill value where the point failed
    assert "1 failed" not in r.summary() and "2 failed" in r.summary()


def test_results_are_labelled_and_written_as_a_table(tmp_path: Path) -> None:
    r = sweep(lambda ratio, zeta: {"v": float(posicast.residual_vibration(
        posicast.design("zv", posicast.Mode(1.0, zeta)), ratio, zeta)), "kind": "zv", "ok": True},
        {"ratio": [1.0, 2.0], "zeta": [0.0, 0.1]}, client="serial")
    assert r["ratio"].tolist() == [[1.0, 1.0], [2.0, 2.0]] and r["zeta"].tolist() == [[0.0, 0.1], [0.0, 0.1]]
    assert r["v"][0, 0] == pytest.approx(0.0, abs=1e-12)  # ZV at its own mode (seed 004 eq. 1)
    assert r["v"][1, 0] == pytest.approx(1.0, abs=1e-12)  # undamped ZV at 2 omega: both impulses in phase
    assert r["kind"].dtype.kind == "U" and r["ok"].dtype == bool
    r.to_csv(tmp_path / "t.csv")
    lines = (tmp_path / "t.csv").read_text().splitlines()
    assert lines[0] == "ratio,zeta,v,kind,ok,status,error" and len(lines) == 5
    # written like every file posicast writes (posicast._files.atomic_write): the usual mode, not the
    # temporary file's private 0600, and no temporary left behind
    mask = os.umask(0)
    os.umask(mask)
    assert (tmp_path / "t.csv").stat().st_mode & 0o777 == 0o666 & ~mask
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv"]
    with pytest.raises(ValueError, match="path: cannot write"):
        r.to_csv(tmp_path / "no_such_dir" / "t.csv")
    with pytest.raises(KeyError, match="neither a value"):
        r["nope"]


def test_draws_are_seeded_and_independent_of_batching() -> None:
    params = {"c1": stats.uniform(25, 50), "k2": stats.uniform(5, 10)}
    a = sweep(lambda c1, k2: c1 / k2, params, n=9, seed=3, client="serial", batch_size=2)
    b = sweep(lambda c1, k2: c1 / k2, params, n=9, seed=3, client="serial", batch_size=5)
    assert a.same_as(b) and a.shape == (9,)
    rng = np.random.default_rng(3)
    c1 = stats.uniform(25, 50).rvs(size=9, random_state=rng)
    assert np.array_equal(a["c1"], c1)
    assert not sweep(lambda c1, k2: c1, params, n=9, seed=4, client="serial").same_as(a)


def test_progress_bar_on_request(capsys: pytest.CaptureFixture[str]) -> None:
    sweep(lambda x: x, {"x": [1.0, 2.0, 3.0]}, client="serial", progress=True)
    err = capsys.readouterr().err
    assert "3/3" in err and "100%" in err


# ---------------------------------------------------------------------- bad input: one clear line each
@pytest.mark.parametrize("params, kw, exc, match", [
    ({"gain": []}, {}, ValueError, r"parameters\['gain'\] is empty"),
    ({}, {}, ValueError, "parameters is empty"),
    ({"gian": [1.0]}, {}, ValueError, r"unknown parameter 'gian': chart_point accepts gain, delay_error"),
    ({"gain": [1.0, math.nan]}, {}, ValueError, "must be finite"),
    ({"gain": "0.5"}, {}, TypeError, "1-D sequence of values"),
    ({"gain": [0.5], "delay_error": stats.uniform()}, {}, ValueError, "mixes grid axes"),
    ({"gain": stats.uniform()}, {}, ValueError, "n must be given"),
    ({"gain": stats.uniform()}, {"n": 4}, ValueError, "seed must be given"),
    ({"gain": [0.5]}, {"n": 4}, ValueError, "apply to a sweep over distributions only"),
    ({"gain": [0.5]}, {"client": 3}, TypeError, "client must be None"),
    ({"gain": [0.5]}, {"client": "serial", "workers": 2}, ValueError, "workers must be None or 1"),
    ({"gain": [0.5]}, {"batch_size": 0}, ValueError, "batch_size must be"),
])
def test_bad_input_is_one_named_error(params: dict, kw: dict, exc: type, match: str) -> None:
    kw.setdefault("client", "serial")
    with pytest.raises(exc, match=match):
        sweep(chart_point, params, **kw)


def test_unreachable_scheduler_is_a_named_error(tmp_path: Path) -> None:
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(SchedulerUnreachable, match=rf"no Dask scheduler at 'tcp://127.0.0.1:{port}'"):
        sweep(chart_point, {"gain": [0.5]}, client=f"tcp://127.0.0.1:{port}", connect_timeout=0.5,
              store=tmp_path / "s.zarr")
    assert not (tmp_path / "s.zarr").exists()  # nothing written on error
    assert issubclass(SchedulerUnreachable, ConnectionError)


def test_store_of_another_sweep_is_refused(tmp_path: Path) -> None:
    st = tmp_path / "s.zarr"
    sweep(lambda x: x, {"x": [1.0, 2.0]}, client="serial", store=st)
    with pytest.raises(StoreMismatch, match="holds a sweep over other points"):
        sweep(lambda x: x, {"x": [1.0, 3.0]}, client="serial", store=st)
    r = sweep(lambda x: x, {"x": [1.0, 3.0]}, client="serial", store=st, overwrite=True)
    assert r["value"].tolist() == [1.0, 3.0]
    (tmp_path / "f").write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        sweep(lambda x: x, {"x": [1.0]}, client="serial", store=tmp_path / "f")
    with pytest.raises(ValueError, match="does not exist"):
        load(tmp_path / "none.zarr")


def test_unstorable_value_fails_that_point() -> None:
    r = sweep(lambda x: np.ones(2) * x, {"x": [1.0]}, client="serial")
    assert r.status[0] == "error" and "a sweep stores numbers, bools and strings" in r.errors[0]
    r = sweep(lambda x: "big" if x > 1 else x, {"x": [1.0, 2.0]}, client="serial")
    assert r.status.tolist() == ["ok", "error"]
    assert r.errors[1] == "TypeError: value 'value' is str here, float at other points"


def test_space_points_follow_numpy_order() -> None:
    s = make_space({"a": [1, 2], "b": ["x", "y", "z"]})
    assert [s.point(i) for i in (0, 2, 3)] == [{"a": 1.0, "b": "x"}, {"a": 1.0, "b": "z"}, {"a": 2.0, "b": "x"}]
    assert s.fingerprint() == make_space({"a": [1.0, 2.0], "b": ["x", "y", "z"]}).fingerprint()
    assert os.cpu_count()  # the local default uses it
