"""Benchmark: certified verdicts and root searches on small loops (issue #15, wave 5).

Three workloads of the demo, timed in CPU seconds (``time.process_time``, one BLAS thread):

* ``sweep``: the 75 certified ``stability`` verdicts of seed 000's inverse-ZV loop over
  gain x delay error (the demo's sweep section, ``posicast.sweeps.charts.seed000_loop``);
* ``crane``: ``Loop.stability`` of the seed 001 crane loops with ZV and DeZV shapers, in the
  control-action and inverse-shaper structures;
* ``roots``: ``posicast.roots`` on the issue #3 test set of the demo's "Certified root finding"
  section (shaper numerators, two-mode ZV.ZV, the inverse ZV and DZV loops) in [-20, 5] x [0, 500].

The comparator is the previous posicast: the ``src`` folder of commit ``PREVIOUS_COMMIT``
(before issue #15's wave 5; extracted with ``git archive``, or ``--previous SRC``).  Both run
here, in alternating fresh processes, and the ratio is of their medians.  Where git or that
commit is not there, the figures recorded before this work (``RECORDED``, on an AMD EPYC; another
machine gives other absolute times) stand in.  Goal: ratio >= 2.  Each run also checks that
the verdicts and root counts are the same as the comparator's.

Usage: python benchmarks/bench_certified.py [--quick] [--rounds N] [--previous SRC]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

from _harness import machine_info, md_table, previous_src, print_machine_info

# CPU seconds at commit 0f959c0 (before issue #15 wave 5), medians of 3 alternating rounds,
# AMD EPYC, 2 logical cores shared with other agents, load average 3.8 (2026-11-25 03:54 UTC)
RECORDED = {"sweep": 1.085, "crane": 0.153, "roots": 0.106}
PREVIOUS_COMMIT = "0f959c0"
GOAL = 2.0


def _work() -> dict:
    """The three workloads, built (not timed)."""
    import numpy as np

    import posicast as pc
    from posicast.cases import ALL
    from posicast.cases import loop as case_loop
    from posicast.modes import Mode
    from posicast.shapers import design
    from posicast.sweeps.charts import seed000_loop

    sweep = [seed000_loop(g, e).characteristic for g in np.linspace(0.1, 1.5, 15) for e in np.linspace(-0.6, 0.6, 5)]
    mode = ALL["gantry_crane"].mode
    crane = [case_loop("gantry_crane", arch, design(k, mode))
             for k in ("zv", "dezv") for arch in ("control_action", "inverse_shaper")]
    m0 = Mode(10.0, 0.03)  # seed 000's F mode, as in the demo
    G, F, C = ([1.0], [1.0, 1.0, 0.0]), ([1.0, 0.0], [1.0, 0.6, 100.0]), ([10.0, 10.0], [0.01, 1.0])
    zv = design("zv", m0)
    qs = [design(k, m0, **kw).num for k, kw in (("zv", {}), ("zvdk", {"k": 3}), ("dzv", {}), ("dezv", {}),
                                                 ("dtzv", {}), ("dczv", {}), ("dtazv", {}))]
    qs.append(zv.num * design("zv", Mode(27.0, 0.05)).num)
    qs += [pc.inverse_shaper(G=G, F=F, C=C, S=S).characteristic for S in (zv, design("dzv", m0))]
    return {"sweep": sweep, "crane": crane, "roots": qs}


def _worker(reps: int) -> dict:
    """Time each workload ``reps`` times in this process; CPU seconds and the answers."""
    import posicast as pc

    work = _work()
    run = {
        "sweep": lambda: [(s.stable, int(s.unstable_roots.size)) for s in (pc.stability(h) for h in work["sweep"])],
        "crane": lambda: [(s.stable, int(s.unstable_roots.size)) for s in (lp.stability() for lp in work["crane"])],
        "roots": lambda: [int(pc.roots(h, (-20.0, 5.0, 0.0, 500.0)).count) for h in work["roots"]],
    }
    pc.stability(work["sweep"][0]), work["crane"][0].stability(), pc.roots(work["roots"][0], (-1.0, 1.0, 0.0, 10.0))  # warm-up
    out = {}
    for name, fn in run.items():
        times, answer = [], None
        for _ in range(reps):
            t0 = time.process_time()
            answer = fn()
            times.append(time.process_time() - t0)
        out[name] = {"times": times, "answer": answer}
    return out


def _spawn(src: str | None, reps: int) -> dict:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    if src:
        env["PYTHONPATH"] = src
    res = subprocess.run([sys.executable, __file__, "--worker", str(reps)], env=env, check=True,
                         capture_output=True, text=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one round of one run each")
    ap.add_argument("--rounds", type=int, default=3, help="alternating rounds (default 3)")
    ap.add_argument("--previous", default=None, help="src folder of the previous posicast (the comparator)")
    ap.add_argument("--worker", type=int, default=0, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(_worker(args.worker)))
        return 0
    rounds, reps = (1, 1) if args.quick else (args.rounds, 2)
    if args.previous is None:
        args.previous = previous_src(PREVIOUS_COMMIT)
    print("# Benchmark: certified verdicts and root searches on small loops (issue #15, wave 5)")
    print_machine_info(machine_info())
    print(f"  load     : {os.getloadavg()[0]:.2f} (1 min) before")
    now: dict[str, list[float]] = {}
    before: dict[str, list[float]] = {}
    same = True
    for _ in range(rounds):
        if args.previous:
            prev = _spawn(args.previous, reps)
        cur = _spawn(None, reps)
        for name, r in cur.items():
            now.setdefault(name, []).extend(r["times"])
            if args.previous:
                before.setdefault(name, []).extend(prev[name]["times"])
                same &= prev[name]["answer"] == r["answer"]
    rows = []
    for name in now:
        t_now = statistics.median(now[name])
        t_before = statistics.median(before[name]) if args.previous else RECORDED[name]
        ratio = t_before / t_now
        rows.append([name, f"{t_now:.3f} s", f"{t_before:.3f} s" + ("" if args.previous else " (recorded, EPYC)"),
                     f"{ratio:.2f}x", f">= {GOAL:g}x: {'met' if ratio >= GOAL else 'MISSED'}"])
    print(f"  load     : {os.getloadavg()[0]:.2f} (1 min) after\n")
    print(md_table(["workload", "posicast (CPU, median)", "previous posicast", "speed-up", "goal"], rows))
    if args.previous:
        print(f"\nverdicts and root counts the same as the previous posicast's: {'yes' if same else 'NO'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
