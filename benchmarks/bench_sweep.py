"""posicast.sweep on 2 local Dask worker processes against the same sweep serially (issue #19, acceptance 3).

The sweep: a 400-point certified stability chart (20 gains x 20 shaper delay errors) of seed 000's
inverse-ZV loop (section V, eq. 25-27; posicast.sweeps.charts.seed000_chart's point function),
each point a certified root search of the closed loop's neutral characteristic (~20-30 ms).
Side by side, medians of --repeats runs:

* a plain Python loop over the points (no Dask, no store): the comparator;
* ``posicast.sweep(..., client="serial")`` with a Zarr store (the same batching and persistence);
* ``posicast.sweep(..., client=<2-worker LocalCluster>)`` with a Zarr store; the cluster is started
  once, before the runs (its start-up is reported separately: a one-off cost per session).

The per-task overhead is measured two ways: from the sweep's own accounting
(``(wall x workers - time in the function) / tasks``) and directly, as Dask's round trip of an
empty task on the same cluster.  The load average is printed next to the numbers: the machine
is shared.
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _harness import machine_info, md_table, print_machine_info  # noqa: E402

from posicast.sweeps import local_cluster, sweep  # noqa: E402
from posicast.sweeps.charts import seed000_loop, stability_point  # noqa: E402


def _noop(x: float) -> float:
    return x


def _waiting_point(gain: float, delay_error: float) -> float:
    """30 ms that do not use the CPU (a point waiting on I/O or a remote solver): Dask's own scaling."""
    time.sleep(0.03)
    return gain * delay_error


def _fixed_work(n: int = 40) -> float:
    """``n`` chart points in a row, no Dask in between: the machine's own 2-process scaling (the ceiling)."""
    t = time.perf_counter()
    for g in np.linspace(0.05, 1.5, n):
        stability_point(seed000_loop, gain=float(g), delay_error=0.1)
    return time.perf_counter() - t


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="100 points, one run each")
    args = ap.parse_args(argv)
    side, reps = (10, 1) if args.quick else (20, args.repeats)
    gains = list(np.linspace(0.05, 1.5, side))
    errors = list(np.linspace(-0.5, 0.5, side))
    params = {"gain": gains, "delay_error": errors}
    f = functools.partial(stability_point, seed000_loop)
    print(__doc__.splitlines()[0])
    print_machine_info(machine_info(("numpy", "scipy", "posicast", "distributed", "zarr")))
    print(f"  load avg : {' '.join(f'{x:.2f}' for x in os.getloadavg())} (before)")
    n = len(gains) * len(errors)

    from distributed import Client

    t0 = time.perf_counter()
    cluster = local_cluster(2)  # what sweep(workers=2) starts
    client = Client(cluster)
    client.run(lambda: __import__("posicast.sweeps.charts"))  # workers import posicast once, like any session
    startup = time.perf_counter() - t0
    # warm-up (untimed): this process and each worker evaluate a few points first
    warm = {"gain": gains[:4], "delay_error": errors[:2]}
    sweep(f, warm, client="serial", progress=False)
    sweep(f, warm, client=client, batch_size=1, progress=False)

    # Dask's own per-task round trip: 200 empty tasks, one at a time
    rt = []
    for i in range(200):
        t = time.perf_counter()
        client.submit(_noop, float(i), pure=False).result()
        rt.append(time.perf_counter() - t)
    roundtrip = statistics.median(rt)

    # the machine's ceiling: the same fixed work on one worker alone, then on both at once
    names = list(client.scheduler_info()["workers"])
    client.submit(_fixed_work, 4, pure=False, workers=[names[0]]).result()
    alone = statistics.median(client.submit(_fixed_work, pure=False, workers=[names[0]]).result() for _ in range(3))
    both = statistics.median(max(f.result() for f in [client.submit(_fixed_work, pure=False, workers=[w])
                                                      for w in names]) for _ in range(3))
    ceiling = 2 * alone / both

    plain, serial, parallel, overhead_serial, overhead_par, batches = [], [], [], [], [], 0
    reference = None
    for _ in range(reps):
        t = time.perf_counter()
        ref = [[f(gain=g, delay_error=e)["stable"] for e in errors] for g in gains]
        plain.append(time.perf_counter() - t)
        with tempfile.TemporaryDirectory() as tmp:
            r = sweep(f, params, client="serial", store=Path(tmp) / "s.zarr", progress=False)
            serial.append(r.timing.wall)
            overhead_serial.append(r.timing.overhead_per_task)
            r2 = sweep(f, params, client=client, store=Path(tmp) / "p.zarr", progress=False)
            parallel.append(r2.timing.wall)
            overhead_par.append(r2.timing.overhead_per_task)
            batches = r2.timing.tasks
            assert r2.same_as(r) and r["stable"].tolist() == ref, "parallel, serial and plain results differ"
            reference = r
    # the framework alone: the same sweep of 30 ms points that wait instead of computing
    with tempfile.TemporaryDirectory() as tmp:
        ws = sweep(_waiting_point, params, client="serial", store=Path(tmp) / "ws.zarr", progress=False).timing
        wp = sweep(_waiting_point, params, client=client, store=Path(tmp) / "wp.zarr", progress=False).timing
    client.close()
    cluster.close()

    mp, ms, mpar = (statistics.median(x) for x in (plain, serial, parallel))
    rows = [
        ["plain loop (comparator)", f"{mp:.2f} s", f"{mp / n * 1e3:.1f} ms", "-", "1.00"],
        ["sweep, serial, Zarr store", f"{ms:.2f} s", f"{ms / n * 1e3:.1f} ms",
         f"{statistics.median(overhead_serial) * 1e3:.1f} ms", f"{mp / ms:.2f}"],
        ["sweep, 2 local workers, Zarr store", f"{mpar:.2f} s", f"{mpar / n * 1e3:.1f} ms",
         f"{statistics.median(overhead_par) * 1e3:.1f} ms", f"{mp / mpar:.2f}"],
    ]
    print(f"\n{n} points, {batches} tasks of {n // max(batches, 1)} points, median of {reps} run(s)")
    print(md_table(["run", "wall", "per point", "overhead per task", "speed-up vs plain loop"], rows))
    stable = int(np.count_nonzero(reference["stable"])) if reference is not None else 0
    print(f"\nspeed-up, 2 workers vs the serial sweep: {ms / mpar:.2f}x; vs the plain loop: {mp / mpar:.2f}x "
          "(target >= 1.7)")
    print(f"the framework alone ({n} points of 30 ms that wait, not compute): serial {ws.wall:.2f} s, 2 workers "
          f"{wp.wall:.2f} s: {ws.wall / wp.wall:.2f}x; overhead per task {ws.overhead_per_task * 1e3:.1f} ms serial, "
          f"{wp.overhead_per_task * 1e3:.1f} ms on the cluster ({wp.tasks} tasks)")
    print(f"the machine's 2-process ceiling now: {ceiling:.2f}x (the same 40 points on one worker alone, "
          f"{alone:.2f} s, and on both at once, {both:.2f} s each)")
    print(f"Dask round trip of an empty task: {roundtrip * 1e3:.2f} ms (median of 200); LocalCluster start-up "
          f"with the workers' imports: {startup:.2f} s (once per session)")
    print(f"chart: {stable} of {n} points certified stable; all three runs give the same verdicts")
    print(f"  load avg : {' '.join(f'{x:.2f}' for x in os.getloadavg())} (after)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
