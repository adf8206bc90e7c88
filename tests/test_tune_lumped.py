"""Tuning with a lumped shaper in the loop (issue #15 part A): the scan's thinned frequency columns.

A lumped shaper keeps ``|L|`` from decaying, so the grid refined for the largest
gains of the sweep is dense (``~ delta / tau``) up to its ceiling.  Each group of
scan lines uses only the columns its own gains need over the whole ``ky`` window
(``posicast.tune.frequency.thin_columns``).  The reference is the same design on
every column of the grid (thinning switched off).
"""

from __future__ import annotations

import numpy as np
import pytest

import posicast
from posicast.cases import ALL
from posicast.tune import design as design_module
from posicast.tune import frequency
from posicast.tune.design import _snap_up
from posicast.tune.frequency import thin_columns
from posicast.tune.regions import Region
from posicast.tune.scan import intersect

CRANE = ALL["gantry_crane"]


@pytest.fixture(scope="module")
def zv_designs():
    S = posicast.design("zv", CRANE.mode)
    thinned = posicast.tune_pd(CRANE.G, S, "control_action", ms=1.2, F=CRANE.F)
    saved = frequency._THIN_ABOVE
    frequency._THIN_ABOVE = 10**12  # every column, as before issue #15
    try:
        full = posicast.tune_pd(CRANE.G, S, "control_action", ms=1.2, F=CRANE.F)
    finally:
        frequency._THIN_ABOVE = saved
    return thinned, full


def test_thinned_columns_obey_the_grid_refinement_rule(zv_designs):
    """Every kept step that skips columns is shorter than the spacing the grid refinement accepts for the
    gains asked for (below one unit of it, summed along the step); the first and last grid columns and all limit columns are kept; far fewer columns remain."""
    cols = zv_designs[0].region.sweep.problem.columns  # the whole sweep's grid, valid for its largest gains
    X, Y = 2.0, 1e6
    sub, sel = thin_columns(cols, X, Y)
    assert sel is not None and sub.n_grid < 0.7 * cols.n_grid
    assert sel[0] == 0 and sel[-1] == cols.n_grid - 1
    assert sub.u.size - sub.n_grid == cols.u.size - cols.n_grid  # the limit columns
    h = cols.data.allowed_spacing(X, Y)
    units = np.concatenate([[0.0], np.cumsum(np.diff(cols.omega[: cols.n_grid]) / np.fmin(h[:-1], h[1:]))])
    skipping = np.diff(sel) > 1
    assert skipping.any() and np.all(np.diff(units[sel])[skipping] < 1.0)
    np.testing.assert_array_equal(sub.u[: sub.n_grid], cols.u[sel])
    # a small grid (a distributed shaper's) is used whole
    dezv = posicast.tune_pd(CRANE.G, posicast.design("dezv", CRANE.mode), "control_action", ms=1.2, F=CRANE.F)
    small = dezv.region.problem.columns
    assert thin_columns(small, X, Y) == (small, None)


def test_lumped_design_is_the_full_grid_design(zv_designs):
    """Same optimum and same H-infinity intervals as the scan on every column (ZV in the control action,
    Ms = 1.2; the optimum 8.6139 / 1.4681 is the full-grid design's)."""
    thinned, full = zv_designs
    assert thinned.kp == pytest.approx(full.kp, rel=1e-9) and thinned.kd == pytest.approx(full.kd, rel=1e-9)
    assert thinned.kp == pytest.approx(8.6139, rel=1e-4) and thinned.kd == pytest.approx(1.4681, rel=1e-4)
    assert thinned.ms == pytest.approx(1.2, abs=1e-6) and thinned.stable
    a, b = thinned.region, full.region
    np.testing.assert_array_equal(a.x, b.x)
    for la, lb in zip(a.lines, b.lines):
        assert la.hinf.shape == lb.hinf.shape
        np.testing.assert_allclose(la.hinf, lb.hinf, rtol=1e-6, atol=1e-9)


