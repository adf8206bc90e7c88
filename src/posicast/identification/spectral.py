"""Output-only identification from a power spectrum: modes in a resonance test's PSD.

The spectrum and its model ``M(f) = E(f) R(f^2) / prod_k |D_k(j 2 pi f)|^2 + g / f^2 + N``
are in :mod:`.spectral_model`; the PSD estimates in :mod:`.welch`.  This module fits it.

The periodogram average at each bin is the true PSD times a scaled chi-square
variable, so the fit is the Whittle (gamma) maximum likelihood, computed by
iteratively reweighted least squares (weights ``1 / M``).  Its dispersion is
estimated from the residual (and for tests never taken below the estimator's own
``1/K``), the correlation of neighbouring bins comes from the estimator's window, and
both scale the Gauss-Newton covariance of the poles and the deviance tests.

Modes are added greedily from the excitation-normalised spectrum's peaks and each
is kept only when a likelihood-ratio test against the model without it passes
after allowing for the frequency search (:mod:`.significance`).  A mode whose
half-power band leaves the fitted band is a rise at the band edge, not a mode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np
from scipy import signal, stats

from .. import _validate as v
from ..modes import Mode
from .results import PeakGuess
from .significance import MAX_MODES, ModeTest, NoModeFound, at_band_edge, search_cells
from .spectral_model import ZETA_BOUNDS, Batch, SpectralModel, Spectrum, pole_bounds
from .welch import (KAISER6_CORRELATION, block_kernel, smoothed_periodogram, welch_dispersion,  # noqa: F401
                    welch_kernel, welch_psd, window_correlation)  # (re-exported: their old home)

__all__ = ["Spectrum", "SpectralFit", "SpectralModes", "fit_spectrum", "welch_psd", "smoothed_periodogram",
           "window_correlation", "welch_dispersion", "welch_kernel", "block_kernel", "BROAD_ZETA",
           "KAISER6_CORRELATION"]

#: A fitted peak this broad (the resonant gain 1/(2 zeta) is near 1) is background, not a resonance.
BROAD_ZETA = 0.45
#: A mode whose peak is below this share of the spectrum's maximum is not reported (Klipper's 1/20).
MINOR_SHARE = 0.05
#: Below this frequency (Hz) a sweeping test's slow-sweep lines dominate the spectrum: modes there are flagged.
LOW_SWEEP_LIMIT = 15.0


@dataclass
class SpectralFit:
    """Details of a spectral fit beyond :class:`~posicast.identification.Identification`.

    Attributes
    ----------
    freqs, psd : ndarray
        The fitted bins and data.
    model : ndarray
        Fitted PSD on ``freqs``.
    background : ndarray
        Fitted PSD without any mode (excitation through a flat path, sweep, floor).
    components : list of ndarray
        Per mode: model minus the model refitted without that mode.
    dispersion : float
        Residual variance of ``psd / model`` (``1/K`` for ``K`` averaged periodograms).
    correlation : float
        Variance inflation from correlated neighbouring bins (>= 1).
    """

    freqs: np.ndarray
    psd: np.ndarray
    model: np.ndarray
    background: np.ndarray
    components: list[np.ndarray] = field(default_factory=list)
    dispersion: float = float("nan")
    correlation: float = 1.0


@dataclass
class SpectralModes:
    """What :func:`fit_spectrum` found.

    Attributes
    ----------
    modes : list of Mode
        Resonances, by frequency.
    intervals : list of ((omega_lo, omega_hi), (zeta_lo, zeta_hi))
        95 % intervals.
    tests : list of ModeTest
        Each mode against the model without it.
    at_edge : list of bool
        The mode's half-power band leaves the fitted band.
    shares : list of float
        Each mode's share of the fitted spectrum's power.
    fit : SpectralFit
    notes : list of str
    """

    modes: list[Mode]
    intervals: list[tuple[tuple[float, float], tuple[float, float]]]
    tests: list[ModeTest]
    at_edge: list[bool]
    shares: list[float]
    fit: SpectralFit
    notes: list[str] = field(default_factory=list)

class _Tested(NamedTuple):
    """The modes that passed the backward elimination, with their tests and the fit's scatter."""

    theta: np.ndarray
    model_psd: np.ndarray  # the fitted PSD with every mode
    background: np.ndarray  # the fitted PSD without any mode
    tests: list[ModeTest]
    components: list[np.ndarray]  # per mode: the model minus the model without it
    dispersion: float
    correlation: float
    scale: float  # the intervals' scale: dispersion x correlation


