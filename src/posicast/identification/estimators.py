"""The front door of identification: :func:`identify` checks the signals and runs one method.

Estimators of lightly damped modes (omega, zeta) with 95 % confidence intervals; each
method lives in its own module (:mod:`.output_error`, :mod:`.arx`, :mod:`.frequency_domain`,
:mod:`.decay`, :mod:`.spectral`), the result types in :mod:`.results` and the
intervals and whiteness in :mod:`.fit_statistics`.  Methods of :func:`identify`:

``"oe"`` (default)
    Output-error fit of a continuous-time modal model by variable projection.
    The model is ``y = sum_k (b0_k + b1_k s) / (s^2 + 2 zeta_k omega_k s + omega_k^2) u
    + d u + c`` plus each mode's free response (unknown initial state), sampled
    exactly under a zero-order hold.  The numerators, feed-through ``d`` (an
    accelerometer's ``s^2`` term) and offset ``c`` enter linearly and are
    projected out; only ``(ln omega_k, zeta_k)`` are searched
    (scipy.optimize.least_squares), from the peaks of the empirical transfer
    function.  Valid for position and acceleration outputs.  Output noise does
    not bias it (the criterion is the simulated, not the predicted, output).
    Intervals: Gauss-Newton covariance ``s^2 (J^T J)^-1`` of the projected
    residual; when the residual fails the whiteness test, a Newey-West (HAC)
    covariance is used instead.
``"arx"``
    Seed 002's least squares (eq. 19-25), the documented baseline: biased
    when the output is noisy (the regressors contain the noise).
``"freq"``
    Seed 002 section 3.2.2: FFT ratio, spectral peak, -3 dB bandwidth to the
    pole radius (eq. 26, corrected), poles by eq. 27, spectrum resampled so
    the peak is on the grid, then the seed's step-up/step-down refinement of
    omega and zeta on the response error.
``"decay"``
    Free-decay (ring-down) data, ``u`` ignored: matrix pencil (Hua & Sarkar)
    on the record, then the OE refinement of the free response.
``"psd"``
    Output-only (input not recorded, e.g. a Klipper resonance test): Welch
    PSD (:mod:`.welch`) fitted by a sum of modal power peaks on a smooth
    background (:mod:`.spectral_model`, :mod:`.spectral`).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from .. import _validate as v
from ..modes import Mode  # noqa: F401 (the doctest of identify uses it)
from .arx import fit_arx
from .decay import fit_decay
from .fit_statistics import fit_percent, whiteness
from .frequency_domain import fit_freq
from .frequency_domain import _radius_from_bandwidth, resonator_bandwidth  # noqa: F401 (old home)
from .output_error import OESettings, significant_oe
from .results import Identification, Interval
from .significance import MAX_MODES, NoModeFound, at_band_edge  # noqa: F401 (at_band_edge: old home)
from .spectral import fit_spectrum
from .spectral_model import Spectrum
from .welch import KAISER6_CORRELATION, welch_dispersion, welch_kernel, welch_psd

__all__ = ["Interval", "Identification", "identify", "METHODS", "whiteness", "fit_percent"]

METHODS = ("oe", "arx", "freq", "decay", "psd")
COVARIANCES = ("auto", "gauss-newton", "hac")


class Signals(NamedTuple):
    """Checked input of :func:`identify`: times, input (None for output-only data), output, sampling rate."""

    t: np.ndarray
    u: np.ndarray | None
    y: np.ndarray
    fs: float


def clipped_samples(y: np.ndarray) -> np.ndarray | None:
    """Samples at a saturated extreme: the largest (or smallest) value held for 3 or more samples
    in a row at least twice, and reached by at least 0.5 % of the record; None otherwise.

    A sensor or an amplifier that saturates holds its limit, again on each swing; an
    unsaturated record reaches its extreme on isolated samples, and a response that
    settles at its largest value holds it once.
    """
    out = np.zeros(y.size, dtype=bool)
    for ext in (float(np.max(y)), float(np.min(y))):
        at = y == ext
        if at.sum() < max(4, 0.005 * y.size):
            continue
        runs = np.diff(np.flatnonzero(np.diff(np.r_[0, at.astype(np.int8), 0])))[::2]
        if np.count_nonzero(runs >= 3) >= 2:
            out |= at
    return out if out.any() else None


def _median(x: np.ndarray) -> float:
    """``float(np.median(x))`` of a finite 1-D array: the same partition and the same mean of the middle pair,
    without np.median's generic machinery (issue #15: a third of the signal checks on a 2000-sample record)."""
    m = x.size
    if m % 2:
        return float(np.partition(x, m // 2)[m // 2])
    part = np.partition(x, [m // 2 - 1, m // 2])
    return float((part[m // 2 - 1] + part[m // 2]) / 2.0)


def _check_signals(t: Any, u: Any, y: Any, need_u: bool) -> Signals:
    t = v.real_array(t, "t")
    y = v.real_array(y, "y")
    if t.ndim != 1 or y.ndim != 1:
        raise ValueError("t and y must be one-dimensional arrays")
    if t.size != y.size:
        raise ValueError(f"t and y must have the same length, got {t.size} and {y.size}")
    if y.size < 16:
        raise ValueError(f"y must have at least 16 samples, got {y.size}")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.nonzero(dt <= 0)[0][0]) + 1
        raise ValueError(f"t must be strictly increasing (sample {k}: {t[k]:g} after {t[k - 1]:g})")
    h = _median(dt)
    if np.max(np.abs(dt - h)) > 0.01 * h:
        raise ValueError("t must be evenly sampled (steps vary by more than 1 %); resample first "
                         "(posicast.identification.load_csv resamples files)")
    uu = None
    if u is not None:
        uu = v.real_array(u, "u")
        if uu.shape != y.shape:
            raise ValueError(f"u must have the same shape as y, got {uu.shape} and {y.shape}")
    elif need_u:
        raise ValueError("u is required for this method (use method='psd' or 'decay' for output-only data)")
    return Signals(t, uu, y, 1.0 / h)


def identify(t: Any, u: Any, y: Any, n_modes: int | str = 1, method: str = "oe", *,
             covariance: str = "auto", feedthrough: bool | str = "auto", offset: bool | str = "auto",
             initial_state: bool | str = "auto", max_modes: int = 4, refine: bool = True,
             band: tuple[float, float] | None = None, excitation_slope: float = 0.0, nk: int = 0) -> Identification:
    """Identify lightly damped modes from sampled data.

    Parameters
    ----------
    t : array_like
        Sample times (s), strictly increasing and evenly spaced (1 % tolerance).
    u : array_like or None
        Input (same length), or None for output-only methods ``"psd"``, ``"decay"``.
    y : array_like
        Measured output (position, velocity or acceleration).
    n_modes : int in [1, 6] or "auto"
        Number of modes; ``"auto"`` picks 1..``max_modes`` (at most 6) by BIC (``"oe"``
        only).  Six modes is the most one fit takes (the cost of the output-error fit
        and its backward elimination grows as about ``n_modes^4``: 13 modes of a
        400-sample record took 5 s); fit a wider band in pieces.
    method : {"oe", "arx", "freq", "decay", "psd"}
        See the module docstring.  ``"arx"`` and ``"freq"`` fit one mode.
    covariance : {"auto", "gauss-newton", "hac"}
        Interval method; ``"auto"`` switches to Newey-West when the residual is coloured.
    feedthrough, offset, initial_state : bool or "auto"
        Nuisance terms of the OE model: a direct input-to-output term, a constant
        offset, a free response from a nonzero initial state.  ``"auto"``
        (default) fits without them and adds each only when an F-test at the
        fitted poles asks for it (an acceleration output has a direct term; a
        record that starts moving has an initial state).  Fitting unneeded
        terms costs ζ bias: +1.3 % instead of +0.65 % on seed 002's single
        step at 5 % noise.
    refine : bool
        ``"freq"``: run seed 002's iterative refinement.
    band : (float, float), optional
        ``"psd"``: frequency band in Hz.
    excitation_slope : float
        ``"psd"``: excitation PSD ~ f^a (Klipper sweep: 2).
    nk : int
        ``"arx"``: input delay (seed eq. 21: 0).

    Returns
    -------
    Identification
        ``.modes`` (list of Mode), ``.intervals`` (95 %), fit and whiteness.

    Examples
    --------
    >>> from posicast.testing import synthetic
    >>> d = synthetic(Mode.from_hz(28.0, 0.05), "step", n=800, noise=0.05, seed=3)
    >>> r = identify(d.t, d.u, d.y)
    >>> m, iv = r.modes[0], r.intervals[0]
    >>> abs(m.freq_hz - 28.0) < 0.1 and abs(m.zeta - 0.05) < 0.01
    True
    >>> iv.omega[0] < m.omega < iv.omega[1]
    True
    """
    method = v.choice(method, "method", METHODS)
    covariance = v.choice(covariance, "covariance", COVARIANCES)
    auto = isinstance(n_modes, str)
    if auto:
        if n_modes != "auto":
            raise ValueError(f"n_modes must be an integer >= 1 or 'auto', got {n_modes!r}")
        if method not in ("oe", "psd"):
            raise ValueError("n_modes='auto' is available for method='oe' and 'psd' only")
        max_modes = v.integer_in_range(max_modes, "max_modes", 1, MAX_MODES)
    else:
        n_modes = v.integer_in_range(n_modes, "n_modes", 1, MAX_MODES)
    _, uu, yy, fs = _check_signals(t, u, y, need_u=method in ("oe", "arx", "freq"))
    spread = float(np.ptp(yy))
    if spread <= 1e-12 * max(float(np.max(np.abs(yy))), 1e-300):
        raise NoModeFound(f"no mode found ({method}): the output is constant ({float(yy[0]):.6g} throughout)")
    clip = clipped_samples(yy)
    weights = None if clip is None else (~clip).astype(float)
    clip_note = [] if clip is None else [
        f"the output is clipped (held at {float(np.max(yy)):.6g} / {float(np.min(yy)):.6g}) on {int(clip.sum())} "
        f"samples of {yy.size}: " + ("they are left out of the fit" if method in ("oe", "freq", "decay") else
                                     "this method cannot leave them out; use method='oe'")]
    if method == "arx":
        if n_modes != 1:
            raise ValueError("method='arx' (seed 002 eq. 20) fits one mode; n_modes must be 1")
        out = fit_arx(uu, yy, fs, nk=v.integer(nk, "nk", 0))
    elif method == "freq":
        if n_modes != 1:
            raise ValueError("method='freq' (seed 002 section 3.2.2) fits one mode; n_modes must be 1")
        out = fit_freq(uu, yy, fs, refine=refine, covariance=covariance, feedthrough=feedthrough is True,
                       offset=offset is not False, initial_state=initial_state is not False, weights=weights)
    elif method == "psd":
        out = _fit_psd(yy, fs, n_modes, band=band, excitation_slope=excitation_slope)
    elif method == "decay":
        if uu is not None and np.ptp(uu) > 1e-12 * max(float(np.max(np.abs(uu))), 1e-300):
            # a ring-down model cannot see an input that moves during the record: its answer would be wrong
            raise ValueError("method='decay' fits a free ring-down and ignores u, but u changes during the record "
                             f"(from {float(np.min(uu)):.6g} to {float(np.max(uu)):.6g}); use method='oe', or pass "
                             "u=None with the part of the record after the input stops")
        out = fit_decay(yy, fs, int(n_modes), covariance=covariance, offset=offset is not False, weights=weights)
    else:
        settings = _oe_settings(covariance, feedthrough, offset, initial_state, weights)
        out = significant_oe(uu, yy, fs, int(n_modes), settings).identification if not auto else \
            _oe_by_bic(uu, yy, fs, max_modes, settings)
    out.notes += clip_note
    return out


def _oe_settings(covariance: str, feedthrough: Any, offset: Any, initial_state: Any,
                 weights: np.ndarray | None) -> OESettings:
    for name, val in (("feedthrough", feedthrough), ("offset", offset), ("initial_state", initial_state)):
        if val != "auto" and not isinstance(val, bool):
            raise ValueError(f"{name} must be True, False or 'auto', got {val!r}")
    return OESettings(covariance, feedthrough, offset, initial_state, weights)


def _oe_by_bic(u: np.ndarray | None, y: np.ndarray, fs: float, max_modes: int, settings: OESettings) -> Identification:
    """``n_modes="auto"``: the output-error fit of 1..``max_modes`` modes with the smallest BIC."""
    best, scores = None, {}
    for n in range(1, max_modes + 1):
        r, rss, k = significant_oe(u, y, fs, n, settings)
        if len(r.modes) < n:  # a mode of this order was not significant: higher orders add only noise
            break
        bic = y.size * math.log(max(rss, 1e-300) / y.size) + k * math.log(y.size)
        scores[n] = bic
        if best is None or bic < best[1]:
            best = (r, bic)
    if best is None:
        raise ValueError(f"max_modes must be >= 1, got {max_modes}")
    best[0].order_scores = scores
    return best[0]


def _fit_psd(y: np.ndarray, fs: float, n_modes: int | str, *, band: Any, excitation_slope: Any) -> Identification:
    """Output-only: Welch PSD (1 Hz resolution) fitted by :func:`posicast.identification.spectral.fit_spectrum`
    with an excitation ``E(f) = f^excitation_slope``."""
    if band is not None:
        lo, hi = (v.positive(band[0], "band[0]"), v.positive(band[1], "band[1]"))
        if not lo < hi <= fs / 2:
            raise ValueError(f"band must satisfy 0 < low < high <= fs/2 = {fs / 2:g}, got {band}")
        band = (lo, hi)
    slope = v.real_in_range(excitation_slope, "excitation_slope", -4.0, 4.0)
    resolution = max(1.0, 8.0 * fs / y.size)  # at least 8 segments
    f, P, K = welch_psd(y - np.mean(y), fs, resolution)
    lo, hi = band if band is not None else (max(2.0, 2.0 * float(f[1])), 0.45 * fs)
    E = np.where(f > 0, np.maximum(f, 1e-300) ** slope, 0.0)
    spec = Spectrum(f, P, E, (lo, hi), low_frequency=False, resolution=float(f[1] - f[0]),
                    source="Welch PSD of y", correlation=KAISER6_CORRELATION,
                    dispersion_floor=welch_dispersion(np.kaiser(2 * (f.size - 1), 6.0), K), kernel=welch_kernel())
    r = fit_spectrum(spec, n_modes)
    return Identification(r.modes, [Interval(*iv) for iv in r.intervals], "psd", float("nan"), float("nan"),
                          "whittle", r.fit.model, None, fs, freqs=r.fit.freqs, spectrum=r.fit.psd,
                          shares=r.shares, tests=r.tests, at_edge=r.at_edge,
                          notes=[f"output-only PSD fit on [{lo:.1f}, {hi:.1f}] Hz, excitation ~ f^{slope:g}"]
                          + r.notes)