# ---------------------------------------------------------------------------- issue #15: pass 2 in a window
def test_pass2_window_gives_the_whole_range_design(zv_designs):
    """For a large (lumped-shaper) grid the final scan refines a ky window around the optimum's component:
    the optimum is the whole-range scan's (8.6139 / 1.4681), the window is stated (Kp in [-20, 20]: twice the
    sweep's 7.56, rounded up), and inside it every line's H-infinity intervals are the whole-range scan's."""
    windowed = zv_designs[0]
    saved = design_module.WINDOW_ABOVE
    design_module.WINDOW_ABOVE = 10**12  # the whole search range, as before
    try:
        whole = posicast.tune_pd(CRANE.G, posicast.design("zv", CRANE.mode), "control_action", ms=1.2, F=CRANE.F)
    finally:
        design_module.WINDOW_ABOVE = saved
    assert windowed.kp == pytest.approx(whole.kp, rel=1e-9) and windowed.kd == pytest.approx(whole.kd, rel=1e-9)
    a, b = windowed.region, whole.region
    assert a.windowed and not b.windowed and b.sweep is None
    assert a.y_range == (-20.0, 20.0) and a.search_range == b.y_range
    assert isinstance(a.sweep, Region) and a.sweep.x.size == 67 and a.sweep.y_range == b.y_range
    assert "kp in [-20, 20]" in windowed.summary() and "window" in repr(a)
    np.testing.assert_array_equal(a.x, b.x)
    for la, lb in zip(a.lines, b.lines):
        inside = intersect(lb.hinf, np.array([a.y_range]))
        assert la.hinf.shape == inside.shape
        np.testing.assert_allclose(la.hinf, inside, rtol=1e-6, atol=1e-9)
    assert a.extent() == pytest.approx(b.extent(), rel=1e-9)


def test_window_snaps_to_one_two_five():
    assert [_snap_up(v) for v in (15.12, 1.028, 2.0, 0.0042, 7e5)] == pytest.approx([20.0, 2.0, 2.0, 0.005, 1e6])


def test_readme_window_example():
    """README "Window of the final scan" runs as printed (the block is a doctest)."""
    import doctest
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    section = text[text.index("*Window of the final scan"):]
    start = section.index("```python") + len("```python")
    block = "\n".join(line.strip() for line in section[start: section.index("```", start)].splitlines())
    test = doctest.DocTestParser().get_doctest(block, {}, "README window", "README.md", 0)
    runner = doctest.DocTestRunner()
    runner.run(test)
    assert runner.failures == 0 and runner.tries >= 5


def test_dead_time_with_a_derivative_filter_gives_a_verified_design():
    """A fresh line at the best line's kd that finds no stable admissible piece used to reach the controller
    as kp = -inf ("num must be finite"; found through posicast serve's loop tab). The design now comes from
    the next best lines and is checked here independently: Ms on a dense grid and the certified spectrum."""
    G = posicast.TransferFunction.from_poly([1.0], [1.0, 1.0, 0.0], delay=0.02)
    S = posicast.design("zvd", posicast.Mode.from_hz(2.0, 0.05))
    F = posicast.TransferFunction.from_poly([157.9137], [1.0, 1.256637, 157.9137])
    r = posicast.tune_pd(G, S, "control_action", ms=2.0, F=F, derivative_filter=0.01)
    assert r.stable and np.isfinite([r.kp, r.kd]).all() and r.kp > 0 and r.kd > 0
    assert "not the exact optimum" in r.reason  # it says it is the next lines' best, not the optimum
    w = np.linspace(1e-3, 200.0, 200_001)
    L = r.controller(1j * w) * G(1j * w) * S(1j * w)
    assert np.max(1.0 / np.abs(1.0 + L)) <= 2.0 * (1 + 1e-6)
    assert posicast.stability(posicast.control_action(G=G, C=r.controller, S=S)).stable
    # the design is close to the one without the filter (kp 5.15, kd 2.88), not a degenerate corner
    free = posicast.tune_pd(G, S, "control_action", ms=2.0, F=F)
    assert 0.8 * free.kp < r.kp <= free.kp * 1.05


