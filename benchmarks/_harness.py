"""Shared helpers for the benchmark scripts in this folder (not part of the library).

Machine description, median timing with a time budget and a per-run time limit,
root-set comparison, and a high-precision (mpmath) referee for roots.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import os
import platform
import signal
import statistics
import sys
import time
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any, Callable

import numpy as np

# ----------------------------------------------------------------------------- machine


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def version_of(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def machine_info(packages: tuple[str, ...] = ("numpy", "scipy", "posicast")) -> dict[str, str]:
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        usable = os.cpu_count() or 0
    info = {
        "date": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "cpu": cpu_model(),
        "cores": f"{os.cpu_count()} logical, {usable} usable by this process",
        "os": platform.platform(),
        "python": platform.python_version(),
    }
    for p in packages:
        info[p] = version_of(p)
    return info


def print_machine_info(info: dict[str, str]) -> None:
    width = max(len(k) for k in info)
    for k, v in info.items():
        print(f"  {k:<{width}} : {v}")


# ----------------------------------------------------------------------------- timing


class RunTimeout(Exception):
    """One run went past its time limit."""


def previous_src(ref: str) -> str | None:
    """The ``src`` folder of this repository at commit ``ref``, extracted once (``git archive``) into
    ``.venv/.bench-previous/<ref>``: the "previous posicast" a benchmark runs beside this one, in the same
    session on the same machine.  None when git or the commit is not there (e.g. a shallow clone)."""
    import io
    import pathlib
    import subprocess
    import tarfile

    root = pathlib.Path(__file__).resolve().parent.parent
    dest = root / ".venv" / ".bench-previous" / ref
    if (dest / "src" / "posicast" / "__init__.py").is_file():
        return str(dest / "src")
    try:
        tar = subprocess.run(["git", "-C", str(root), "archive", "--format=tar", ref, "src"], check=True,
                             capture_output=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    dest.mkdir(parents=True, exist_ok=True)
    with tarfile.open(fileobj=io.BytesIO(tar)) as tf:
        tf.extractall(dest, filter="data")
    return str(dest / "src")


@contextlib.contextmanager
def time_limit(seconds: float | None):
    """Raise :class:`RunTimeout` in the main thread after ``seconds`` (Unix only)."""
    if not seconds or not hasattr(signal, "SIGALRM"):
        yield
        return

    def _raise(signum, frame):  # noqa: ARG001
        raise RunTimeout(f"run exceeded {seconds:g} s")

    old = signal.signal(signal.SIGALRM, _raise)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


@dataclass
class Timing:
    times: list[float] = field(default_factory=list)
    result: Any = None
    error: str | None = None

    @property
    def median(self) -> float:
        return statistics.median(self.times) if self.times else float("nan")

    @property
    def runs(self) -> int:
        return len(self.times)


def timed(
    fn: Callable[[], Any],
    repeats: int,
    budget: float = float("inf"),
    run_limit: float | None = None,
) -> Timing:
    """Call ``fn`` up to ``repeats`` times; stop early once ``budget`` seconds are spent.

    At least one run is always made.  The result of the last run is kept.  An
    exception (including a run past ``run_limit`` seconds) stops the series and
    is recorded in ``error``.
    """
    out = Timing()
    spent = 0.0
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        try:
            with time_limit(run_limit):
                res = fn()
        except Exception as exc:  # the comparators may fail in many ways
            out.error = f"{type(exc).__name__}: {exc}"
            break
        dt = time.perf_counter() - t0
        out.times.append(dt)
        out.result = res
        spent += dt
        if spent >= budget:
            break
    return out


# ----------------------------------------------------------------------------- comparison


def in_region(z: np.ndarray, region, pad: float = 0.0) -> np.ndarray:
    a, b, c, d = region
    return (z.real >= a - pad) & (z.real <= b + pad) & (z.imag >= c - pad) & (z.imag <= d + pad)


def boundary_distance(z: np.ndarray, region) -> np.ndarray:
    """Distance of each point to the boundary of the rectangle (0 on it, >0 off it)."""
    a, b, c, d = region
    return np.minimum.reduce([np.abs(z.real - a), np.abs(z.real - b), np.abs(z.imag - c), np.abs(z.imag - d)])


@dataclass
class Comparison:
    n_a: int
    n_b: int
    max_dist: float  # over matched roots, both directions
    unmatched_a: np.ndarray  # roots of A with nothing of B within the capture radius
    unmatched_b: np.ndarray
    boundary_ignored: int  # unmatched roots within boundary_tol of the region boundary

    @property
    def agree(self) -> bool:
        return self.unmatched_a.size == 0 and self.unmatched_b.size == 0 and self.max_dist <= 1e-8

    def summary(self) -> str:
        parts = []
        if self.unmatched_a.size:
            parts.append(f"{self.unmatched_a.size} only in A: {fmt_roots(self.unmatched_a)}")
        if self.unmatched_b.size:
            parts.append(f"{self.unmatched_b.size} only in B: {fmt_roots(self.unmatched_b)}")
        if self.boundary_ignored:
            parts.append(f"{self.boundary_ignored} boundary root(s) ignored")
        if self.n_a != self.n_b:
            parts.append(f"counts differ ({self.n_a} vs {self.n_b})")
        return "; ".join(parts) or "-"


def fmt_roots(z: np.ndarray, limit: int = 4) -> str:
    s = ", ".join(f"{complex(x).real:.6g}{complex(x).imag:+.6g}j" for x in z[:limit])
    return s + (", ..." if z.size > limit else "")


def compare_roots(
    a,
    b,
    region,
    *,
    boundary_tol: float = 1e-6,
    capture: float = 0.25,
) -> Comparison:
    """Compare two root lists (each may repeat roots by multiplicity) inside ``region``.

    Each root of one set is matched to the nearest root of the other.  Distances
    below ``capture`` count as the same root (its inaccuracy goes into
    ``max_dist``); farther ones are unmatched.  Both sets are first restricted to
    ``region`` grown by ``boundary_tol``; an unmatched root within ``boundary_tol``
    of the boundary (included by one tool, not by the other) is ignored and counted
    in ``boundary_ignored``.  ``n_a``/``n_b`` count the roots (with repetition)
    after that restriction.
    """
    a = np.asarray(a, dtype=complex).ravel()
    b = np.asarray(b, dtype=complex).ravel()
    a = a[in_region(a, region, boundary_tol)]
    b = b[in_region(b, region, boundary_tol)]
    max_dist = 0.0
    unmatched = []
    ignored = 0
    for x, y in ((a, b), (b, a)):
        if x.size == 0:
            unmatched.append(np.zeros(0, complex))
            continue
        d = np.min(np.abs(x[:, None] - y[None, :]), axis=1) if y.size else np.full(x.size, np.inf)
        ok = d <= capture
        if ok.any():
            max_dist = max(max_dist, float(d[ok].max()))
        miss = x[~ok]
        near = boundary_distance(miss, region) <= boundary_tol
        ignored += int(near.sum())
        unmatched.append(miss[~near])
    return Comparison(a.size, b.size, max_dist, unmatched[0], unmatched[1], ignored)


def cluster(z, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Group points closer than ``radius`` (single linkage); return centroids and sizes."""
    z = np.asarray(z, dtype=complex).ravel()
    labels = -np.ones(z.size, dtype=int)
    k = 0
    for i in range(z.size):
        if labels[i] >= 0:
            continue
        labels[i] = k
        stack = [i]
        while stack:
            j = stack.pop()
            near = np.where((labels < 0) & (np.abs(z - z[j]) < radius))[0]
            labels[near] = k
            stack.extend(near.tolist())
        k += 1
    centers = np.array([z[labels == i].mean() for i in range(k)], dtype=complex)
    sizes = np.array([(labels == i).sum() for i in range(k)], dtype=int)
    return centers, sizes