# ----------------------------------------------------------------------------- the fit


def _fit(model: SpectralModel, theta0: np.ndarray, iterations: int = 3, rtol: float = 1e-8) -> tuple[np.ndarray, np.ndarray]:
    """Poles by least squares on relative errors, then Whittle IRLS steps (weights ``1/M``).

    The first pass weights by the smoothed data, which cannot run away when the model
    is still missing a mode; each reweighting is kept only if the gamma deviance drops
    and the model stays positive.
    """
    lo, hi = pole_bounds(model, theta0.size // 2)
    th = np.clip(theta0, lo + 1e-9, hi - 1e-9)
    model.weights = 0.05 / model.floor

    def run(x: np.ndarray) -> np.ndarray:
        return _levenberg_marquardt(model.residual_and_jacobian_lazy, x, lo, hi, rtol=rtol)

    th = run(th)
    M, _ = model.solve(th)
    dev = _deviance(model, M) if np.all(M > 0) else math.inf
    for _ in range(iterations):
        if not np.all(M > 0):
            break
        w_old = model.weights
        model.weights = 1.0 / M
        th_new = run(th)
        M_new, _ = model.solve(th_new)
        dev_new = _deviance(model, M_new) if np.all(M_new > 0) else math.inf
        if dev_new >= dev - 1e-9 * abs(dev):
            model.weights = w_old
            break
        th, M, dev = th_new, M_new, dev_new
    return th, M


def _deviance(model: SpectralModel, M: np.ndarray) -> float:
    """Gamma deviance (unit dispersion): ``2 sum(-log(P/M) + (P - M)/M)``; M floored at 5 % of the data."""
    P = model.P
    M = np.maximum(M, model.floor)
    r = P / M
    return float(2.0 * np.sum(-np.log(np.maximum(r, 1e-300)) + r - 1.0))


def _dispersion(model: SpectralModel, M: np.ndarray, n_par: int) -> tuple[float, float, np.ndarray]:
    """Dispersion (Pearson) and the correlation inflation ``1 + 2 sum (1 - l/(L+1)) rho_l``."""
    r = model.P / np.maximum(M, model.floor) - 1.0
    n = r.size
    phi = float(r @ r) / max(n - n_par, 1)
    rc = r - r.mean()
    L = max(2, int(round(4 * (n / 100.0) ** (2 / 9))))
    c0 = float(rc @ rc)
    infl = 1.0
    if c0 > 0:
        for lag in range(1, min(L, n - 1) + 1):
            infl += 2.0 * (1.0 - lag / (L + 1.0)) * float(rc[lag:] @ rc[:-lag]) / c0
    return phi, max(infl, 1.0), r


def _levenberg_marquardt(fun: Callable[[np.ndarray], tuple[np.ndarray, Callable[[], np.ndarray]]],
                         x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, *, max_iter: int = 60,
                         rtol: float = 1e-9) -> np.ndarray:
    """Levenberg-Marquardt (Marquardt's diagonal scaling) with steps clipped to the bounds.

    A few poles on a few hundred bins: scipy's trust-region reflective solver spent
    most of its time in its own bookkeeping here (60 iterations per fit at 1e-10
    tolerances); this stops when the cost changes by less than ``rtol``.  ``fun``
    returns the residual and a function giving the Jacobian, called only at accepted
    points (issue #15).
    """
    x = np.clip(np.asarray(x0, float), lo, hi)
    if x.size == 0:
        return x
    r, jac = fun(x)
    J = jac()
    cost = float(r @ r)
    lam = 1e-3
    for _ in range(max_iter):
        g = J.T @ r
        H = J.T @ J
        d = np.diag(H).copy()
        d[d <= 0] = 1.0
        diag, rhs = np.diag(d), -g  # fixed over the damping trials
        improved = False
        for _ in range(12):
            try:
                step = np.linalg.solve(H + lam * diag, rhs)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            xn = np.minimum(np.maximum(x + step, lo), hi)
            rn, jac_n = fun(xn)
            cn = float(rn @ rn)
            if cn < cost:
                improved = True
                break
            lam *= 4.0
        if not improved:
            break
        done = cost - cn <= rtol * cost
        x, r, cost = xn, rn, cn
        if done:
            break
        J = jac_n()
        lam = max(lam / 5.0, 1e-12)
    return x


def _levenberg_marquardt_batch(evaluate: Callable[[np.ndarray], Batch], X0: np.ndarray, lo: np.ndarray,
                               hi: np.ndarray, *, max_iter: int, rtol: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_levenberg_marquardt` on every row of ``X0`` at once: each row keeps its own damping ``lam``
    and stops on its own test, so each row takes the steps it would take alone (issue #15).

    ``evaluate(X)`` gives the rows' residuals and, on demand, their Jacobians (:class:`Batch`); a
    Jacobian is computed only at accepted points, from the evaluation that accepted them.  Returns the
    fitted rows and their costs (sums of squared residuals).  The per-row bookkeeping (dampings, costs,
    which rows still run) is plain Python: a few rows, where numpy's per-call overhead was a quarter of
    the fit (issue #15, wave 6); the arithmetic is the same floating-point operations.
    """
    X = np.minimum(np.maximum(np.asarray(X0, float), lo), hi)
    b = evaluate(X)
    r = b.r.copy()
    J = b.jacobian(range(X.shape[0]))
    cost: list[float] = np.einsum("cb,cb->c", r, r).tolist()
    lam = [1e-3] * X.shape[0]
    active = list(range(X.shape[0]))  # the rows still iterating, in order
    eye = np.eye(X.shape[1])
    for _ in range(max_iter):
        if not active:
            break
        idx = active
        Ji, ri = J[idx], r[idx]
        g = np.einsum("cbk,cb->ck", Ji, ri)
        H = np.einsum("cbk,cbl->ckl", Ji, Ji)
        d = np.diagonal(H, axis1=1, axis2=2).copy()
        d[d <= 0] = 1.0
        pending = list(range(len(idx)))  # positions in idx without an accepted step yet
        accepted: dict[int, tuple[Batch, int, np.ndarray, float]] = {}  # position -> evaluation, its row, x, cost
        for _ in range(12):
            if not pending:
                break
            step, ok = _damped_steps(H, g, d, pending, [lam[idx[i]] for i in pending], eye)
            sel = pending
            if not ok.all():
                sel = [i for i, good in zip(pending, ok.tolist()) if good]
                for i in set(pending) - set(sel):
                    lam[idx[i]] *= 10.0  # singular: more damping, as the single fit does
                step = step[ok]
                if not sel:
                    continue
            xn = np.minimum(np.maximum(X[[idx[i] for i in sel]] + step, lo), hi)
            bn = evaluate(xn)
            cn = np.einsum("cb,cb->c", bn.r, bn.r).tolist()
            for row, i in enumerate(sel):
                if cn[row] < cost[idx[i]]:
                    accepted[i] = (bn, row, xn[row], cn[row])
                else:
                    lam[idx[i]] *= 4.0
            pending = [i for i in pending if i not in accepted]
        active = []
        by_source: dict[int, tuple[Batch, list[int], list[int]]] = {}
        for i, c in enumerate(idx):
            if i not in accepted:
                continue  # no step lowered the cost: this row stops
            bn, row, x_new, c_new = accepted[i]
            done = cost[c] - c_new <= rtol * cost[c]
            X[c], r[c], cost[c] = x_new, bn.r[row], c_new
            if done:
                continue
            active.append(c)
            lam[c] = max(lam[c] / 5.0, 1e-12)
            entry = by_source.setdefault(id(bn), (bn, [], []))
            entry[1].append(c)
            entry[2].append(row)
        for bn, targets, rows in by_source.values():
            J[targets] = bn.jacobian(rows)
    return X, np.array(cost)


def _damped_steps(H: np.ndarray, g: np.ndarray, d: np.ndarray, rows: list[int], lams: list[float],
                  eye: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Levenberg-Marquardt steps ``(H[c] + lam diag(d[c])) step = -g[c]`` of the chosen rows, and ``ok``:
    False where the damped matrix is singular (``np.linalg.solve`` would raise).

    Two parameters (a screened pole) by Cramer's rule in Python floats: the same operations as on arrays
    (``H + lam (d eye)`` adds ``lam d`` on the diagonal and ``lam 0`` off it), without numpy's per-call cost
    on a few 2 x 2 systems (issue #15, wave 6)."""
    if H.shape[1] == 2:
        steps, ok = [], []
        for c, lam in zip(rows, lams):
            (h00, h01), (h10, h11) = H[c].tolist()
            d0, d1 = d[c].tolist()
            r0, r1 = (-g[c]).tolist()
            a, b, cc, dd = h00 + lam * d0, h01 + lam * (d0 * 0.0), h10 + lam * (d1 * 0.0), h11 + lam * d1
            det = a * dd - b * cc
            good = math.isfinite(det) and det != 0
            det = det if good else 1.0
            steps.append(((dd * r0 - b * r1) / det, (a * r1 - cc * r0) / det))
            ok.append(good)
        return np.array(steps), np.array(ok)
    M = H[rows] + np.array(lams)[:, None, None] * (d[rows, :, None] * eye)
    rhs = -g[rows]
    try:
        return np.linalg.solve(M, rhs[:, :, None])[:, :, 0], np.ones(M.shape[0], dtype=bool)
    except np.linalg.LinAlgError:
        out, ok = np.zeros(rhs.shape), np.ones(M.shape[0], dtype=bool)
        for c in range(M.shape[0]):
            try:
                out[c] = np.linalg.solve(M[c], rhs[c])
            except np.linalg.LinAlgError:
                ok[c] = False
        return out, ok


def _screen_new_pole(model: SpectralModel, theta: np.ndarray, starts: np.ndarray, *, max_iter: int = 15,
                     rtol: float = 1e-5) -> tuple[np.ndarray, np.ndarray]:
    """Fit only the new pole from each start (rows ``(ln w, zeta)``), the others fixed: a cheap screen.

    Returns the fitted new poles, one row per start, and the cost of each (the sum of squared
    weighted residuals of ``theta`` plus that pole).
    """
    lo, hi = pole_bounds(model, 1)
    lo, hi = lo + 1e-9, hi - 1e-9
    return _levenberg_marquardt_batch(lambda X: model.batch(theta, X), np.asarray(starts, float), lo, hi,
                                      max_iter=max_iter, rtol=rtol)


def _peaks(model: SpectralModel, k: int, exclude: list[float], M: np.ndarray | None = None) -> list[PeakGuess]:
    """Candidate (frequency, zeta) where the data exceed the current model ``M`` most, most prominent first.

    Peaks of ``log(P / M)`` lightly smoothed (a 3-bin mean: a median would flatten a peak
    one or two bins wide); the damping guess is the half width of the excess ``P/M - 1``.
    """
    ref = model._reduce(model.E_parts[0][:, None])[:, 0] if M is None else np.maximum(M, model.floor)
    R = model.P / ref
    L = np.convolve(np.log(np.maximum(R, 1e-300)), np.ones(3) / 3.0, mode="same")
    idx, props = signal.find_peaks(L, prominence=0.05)
    order = np.argsort(props["prominences"])[::-1] if idx.size else []
    step = float(np.median(np.diff(model.f))) if model.f.size > 1 else 1.0
    out: list[PeakGuess] = []
    for i in (idx[order] if idx.size else []):
        i = int(max(i - 1, 0) + np.argmax(R[max(i - 1, 0):i + 2]))  # the highest bin next to the smoothed peak
        fp = float(model.f[i])
        if any(abs(fp - e) < 0.03 * e for e in exclude):
            continue
        X = R - 1.0
        half = 0.5 * X[i]
        a = i
        while a > 0 and X[a] > half:
            a -= 1
        b = i
        while b < R.size - 1 and X[b] > half:
            b += 1
        width = max(float(model.f[b] - model.f[a]) - step, step)  # between the half-power crossings
        out.append(PeakGuess(fp, float(np.clip(width / (2.0 * fp), 0.003, 0.4))))
        if len(out) >= k:
            break
    return out


def fit_spectrum(spec: Spectrum, n_modes: int | str = "auto", *, max_modes: int = 4,
                 progress: Callable[[str], None] | None = None) -> SpectralModes:
    """Fit the modes of a resonance spectrum (module docstring).

    ``n_modes`` is the most modes to fit (1 to 6) or ``"auto"`` (up to ``max_modes``);
    modes the data do not demand are dropped either way.  Raises
    :class:`~posicast.identification.NoModeFound` when no mode passes its test, or the only
    peaks are a rise at the band edge or broad background.
    """
    v.instance_of(spec, Spectrum, "spec", "a Spectrum")
    if n_modes != "auto":
        n_modes = v.integer_in_range(n_modes, "n_modes", 1, MAX_MODES)
    max_modes = v.integer_in_range(max_modes, "max_modes", 1, MAX_MODES)
    model = SpectralModel(spec)
    if model.f.size < 12:
        raise ValueError(f"only {model.f.size} usable frequency bins in the band {spec.band[0]:g}-{spec.band[1]:g} Hz; "
                         "a PSD needs at least 12")
    target = int(n_modes) if n_modes != "auto" else max_modes
    bin_step = spec.resolution if math.isfinite(spec.resolution) else float(np.median(np.diff(model.f)))
    cells = search_cells(model.f[0], model.f[-1], 1.0 / max(bin_step, 1e-9))
    theta, M_cur = _forward(model, target, progress)
    tested = _backward(model, theta, M_cur, cells, bin_step, progress)
    return _report(model, tested)


def _forward(model: SpectralModel, target: int, progress: Callable[[str], None] | None
             ) -> tuple[np.ndarray, np.ndarray]:
    """Forward selection: up to ``target`` poles and the model PSD with them.

    Screen the peaks of data / current model by fitting the new pole alone, fit the best
    jointly, and go on while it lowers the (relative) residual by more than 1 %; which of
    these modes the data demand is decided afterwards (:func:`_backward`), against the
    dispersion of the full model.
    """
    # the model without modes: excitation through a flat path, sweep lines, floor
    M0 = _fit(model, np.zeros(0), iterations=0)[1]
    theta, M_cur = np.zeros(0), M0
    rss_cur = float(np.sum(model.residual(theta) ** 2))
    while theta.size // 2 < target:
        best = _best_new_pole(model, theta, M_cur)
        if best is None:
            break
        th, M = _fit(model, best, iterations=0, rtol=1e-6)
        rss = float(np.sum(model.residual(th) ** 2))
        th, M, rss = _second_start(model, th, M, rss, M0)
        if rss > 0.99 * rss_cur:
            break
        theta, M_cur, rss_cur = th, M, rss
        if progress:
            progress(f"fitted {theta.size // 2} mode(s): " + ", ".join(
                f"{math.exp(theta[2 * k]) / (2 * math.pi):.2f} Hz" for k in range(theta.size // 2)))
    return theta, M_cur


def _best_new_pole(model: SpectralModel, theta: np.ndarray, M_cur: np.ndarray) -> np.ndarray | None:
    """The poles ``theta`` plus the best new one screened at the peaks of data / current model (None: no peak)."""
    have = [math.exp(theta[2 * k]) / (2 * math.pi) for k in range(theta.size // 2)]
    starts = []
    for fp, zp in _peaks(model, 4, have, M_cur):
        # the width guess is poor while the model still lacks the mode: try a ladder of dampings too
        starts += [[math.log(2 * math.pi * fp), z0]
                   for z0 in [zp] + [z for z in (0.005, 0.02, 0.06, 0.2) if not 0.67 < z / zp < 1.5]]
    if not starts:
        return None
    X, cost = _screen_new_pole(model, theta, np.array(starts))
    return np.r_[theta, X[int(np.argmin(cost))]]  # the first of the lowest, as a loop with ``<`` keeps


def _second_start(model: SpectralModel, th: np.ndarray, M: np.ndarray, rss: float, M0: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, float]:
    """A second start: the n most prominent peaks of the spectrum over the mode-free model ``M0``, each
    with its damping guess (greedy steps can settle on one broad mode covering two peaks); the better fit."""
    n_new = th.size // 2
    direct = _peaks(model, n_new, [], M0)
    found = sorted(math.exp(th[2 * k]) / (2 * math.pi) for k in range(n_new))
    same = len(direct) == n_new and all(abs(a - b) < 0.03 * b for a, b in zip(sorted(p for p, _ in direct), found))
    if len(direct) == n_new and not same:  # greedy steps already on those peaks: nothing to gain
        # the width guesses, then one damping for all: four fits side by side (as _fit would run each)
        th0 = np.array([[[math.log(2 * math.pi * fp), zp if zl is None else zl] for fp, zp in direct]
                        for zl in (None, 0.02, 0.05, 0.1)]).reshape(4, -1)
        lo, hi = pole_bounds(model, n_new)
        model.weights = 0.05 / model.floor
        X, cost = _levenberg_marquardt_batch(lambda X: model.batch(np.zeros(0), X),
                                             np.clip(th0, lo + 1e-9, hi - 1e-9), lo, hi, max_iter=60, rtol=1e-6)
        better = None
        for j in range(X.shape[0]):
            if cost[j] < rss:
                th, rss, better = X[j], float(cost[j]), j
        if better is not None:
            M = model.solve(th)[0]
    return th, M, rss


def _backward(model: SpectralModel, theta: np.ndarray, M_cur: np.ndarray, cells: float, bin_step: float,
              progress: Callable[[str], None] | None) -> _Tested:
    """Backward elimination: test each mode against the model without it, the other poles fixed (dispersion
    of the full model); drop the least significant failing one and refit, until all pass."""
    M0 = _fit(model, np.zeros(0), iterations=3)[1]
    dev0 = _deviance(model, M0)
    if theta.size:
        theta, M_cur = _fit(model, theta, iterations=3)  # Whittle reweighting of the final model
    dev_cur = _deviance(model, M_cur)
    while True:
        n = theta.size // 2
        if n == 0:
            raise NoModeFound(_no_mode_message(model, M0, cells))
        phi, infl, _ = _dispersion(model, M_cur, 2 * n + 2 * n + 3)
        if model.correlation is not None:
            infl = model.correlation
        scale = max(phi * infl, 1e-12)  # the intervals' scale: the scatter observed
        test_scale = max(max(phi, model.dispersion_floor or 0.0) * infl, 1e-12)  # tests: never below theory
        tests, comps = _mode_tests(model, theta, M_cur, dev_cur, dev0, test_scale, cells, bin_step)
        bad = [k for k in range(n) if not tests[k].significant]
        if not bad:  # a fixed n_modes is the most asked for: modes the data do not demand still go
            return _Tested(theta, M_cur, M0, tests, comps, phi, infl, scale)
        worst = max(bad, key=lambda k: tests[k].p_adjusted)
        if progress:
            progress(f"dropped {math.exp(theta[2 * worst]) / (2 * math.pi):.2f} Hz: {tests[worst].describe()}")
        if n == 1:
            raise NoModeFound(_no_mode_message(model, M0, cells))
        theta, M_cur = _fit(model, np.delete(theta, [2 * worst, 2 * worst + 1]))
        dev_cur = _deviance(model, M_cur)
        model.weights = 1.0 / np.maximum(M_cur, model.floor)


def _mode_tests(model: SpectralModel, theta: np.ndarray, M_cur: np.ndarray, dev_cur: float, dev0: float,
                test_scale: float, cells: float, bin_step: float) -> tuple[list[ModeTest], list[np.ndarray]]:
    """Each mode's likelihood-ratio test against the model without it, and its component of the model."""
    tests, comps = [], []
    for k in range(theta.size // 2):
        # the other poles stay where they are: refitted, a spurious mode would move in to replace it
        Mk = model.solve(np.delete(theta, [2 * k, 2 * k + 1]))[0]
        dk = _deviance(model, Mk)
        lr = max(dk - dev_cur, 0.0) / test_scale
        p = float(stats.chi2.sf(lr, 4))  # its pole and two numerator coefficients
        # a peak narrower than a bin can sit at several places within each bin: that many more tests
        width = 2.0 * theta[2 * k + 1] * math.exp(theta[2 * k]) / (2 * math.pi)
        cells_k = cells * max(1.0, bin_step / max(width, 1e-12))
        tests.append(ModeTest(lr, 4, p, cells_k, min(1.0, p * cells_k),
                              float(min(max((dk - dev_cur) / max(dev0 - dev_cur, 1e-300), 0.0), 1.0))))
        comps.append(M_cur - Mk)
    return tests, comps


def _report(model: SpectralModel, tested: _Tested) -> SpectralModes:
    """Intervals, shares and edge flags of the tested modes; broad and minor features become notes."""
    M_cur, comps, tests = tested.model_psd, tested.components, tested.tests
    modes, ivs, edges, shares = _modes_and_intervals(model, tested)
    order = [int(i) for i in np.argsort([m.omega for m in modes])]
    fit = SpectralFit(model.f, model.P, M_cur, tested.background, [comps[i] for i in order], tested.dispersion,
                      tested.correlation)
    broad, minor, notes = _background_features(modes, comps, order, M_cur)
    keep = [i for i in order if i not in broad and i not in minor]
    if not [i for i in keep if not edges[i]]:
        i = keep[-1] if keep else max(order, key=lambda j: float(np.max(comps[j])))
        m = modes[i]
        what = ("a rise at the edge of the excited band" if edges[i] else
                "a broad feature with no resonant peak" if i in broad else "too small to matter")
        raise NoModeFound(f"no resonance found in {model.f[0]:.1f}-{model.f[-1]:.1f} Hz: the only peak "
                          f"({m.freq_hz:.1f} Hz, zeta {m.zeta:.2f}) is {what}", m, tests[i])
    for i in keep:
        notes += _unresolved(model, modes[i], i, edges)
    return SpectralModes([modes[i] for i in keep], [ivs[i] for i in keep], [tests[i] for i in keep],
                         [edges[i] for i in keep], [shares[i] for i in keep], fit, notes)


def _background_features(modes: list[Mode], comps: list[np.ndarray], order: list[int], M_cur: np.ndarray
                         ) -> tuple[list[int], list[int], list[str]]:
    """The fitted poles that are not reported: broad ones (background) and minor ones; and the notes saying so."""
    notes: list[str] = []
    broad = [i for i in order if modes[i].zeta >= BROAD_ZETA]
    for i in broad:
        notes.append(f"a broad feature at {modes[i].freq_hz:.1f} Hz (zeta {modes[i].zeta:.2f}) is part of the "
                     "fitted background, not a resonance")
    # a mode whose own peak stays under 1/20 of the spectrum's maximum cannot matter to a shaper (it is
    # Klipper's threshold too): a feature of the fit (the slow sweep's lines, a ripple), not reported
    top = float(np.max(M_cur))
    minor = [i for i in order if i not in broad and float(np.max(comps[i])) < MINOR_SHARE * top]
    for i in minor:
        notes.append(f"a small peak at {modes[i].freq_hz:.1f} Hz (under {100 * MINOR_SHARE:.0f} % of the "
                     "spectrum's maximum) is fitted but not reported")
    return broad, minor, notes


class _FittedModes(NamedTuple):
    """Per fitted pole: the mode, its 95 % intervals, whether it leaves the band, its share of the power."""

    modes: list[Mode]
    intervals: list[tuple[tuple[float, float], tuple[float, float]]]
    at_edge: list[bool]
    shares: list[float]


def _modes_and_intervals(model: SpectralModel, tested: _Tested) -> _FittedModes:
    """Per fitted pole: the mode, its 95 % intervals, whether it leaves the band, and its share of the power."""
    theta, M_cur, comps = tested.theta, tested.model_psd, tested.components
    # covariance of the poles: Gauss-Newton of the weighted residual, scaled by dispersion x correlation
    J = model.jacobian(theta)
    JTJ = J.T @ J
    try:
        C = np.linalg.inv(JTJ) * tested.scale
    except np.linalg.LinAlgError:
        C = np.linalg.pinv(JTJ) * tested.scale
    tq = float(stats.norm.ppf(0.975))
    modes, ivs, edges, shares = [], [], [], []
    total = float(np.sum(np.maximum(M_cur, 0.0)))
    for k in range(theta.size // 2):
        lw, z = theta[2 * k], theta[2 * k + 1]
        sw = math.sqrt(max(C[2 * k, 2 * k], 0.0))
        sz = math.sqrt(max(C[2 * k + 1, 2 * k + 1], 0.0))
        m = Mode(math.exp(lw), float(z))
        modes.append(m)
        # an unresolved pole (singular curvature) gets an interval as wide as the band allows
        w_lo, w_hi = math.log(math.pi * model.f[0]), math.log(4 * math.pi * model.f[-1])
        ivs.append(((math.exp(max(lw - tq * sw, w_lo)), math.exp(min(lw + tq * sw, w_hi))),
                    (max(z - tq * sz, 0.0), min(z + tq * sz, 0.999))))
        edges.append(at_band_edge(m, model.f[0], model.f[-1], zeta_floor=ZETA_BOUNDS[0]))
        shares.append(float(np.sum(np.maximum(comps[k], 0.0))) / max(total, 1e-300))
    return _FittedModes(modes, ivs, edges, shares)


def _unresolved(model: SpectralModel, mode: Mode, i: int, edges: list[bool]) -> list[str]:
    """Flag (in ``edges[i]``) and note a kept mode whose damping the spectrum does not resolve."""
    notes = []
    if model.low and mode.freq_hz < LOW_SWEEP_LIMIT and not edges[i]:
        # the slow sweep's lines (odd multiples of 1/P) dominate there and are not a smooth excitation
        edges[i] = True
        notes.append(f"{mode.freq_hz:.1f} Hz lies where the slow sweep's lines dominate (under "
                     f"{LOW_SWEEP_LIMIT:.0f} Hz): reported, not resolved")
    if mode.zeta <= 1.5 * ZETA_BOUNDS[0]:
        edges[i] = True
        notes.append(f"{mode.freq_hz:.1f} Hz has the smallest damping the fit allows: the peak is "
                     "narrower than the resolution, its damping is not resolved")
    elif edges[i]:
        notes.append(f"{mode.freq_hz:.1f} Hz lies at the edge of the excited band: reported, not resolved")
    return notes


def _no_mode_message(model: SpectralModel, M0: np.ndarray, cells: float) -> str:
    ratio = model.P / np.maximum(M0, 1e-300)
    i = int(np.argmax(ratio >= (1.0 - 1e-9) * np.max(ratio)))  # ties to rounding (a flat spectrum): the lowest bin
    return (f"no resonance found in {model.f[0]:.1f}-{model.f[-1]:.1f} Hz: the spectrum is explained by the "
            f"excitation and the noise floor (largest excess {ratio[i]:.2g}x at {model.f[i]:.1f} Hz is within "
            f"noise after {cells:.0f} frequency cells)")