def test_lines_forbidden_on_the_probe_are_forbidden_on_the_whole_grid(monkeypatch):
    """The sweep's lines that a probe of ~1000 columns shows forbidden over the whole window (issue #15, wave 7)
    get the :class:`LineData` the full scan gives them: no admissible interval, the same D-decomposition breaks.
    Most of a lumped ZVD design's sweep lines at large ``kp`` are such lines."""
    from posicast.tune import scan

    real_scan, real_probe = scan.scan_lines, scan._forbidden_on_probe
    blocked_by_probe = []
    compared = []

    def probe(problem, xs):
        out = real_probe(problem, xs)
        blocked_by_probe.append(int(out.sum()))
        return out

    def both(problem, xs):  # the whole sweep with and without the probe, on the grid it was made for
        with_probe = real_scan(problem, xs)
        if not compared and xs.size == 67:
            monkeypatch.setattr(scan, "_forbidden_on_probe", lambda p, x: np.zeros(x.size, dtype=bool))
            compared.append((with_probe, real_scan(problem, xs)))
            monkeypatch.setattr(scan, "_forbidden_on_probe", probe)
        return with_probe

    monkeypatch.setattr(scan, "_forbidden_on_probe", probe)
    monkeypatch.setattr(design_module, "scan_lines", both)
    r = posicast.tune_pd(CRANE.G, posicast.design("zvd", CRANE.mode), "control_action", ms=1.2, F=CRANE.F)
    assert r.region.sweep is not None  # the design left the outer lines out: the whole sweep is scanned here
    probed, full = compared[0]
    assert blocked_by_probe[0] >= 4 and sum(1 for ln in probed if not ln.hinf.size) >= 40
    assert len(probed) == len(full) == 67
    for a, b in zip(probed, full):
        assert a.x == b.x and np.array_equal(a.hinf, b.hinf) and len(a.per_constraint) == len(b.per_constraint)
        assert all(np.array_equal(p, q) for p, q in zip(a.per_constraint, b.per_constraint))
        assert np.array_equal(a.breaks, b.breaks) and np.array_equal(a.break_kind, b.break_kind)
        assert np.array_equal(a.break_err, b.break_err) and a.ends == b.ends  # (comp: set later, by the cells)


@pytest.mark.parametrize("window, fewer", [((-10.0, 10.0), True), ((-20.0, 5.0), True), ((0.5, 3.0), True),
                                           ((-1e5, 1e5), False), ((-7e6, -6e6), False), ((1e8, 2e8), False)])
def test_windowed_crossings_give_the_breaks_of_all_crossings(zv_designs, window, fewer):
    """A line's D-decomposition breaks from the crossings near the window (issue #15, wave 7) are those from
    all of the curve's crossings: the window's own and the nearest beyond each end (or none beyond: then the
    band grows to the whole curve).  Near the design's window, a small part of the ~2000 crossings a line."""
    from dataclasses import replace

    from posicast.tune.boundaries import complex_breaks
    from posicast.tune.scan import _line_breaks

    problem = replace(zv_designs[0].region.sweep.problem, y_window=window)  # the whole sweep's grid
    xs = np.concatenate([np.linspace(-3.0, 3.0, 41), [0.0, 1e-6, 50.0, -400.0]])
    near = complex_breaks(problem.columns, problem.curve, xs, window=window)
    every = complex_breaks(problem.columns, problem.curve, xs)
    if fewer:
        assert sum(c.ky.size for c in near) < 0.2 * sum(c.ky.size for c in every)
    for x, a, b in zip(xs, near, every):
        for p, q in zip(_line_breaks(problem, x, a), _line_breaks(problem, x, b)):
            assert np.array_equal(p, q)