# ----------------------------------------------------------------------------- mpmath referee


def mp_refine(coeffs, delays, starts, mults, dps: int = 40, iters: int = 80) -> np.ndarray:
    """Polish roots of ``h(s) = sum_i sum_k coeffs[i, k] s**k exp(-s delays[i])`` in ``dps`` digits.

    A root of multiplicity ``m`` is refined as the simple root of the derivative
    ``h^(m-1)`` (Newton on it).  For an exact multiple root that is the root
    itself; for a tight cluster of m roots (what float64 coefficients make of a
    multiple root) it is the cluster's centroid to within the square of the
    cluster size over the distance to other roots -- the well-conditioned quantity.
    The float64 coefficients and delays are taken as exact.  Returns complex128;
    a start whose iteration does not settle within 0.5 of where it began comes
    back as nan.
    """
    import mpmath as mp

    coeffs = np.asarray(coeffs, float)
    delays = np.asarray(delays, float)
    out = np.full(len(starts), np.nan + 0j)
    with mp.workdps(dps):
        C = [[mp.mpf(float(c)) for c in row] for row in coeffs]
        T = [mp.mpf(float(t)) for t in delays]

        def deriv(s, j):
            """h^(j)(s) = sum_i e^{-s tau_i} sum_l binom(j, l) p_i^(l)(s) (-tau_i)^(j-l)."""
            total = mp.mpc(0)
            for row, tau in zip(C, T):
                acc = mp.mpc(0)
                for ll in range(0, min(j, len(row) - 1) + 1):
                    # p^(l)(s) = sum_k c_k k!/(k-l)! s^(k-l)
                    pl = mp.mpc(0)
                    for k in range(len(row) - 1, ll - 1, -1):
                        pl = pl * s + row[k] * mp.ff(k, ll)
                    acc += mp.binomial(j, ll) * pl * (-tau) ** (j - ll)
                total += acc * mp.exp(-s * tau)
            return total

        tol = mp.mpf(10) ** (-(dps - 8))
        for n, (s0, m) in enumerate(zip(starts, mults)):
            m = max(1, int(m))
            start = mp.mpc(complex(s0))
            s = start
            for _ in range(iters):
                g = deriv(s, m - 1)
                if g == 0:
                    break
                dg = deriv(s, m)
                if dg == 0:
                    s = None
                    break
                step = g / dg
                s -= step
                if abs(step) <= tol * max(1, abs(s)):
                    break
            else:
                s = None
            if s is not None and abs(s - start) < 0.5:
                out[n] = complex(s)
    return out


