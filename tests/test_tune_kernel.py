"""The compiled kernel of the H-infinity scan (`posicast.tune._kernels`) against the numpy path it replaces:
the same forbidden intervals, runs and branches bit for bit, on the seed 001 crane's grids and on columns
with NaN, infinite and vanishing entries; and the same designs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import posicast.tune.hinf as hinf
from posicast.cases import ALL
from posicast.shapers import design
from posicast.tune import tune_pd
from posicast.tune._kernels import fixed_numerator_runs, kernel

pytestmark = pytest.mark.skipif(kernel() is None, reason="numba is not installed: the numpy path is the only one")

CRANE = ALL["gantry_crane"]


def _numpy_path(monkeypatch):
    monkeypatch.setattr(hinf, "kernel", lambda name="runs": None)


def _same(a: hinf.Forbidden, b: hinf.Forbidden) -> None:
    for name in hinf.Forbidden._fields:
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape and x.dtype == y.dtype, name
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), name


@pytest.fixture(scope="module")
def grids():
    """The final columns of three designs: inverse ZV (a neutral loop, 18 000 grid and 1 024 limit columns),
    control-action ZV and inverse DeZV (no limit columns), with lines over their whole sweeps."""
    out = []
    for kind, arch, ms in [("zv", "inverse_shaper", 2.0), ("zv", "control_action", 1.2), ("dezv", "inverse_shaper", 2.0)]:
        r = tune_pd(CRANE.G, design(kind, CRANE.mode), arch, ms=ms, F=CRANE.F)
        cols = r.region.problem.columns
        xs = np.concatenate([r.region.x, -r.region.x[::7], [0.0, r.kd]])
        out.append((cols, xs))
    return out


def test_the_same_forbidden_intervals_on_real_grids(grids, monkeypatch):
    for cols, xs in grids:
        fast = hinf.forbidden(cols, xs, range(cols.n_constraints))
        with monkeypatch.context() as mp:
            _numpy_path(mp)
            slow = hinf.forbidden(dataclasses.replace(cols, cache={}), xs, range(cols.n_constraints))
        _same(fast, slow)
        assert fast.lo.shape[1] > 1  # runs found, not only the padding


def test_the_same_on_hostile_columns(grids, monkeypatch):
    """NaN and infinite values of ``1 + L``, ``b`` vanishing on grid columns (the linear case), huge and
    tiny magnitudes: where the numpy path gives no interval, a ray or everything, so does the kernel."""
    cols, xs = grids[0]
    rng = np.random.default_rng(3)
    n = cols.u.size
    for trial in range(4):
        u, a, b = cols.u.copy(), cols.a.copy(), cols.b.copy()
        k = rng.choice(cols.n_grid, size=40, replace=False)
        u[k[:8]] = np.nan
        u[k[8:12]] = np.inf
        a[k[12:16]] = complex(np.inf, 1.0)
        b[k[16:28]] = 0.0                       # A = 0 on grid columns: the linear case
        u[k[28:34]] *= 1e150
        b[k[34:40]] *= 1e-150
        if trial % 2:
            b[cols.n_grid:] = 0.0                # every limit column linear
        bad = dataclasses.replace(cols, u=u, a=a, b=b, cache={})
        with np.errstate(all="ignore"), monkeypatch.context() as mp:  # (inf * 0 in the numpy path's U)
            fast = hinf.forbidden(bad, xs, [0])
            _numpy_path(mp)
            slow = hinf.forbidden(dataclasses.replace(bad, cache={}), xs, [0])
        _same(fast, slow)
    assert n == cols.u.size


def test_the_compiled_kernel_is_the_python_function():
    """The function numba compiles, run as Python on a small problem, gives the compiled numbers."""
    rng = np.random.default_rng(5)
    n, m = 300, 4
    args = [rng.normal(size=m) * 10] + [rng.normal(size=n) for _ in range(6)]
    A = args[5] ** 2 + args[6] ** 2
    A[::37] = 0.0
    c = np.abs(rng.normal(size=n))
    db = np.abs(np.diff(args[5] + 1j * args[6]))
    with np.errstate(all="ignore"):  # numpy scalars warn where the compiled code follows IEEE silently
        py = fixed_numerator_runs(*args, A, c, db, 0.3, n - 20)
    jit = kernel()(*args, A, c, db, 0.3, n - 20)
    assert len(py) == len(jit) == 12
    for p, q in zip(py[:-1], jit[:-1]):
        assert np.array_equal(p, q)
    assert py[-1] == jit[-1] == 9
    assert py[0].size > 10  # runs of several columns: the join test is exercised


def test_the_same_inverse_zv_design_with_either_path(monkeypatch):
    S = design("zv", CRANE.mode)
    fast = tune_pd(CRANE.G, S, "inverse_shaper", ms=2.0, F=CRANE.F)
    _numpy_path(monkeypatch)
    slow = tune_pd(CRANE.G, S, "inverse_shaper", ms=2.0, F=CRANE.F)
    assert (fast.kp, fast.kd, fast.ms) == (slow.kp, slow.kd, slow.ms)
    for p, q in zip(fast.region.lines, slow.region.lines):
        assert np.array_equal(p.hinf, q.hinf) and np.array_equal(p.breaks, q.breaks)


def test_complement_names_the_first_interval_that_reaches_the_running_maximum():
    """The gaps' upper-end branches (one vectorised running argmax) against the definition, argmax of the
    sorted upper ends up to each gap, on intervals with tied ends, infinite ends and padding."""
    rng = np.random.default_rng(11)
    m, K = 6, 400
    lo = np.round(rng.uniform(-400, 400, (m, K)))        # integers: many ties
    hi = lo + np.round(rng.uniform(0, 3, (m, K)))
    lo[:, ::97] = -np.inf                                # rays from -inf (finite upper ends)
    hi[lo > 395] = np.inf                                # and rays to +inf, at the top
    lo[:, -30:], hi[:, -30:] = np.inf, -np.inf           # padding entries
    cols = rng.integers(0, 10_000, (m, K))
    f = hinf.Forbidden(lo, hi, cols, cols + 1, np.zeros((m, K), int), np.zeros((m, K), int), np.ones((m, K), int))
    out = hinf.complement(f)
    for i, (iv, ends) in enumerate(out):
        order = np.argsort(lo[i], kind="stable")
        li, hs = lo[i][order], hi[i][order]
        n = int(np.searchsorted(li, np.inf))
        li, hs, order = li[:n], hs[:n], order[:n]
        ci = np.maximum.accumulate(hs)
        expected = []
        for j in np.flatnonzero(li[1:] > ci[:-1]):
            k = int(np.argmax(hs[: j + 1]))
            expected.append(hinf.Branch(int(cols[i, order[k]] + 1), 0, 1) if np.isfinite(hs[k]) else None)
        got = [e[0] for e, (a, b) in zip(ends, iv) if np.isfinite(a)]
        assert len(expected) > 5 and got[: len(expected)] == expected


def test_meets_window_compiled_is_the_numpy_answer(grids):
    """The probes' question (is some ky in the window admissible at every column?) on the real grids, on
    windows from narrow to the whole range, and on columns with NaN, infinite and vanishing entries."""
    compiled = kernel("meets")
    rng = np.random.default_rng(9)
    answers = []
    for cols, xs in grids:
        cases = [cols]
        u, b = cols.u.copy(), cols.b.copy()
        k = rng.choice(cols.n_grid, size=30, replace=False)
        u[k[:6]], u[k[6:10]], b[k[10:30]] = np.nan, np.inf, 0.0
        cases.append(dataclasses.replace(cols, u=u, b=b, cache={}))
        for c in cases:
            fixed = hinf._fixed_numerator(c, 0)
            assert fixed is not None
            parts = hinf._parts(c) + hinf._b_parts(c)
            for lo, hi in [(-np.inf, np.inf), (0.0, np.inf), (-2.0, 2.0), (0.0, 1e-3), (5.0, 5.0), (10.0, -10.0)]:
                with np.errstate(all="ignore"):
                    ref = hinf.meets(hinf.forbidden(c, xs, [0], hull=False), lo, hi)
                got = compiled(np.ascontiguousarray(xs), *parts, fixed[0][None, :], fixed[1][None, :], lo, hi)
                assert np.array_equal(ref, got), (lo, hi)
                answers.append(got)
    both = np.concatenate(answers)
    assert both.any() and not both.all()  # windows with admissible gains and windows without


def test_kernels_compile_without_a_writable_cache(monkeypatch):
    """Where numba finds no place to cache (a read-only install without a user cache directory), it raises
    RuntimeError at decoration; the kernels are then compiled in the process, with the same numbers."""
    import numba

    import posicast.tune._kernels as K

    real, cached = numba.njit, K.kernel("runs")

    def no_cache(*args, **kwargs):
        if kwargs.get("cache"):
            raise RuntimeError("cannot cache function: no locator available")
        return real(*args, **kwargs)

    monkeypatch.setattr(numba, "njit", no_cache)
    monkeypatch.setattr(K, "_KERNELS", {})
    runs = K.kernel("runs")
    assert runs is not None and K.kernel("meets") is not None
    x = np.array([0.5, -1.0])
    w = np.linspace(0.0, 3.0, 50)
    args = (x, np.cos(w), np.sin(w), w, -w, np.cos(2 * w), np.sin(2 * w), np.ones(50), np.full(50, 0.1),
            np.abs(np.diff(np.exp(2j * w))), 0.2, 45)
    assert runs is not cached
    out = runs(*args)
    assert out[0].size > 0
    for p, q in zip(out, cached(*args)):
        assert np.array_equal(p, q)