def test_join_paths_keep_their_crossings_beside_a_nan_end(zv_designs):
    """The joins' horizontal paths test only the curve segments that can cross inside them (issue #15,
    wave 7); a path with a NaN end crosses nothing, and the other paths of its block keep their crossings."""
    from posicast.tune.boundaries import _curve_hits

    problem = zv_designs[0].region.problem
    curve = problem.curve
    near = np.flatnonzero(np.isfinite(curve.x) & (np.abs(curve.x) < 50) & (np.abs(curve.y) < 50))
    i = near[near.size // 2]
    ys = np.linspace(curve.y[i] - 1.0, curve.y[i] + 1.0, 41)
    x0, x1 = np.full(41, curve.x[i] - 5.0), np.full(41, curve.x[i] + 5.0)
    alone = np.array([_curve_hits(problem.columns, curve, x0[k:k + 1], x1[k:k + 1], ys[k:k + 1])[0]
                      for k in range(41)])
    assert alone.sum() == 41
    x0[3] = np.nan
    together = _curve_hits(problem.columns, curve, x0, x1, ys)
    assert not together[3] and np.array_equal(np.delete(together, 3), np.delete(alone, 3))


# ---------------------------------------------------------------------------- issue #15, wave 8: the inner sweep
@pytest.fixture(scope="module")
def staged_and_whole():
    """The crane's lumped designs with the inner sweep, and with every sweep line scanned (INNER_DECADES so
    large that every line is inner: the design as before wave 8)."""
    cases = [("control_action", 1.2, "zv"), ("control_action", 1.2, "zvd"), ("control_action", 1.2, "ei"),
             ("inverse_shaper", 2.0, "zv")]
    out = {}
    for arch, ms, kind in cases:
        S = posicast.design(kind, CRANE.mode)
        staged = posicast.tune_pd(CRANE.G, S, arch, ms=ms, F=CRANE.F)
        saved = design_module.INNER_DECADES
        design_module.INNER_DECADES = 10
        try:
            whole = posicast.tune_pd(CRANE.G, S, arch, ms=ms, F=CRANE.F)
        finally:
            design_module.INNER_DECADES = saved
        out[(arch, kind)] = staged, whole
    return out


def test_inner_sweep_gives_the_whole_sweep_optimum(staged_and_whole):
    """With a lumped shaper in the loop the design scans the 51 sweep lines within 10^2 natural scales of Kd;
    the 16 outer ones are shown to hold no admissible Kp >= 0 and left out (for the inverse ZV loop, three of
    them only in one cell shown unstable). The optimum is the one found with all 67 lines scanned, to the last
    digit, and the verification is the same."""
    for (arch, kind), (staged, whole) in staged_and_whole.items():
        assert (staged.kp, staged.kd, staged.ms, staged.stable) == (whole.kp, whole.kd, whole.ms, whole.stable)
        assert whole.region.skipped is None
        sk = staged.region.skipped
        assert sk is not None and sk.x.size == 16 and sk.floor == 0.0 and sk.n_sweep == 67
        assert (sk.scanned, sk.unstable) == ((4, 1) if arch == "inverse_shaper" else (0, 0))
        assert staged.region.sweep_lines == 67 and "the design scanned 51 of them" in staged.summary()
    assert ("4 scanned exactly on an extended grid: their admissible kp there in 1 cell shown unstable"
            in staged_and_whole[("inverse_shaper", "zv")][0].summary())


def test_skipped_lines_hold_no_admissible_gain_above_the_floor(staged_and_whole):
    """What the design showed, checked on the whole sweep's exact scan (scanned when asked for, with its own
    spectrum checks): none of the lines left out has a stable H-infinity-admissible Kp >= 0. In the control
    action none has an admissible one at all; in the inverse ZV loop the lines at Kd 689-2178 are admissible up
    to Kp ~ 8e4, in unstable cells only."""
    from posicast.tune.regions import pieces, segment_stable

    for (arch, kind), (staged, whole) in staged_and_whole.items():
        sweep = staged.region.sweep
        assert sweep.x.size == 67
        left_out = np.isin(sweep.x, staged.region.skipped.x)
        assert left_out.sum() == 16
        above = [(int(i), lo, hi, j) for i in np.flatnonzero(left_out) for lo, hi, j in pieces(sweep, int(i))
                 if hi > 0.0]
        if arch == "control_action":
            assert not above
        else:
            assert len(above) == 3 and all(hi > 6e4 for _, _, hi, _ in above)
            assert all(segment_stable(sweep, i, j, 0.5 * (max(lo, 0.0) + hi)) is False for i, lo, hi, j in above)


def test_inner_sweep_falls_back_when_the_outer_lines_may_matter(monkeypatch):
    """An inner sweep too narrow for the optimum (here |Kd| <= 10^-3 natural scales: the outer lines hold
    admissible Kp > 0) is not trusted: every sweep line is scanned, and the optimum is the design's."""
    S = posicast.design("zv", CRANE.mode)
    reference = posicast.tune_pd(CRANE.G, S, "control_action", ms=1.2, F=CRANE.F)
    monkeypatch.setattr(design_module, "INNER_DECADES", -3)
    narrow = posicast.tune_pd(CRANE.G, S, "control_action", ms=1.2, F=CRANE.F)
    assert narrow.region.skipped is None
    assert narrow.kp == pytest.approx(reference.kp, rel=1e-9) and narrow.kd == pytest.approx(reference.kd, rel=1e-9)


def test_lines_left_out_are_named_when_the_region_is_not_windowed(monkeypatch):
    """A small final grid (no ky window in pass 2: the region covers the whole search range and keeps no sweep)
    still names the sweep lines pass 1 left out (before, a region without a window dropped them). Here
    1/(s(s+1)) with a ZV shaper (2 Hz, 0.05), Ms 1.6: the same gains as with every sweep line scanned, to the
    last digit."""
    G = posicast.TransferFunction.from_poly([1.0], [1.0, 1.0, 0.0])
    S = posicast.design("zv", posicast.Mode.from_hz(2.0, 0.05))
    staged = posicast.tune_pd(G, S, "control_action", ms=1.6)
    assert not staged.region.windowed and staged.region.sweep is None
    sk = staged.region.skipped
    assert sk is not None and sk.x.size == 16 and sk.n_sweep == 67
    assert "the design scanned 51 of the 67 sweep lines in its first pass" in staged.summary()
    monkeypatch.setattr(design_module, "INNER_DECADES", 10)
    whole = posicast.tune_pd(G, S, "control_action", ms=1.6)
    assert whole.region.skipped is None and (whole.kp, whole.kd) == (staged.kp, staged.kd)


def test_valid_gains_bound_the_terms_past_the_grid_end(staged_and_whole):
    """x_valid and y_valid promise |kx a| and |ky b| below the settled level past the grid's end. With a
    lumped shaper |a| and |b| oscillate there (S has zeros near the axis every period), so the bound comes
    from the envelope omega^m sup|h|, not from the last column: checked on 400 001 exact frequencies over
    [end, 3 end] (the value at the last column alone overstated x_valid up to 74 times for these loops)."""
    from posicast.tune.scan import _settled

    for staged, _ in staged_and_whole.values():
        p = staged.region.problem
        cols = p.columns
        end = cols.omega[cols.n_grid - 1]
        v = cols.data.values(np.linspace(end, 3 * end, 400_001))
        settled = _settled(cols.data)
        assert p.x_valid * np.abs(v["a"]).max() <= settled * (1 + 1e-6)
        assert p.y_valid * np.abs(v["b"]).max() <= settled * (1 + 1e-6)


def test_inner_decides_only_when_the_best_component_ends_inside(staged_and_whole):
    """The inner lines decide pass 1 when their best piece reaches above Kp = 0 and its component ends inside
    them: on the whole sweep it does; cut through the component, or with no piece, it does not."""
    from posicast.tune.cells import interval_point
    from posicast.tune.design import _inner_decides
    from posicast.tune.regions import best_piece, component_lines, make_region

    sweep = staged_and_whole[("control_action", "zv")][0].region.sweep
    best = best_piece(sweep)
    assert best is not None and best[2] > 0 and _inner_decides(sweep, best)
    comp = component_lines(sweep, best[0], interval_point(best[1], best[2]))
    assert 0 < comp.min() and comp.max() < sweep.x.size - 1
    cut = make_region(sweep.problem, sweep.family, list(sweep.lines[: comp.max()]), sweep.cells, sweep.y_range)
    assert not _inner_decides(cut, best_piece(cut))
    assert not _inner_decides(sweep, None) and not _inner_decides(sweep, (best[0], best[1] - 1e9, -1.0))


def test_unstable_above_refuses_a_stable_piece_and_many_lines(staged_and_whole, monkeypatch):
    """The stability test of the outer lines shows nothing where a stable admissible piece lies above the floor
    (the crane's best ZV design, Kp 8.6 at Kd 1.47: the lines around it), shows the lines around it above the
    optimum, does not scan more than _UNSTABLE_LINES lines or check more than _UNSTABLE_CELLS cells, and leaves
    the grid it extends a copy of as it was; the inverse ZV loop's three lines are one unstable cell, one
    spectrum check counted in the design's ledger."""
    from posicast.tune.design import _UNSTABLE_LINES, _sweep_runs, _unstable_above

    best = staged_and_whole[("control_action", "zv")][0]
    p = best.region.problem
    xs = [np.array([0.9, 1.0, 1.1]) * best.kd]
    assert _unstable_above(p, best.family, xs, 1.0, (-1e3, 1e3), 0.0) is None
    assert _unstable_above(p, best.family, xs, 1.0, (-1e3, 1e3), best.kp * 1.01) is not None  # the optimum's top
    many = [np.linspace(1.0, 2.0, _UNSTABLE_LINES + 1) * best.kd]
    assert _unstable_above(p, best.family, many, 1.0, (-1e3, 1e3), best.kp * 1.01) is None
    inv = staged_and_whole[("inverse_shaper", "zv")][0]
    sk = inv.region.skipped.x
    outer = [sk[(sk > 600) & (sk < 3000)]]  # Kd 689, 1225, 2178: the lines admissible up to Kp ~ 8e4
    assert outer[0].size == 3
    sy = float(inv.region.sweep.y_range[1]) / 1e4
    q = inv.region.problem
    omega, n_grid, calls = q.fd.omega, q.fd.n_grid, q.ledger.calls
    assert _unstable_above(q, inv.family, outer, sy, inv.region.sweep.y_range, 0.0) == 1
    assert q.fd.omega is omega and q.fd.n_grid == n_grid == q.columns.n_grid and q.ledger.calls == calls + 1
    monkeypatch.setattr(design_module, "_UNSTABLE_CELLS", 0)  # more cells than checks allowed: not shown
    assert _unstable_above(q, inv.family, outer, sy, inv.region.sweep.y_range, 0.0) is None
    # joins run between neighbouring sweep lines only: the lines in runs of neighbours
    runs = _sweep_runs(np.arange(10.0), np.array([0, 1, 1, 0, 1, 0, 0, 1, 1, 1], dtype=bool))
    assert [r.tolist() for r in runs] == [[1.0, 2.0], [4.0], [7.0, 8.0, 9.0]]


def _overlaps_by_merge(A, B, ma, mb):
    """The joins' pairs by the merge over every segment of both lines (the code before wave 8)."""
    from posicast.tune.cells import interval_point

    out, ja, jb = [], 0, 0
    while ja < A.n_segments and jb < B.n_segments:
        alo, ahi = A.segment_bounds(ja)
        blo, bhi = B.segment_bounds(jb)
        lo, hi = max(alo, blo), min(ahi, bhi)
        if lo < hi and ma[ja] and mb[jb]:
            e_lo = max(A.error_at(lo) if not lo > alo else 0.0, B.error_at(lo) if not lo > blo else 0.0)
            e_hi = max(A.error_at(hi) if not hi < ahi else 0.0, B.error_at(hi) if not hi < bhi else 0.0)
            if lo + e_lo < hi - e_hi:
                out.append((ja, jb, interval_point(lo + e_lo, hi - e_hi)))
        if ahi <= bhi:
            ja += 1
        else:
            jb += 1
    return out


def test_joins_visit_only_wanted_segments_and_find_every_pair():
    """The joins find the overlapping wanted segments of two long lines by binary search (issue #15, wave 8):
    the same pairs, in the same order, with the same join points as the merge over every segment, on 2000
    random pairs of lines (shared breaks, uncertain breaks, few or many wanted segments, empty lines, short
    lines that are merged and long ones that are searched)."""
    from posicast.tune.cells import _overlaps, _overlaps_by_search
    from posicast.tune.scan import LineData

    rng = np.random.default_rng(8)

    def line(breaks):
        breaks = np.unique(breaks)
        return LineData(0.0, np.zeros((0, 2)), [], breaks, np.full(breaks.size, "c"), [],
                        np.zeros(breaks.size + 1, dtype=int), rng.exponential(0.02, breaks.size) * (rng.random(breaks.size) < 0.5))

    pairs = 0
    for _ in range(2000):
        size = 30 if rng.random() < 0.5 else 120
        a = rng.normal(size=rng.integers(0, size)).round(2)
        b = np.concatenate([rng.normal(size=rng.integers(0, size)).round(2), a[: rng.integers(0, a.size + 1)]])
        A, B = line(a), line(b)
        ma = rng.random(A.n_segments) < rng.random()
        mb = rng.random(B.n_segments) < rng.random()
        ref = _overlaps_by_merge(A, B, ma, mb)
        assert _overlaps(A, B, ma, mb) == ref and _overlaps_by_search(A, B, ma, mb) == ref
        pairs += len(ref)
    assert pairs > 2000


def test_meets_is_the_complement_test():
    """:func:`meets` (does an admissible gap of the forbidden intervals meet (lo, hi)?), vectorised over
    lines, against the gaps :func:`complement` lists, on 3000 random sets of intervals (empty entries,
    infinite ends, touching intervals, windows open below)."""
    from posicast.tune.hinf import Forbidden, complement, meets

    rng = np.random.default_rng(15)
    for _ in range(3000):
        m, k = int(rng.integers(1, 5)), int(rng.integers(1, 12))
        lo = rng.normal(size=(m, k))
        hi = lo + rng.exponential(size=(m, k))
        empty = rng.random((m, k)) < 0.3
        lo[empty], hi[empty] = np.inf, -np.inf
        r = rng.random((m, k))
        lo[r < 0.1] = -np.inf
        hi[(r > 0.9) & ~empty] = np.inf
        if k > 1 and rng.random() < 0.3:
            hi[:, 0] = lo[:, 1]  # touching: no gap between them
        z = np.zeros((m, k), dtype=int)
        f = Forbidden(lo, hi, z, z, np.zeros(k, dtype=int), np.zeros(k, dtype=int), np.zeros(k, dtype=int))
        a, b = np.sort(rng.normal(size=2) * 2)
        if rng.random() < 0.2:
            a = -np.inf
        ref = [bool(np.any(np.maximum(iv[:, 0], a) < np.minimum(iv[:, 1], b))) for iv, _ in complement(f)]
        assert meets(f, a, b).tolist() == ref


def test_a_grid_stopped_at_its_cap_is_said_in_the_reason(monkeypatch):
    """A frequency grid that reaches its size cap before every interval meets the refinement rule resolves the
    loop less finely than the scan assumes: the result's reason says so (it was silent before wave 8). Here
    1/(s(s+1)) e^{-0.02 s} with a ZVD shaper and every sweep line scanned reaches the 400 000-point cap; the
    inner sweep's grid (55 556 columns) does not, and its reason has no such note."""
    G = posicast.TransferFunction.from_poly([1.0], [1.0, 1.0, 0.0], delay=0.02)
    S = posicast.design("zvd", posicast.Mode.from_hz(2.0, 0.05))
    staged = posicast.tune_pd(G, S, "control_action", ms=2.0)
    assert staged.stable and not staged.region.problem.fd.capped and "cap" not in staged.reason
    monkeypatch.setattr(design_module, "INNER_DECADES", 10)
    whole = posicast.tune_pd(G, S, "control_action", ms=2.0)
    assert whole.region.problem.fd.capped and "400,000-point cap" in whole.reason
    assert whole.stable and whole.kp == pytest.approx(staged.kp, rel=1e-5)