def centroid_error(z, ref, capture: float = 0.25) -> float:
    """Accuracy of root list ``z`` against referee roots ``ref``.

    Each point of ``z`` goes to its nearest referee root (points farther than
    ``capture`` from all are left out: they are reported as unmatched
    elsewhere); the result is the largest distance between a referee root and
    the mean of the points assigned to it.  For simple roots this is the plain
    nearest-root distance; for a multiple root it judges the tool's estimate
    of the cluster (repeated copies or m nearby points alike).
    """
    z = np.asarray(z, dtype=complex).ravel()
    ref = np.asarray(ref, dtype=complex).ravel()
    ref = ref[np.isfinite(ref)]
    if z.size == 0 or ref.size == 0:
        return float("nan")
    d = np.abs(z[:, None] - ref[None, :])
    j = np.argmin(d, axis=1)
    keep = d[np.arange(z.size), j] <= capture
    worst = 0.0
    for r in np.unique(j[keep]):
        worst = max(worst, float(abs(z[keep][j[keep] == r].mean() - ref[r])))
    return worst


def fmt_time(t: float) -> str:
    if not np.isfinite(t):
        return "-"
    if t < 1.0:
        return f"{t * 1e3:.3g} ms"
    return f"{t:.3g} s"


def fmt_sci(x: float) -> str:
    return "-" if not np.isfinite(x) else f"{x:.1e}"


def md_table(header: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(str(h)), *(len(str(r[i])) for r in rows)) for i, h in enumerate(header)]
    line = lambda cells: "| " + " | ".join(f"{str(c):<{w}}" for c, w in zip(cells, widths)) + " |"  # noqa: E731
    sep = "|" + "|".join("-" * (w + 2) for w in widths) + "|"
    return "\n".join([line(header), sep, *(line(r) for r in rows)])


def flush() -> None:
    sys.stdout.flush()
