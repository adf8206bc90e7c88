"""Issue #15 (part B): the output-error fit's closed-form Jacobian and its shortcuts on long records."""

from __future__ import annotations

import math

import numpy as np
import pytest

import posicast
from posicast.identification import output_error
from posicast.identification.fit_statistics import numerical_jacobian
from posicast.identification.output_error import OEModel
from posicast.identification.resonance import resonance_data
from posicast.identification.spectral_model import SpectralModel
from posicast.testing import synthetic
from posicast.testing.synthetic_data import klipper_dataset

TRUE = posicast.Mode.from_hz(28.0, 0.05)  # seed 002 section 3.2


@pytest.mark.parametrize("terms", [{}, {"feedthrough": False, "offset": False, "initial_state": False}, "weights"])
@pytest.mark.parametrize("n_modes", [1, 2])
@pytest.mark.parametrize("with_input", [True, False])
def test_jacobian_equals_central_differences(terms, n_modes, with_input):
    """Golub-Pereyra's Jacobian of the projected residual against central differences (their error ~1e-9)."""
    d = synthetic(TRUE, "random_binary", n=3000, noise=0.05, seed=0)
    kw = dict(terms) if isinstance(terms, dict) else {
        "weights": (np.random.default_rng(1).random(d.y.size) > 0.1).astype(float)}
    th = np.array([math.log(TRUE.omega * 1.03), 0.07]) if n_modes == 1 else \
        np.array([math.log(170.0), 0.04, math.log(420.0), 0.02])
    model = OEModel(d.u if with_input else None, d.y, 1.0 / d.sample_rate, n_modes, **kw)
    J, Jn = model.jacobian(th), numerical_jacobian(model.residual, th)
    assert J.shape == Jn.shape == (d.y.size, 2 * n_modes)
    assert np.max(np.abs(J - Jn)) < 1e-6 * np.max(np.abs(Jn))


def test_jacobian_at_the_zeta_bound_is_zero_along_zeta():
    """Below ZETA_MIN the model holds zeta at the bound: the residual does not move, nor does the Jacobian."""
    d = synthetic(TRUE, "random_binary", n=2000, noise=0.05, seed=2)
    model = OEModel(d.u, d.y, 1.0 / d.sample_rate, 1)
    J = model.jacobian(np.array([math.log(TRUE.omega), 0.5 * output_error.ZETA_MIN]))
    assert np.all(J[:, 1] == 0.0) and np.max(np.abs(J[:, 0])) > 0


@pytest.mark.parametrize("excitation", ["random_binary", "chirp"])
def test_long_record_shortcuts_keep_the_fit(excitation, monkeypatch):
    """Ranking the start and fitting first on the head of a long record gives the whole record's optimum."""
    d = synthetic(TRUE, excitation, n=20000, noise=0.05, seed=3)
    plain = posicast.identify(d.t, d.u, d.y)
    monkeypatch.setattr(output_error, "_LONG_RECORD", 4096)  # 20000 samples now count as long ...
    monkeypatch.setattr(output_error, "_HEAD", 2048)  # ... with a head of 2048
    short = posicast.identify(d.t, d.u, d.y)
    for a, b in zip(plain.modes + [plain.intervals[0].omega[0], plain.intervals[0].zeta[1]],
                    short.modes + [short.intervals[0].omega[0], short.intervals[0].zeta[1]]):
        if isinstance(a, posicast.Mode):
            assert abs(a.omega / b.omega - 1) < 1e-8 and abs(a.zeta / b.zeta - 1) < 1e-6
        else:
            assert abs(a / b - 1) < 1e-6


# ---------------------------------------------------------------------- the spectral fit (calibration), issue #15
def _demo_log():
    """A synthetic Klipper raw log with modes at 42 and 63 Hz (the demo's log)."""
    return klipper_dataset([posicast.Mode.from_hz(42.0, 0.08), posicast.Mode.from_hz(63.0, 0.06)], gains=[0.6, 0.4],
                           seed=1)


def _spectral_model() -> SpectralModel:
    return SpectralModel(resonance_data(_demo_log()).spectrum)


SPECTRAL_POLES = np.array([math.log(2 * math.pi * 41.0), 0.09, math.log(2 * math.pi * 64.0), 0.05])


def _direct_columns(model: SpectralModel, theta: np.ndarray) -> np.ndarray:
    """The design ``[E T_j(x) / prod |D_k|^2 averaged per bin, extra]`` straight from the module's formula."""
    den = np.ones_like(model.W2)
    for lw, z in theta.reshape(-1, 2):
        w2 = math.exp(2 * lw)
        den *= ((w2 - model.W2) ** 2 + 4 * z * z * w2 * model.W2) / w2 ** 2
    modal = model.cheb[:, : theta.size + 1] * (model.E_parts[0] / den)[:, None]
    return np.hstack([model._reduce(modal), model.extra])


def test_spectral_jacobian_is_kaufmans_column_by_column():
    """The analytic Jacobian equals Kaufman's formula ``-P_perp W (dA/dtheta_k) c`` built one column at a time
    from the design written out directly (its column derivatives by central differences, its projection by
    an SVD), and near the optimum (small residual, where Kaufman's dropped term vanishes) central differences
    of the residual."""
    model = _spectral_model()
    A = _direct_columns(model, SPECTRAL_POLES)
    assert np.max(np.abs(model.columns(SPECTRAL_POLES) - A)) < 1e-12 * np.max(np.abs(A))
    Aw = A * model.weights[:, None]
    U, sv, _ = np.linalg.svd(Aw, full_matrices=False)
    y = model.P * model.weights
    assert np.max(np.abs(model.residual(SPECTRAL_POLES) - (y - U @ (U.T @ y)))) < 1e-10 * np.max(np.abs(y))
    coef = np.linalg.lstsq(Aw, y, rcond=None)[0]
    ref = np.empty((model.f.size, 4))
    for k in range(4):
        h = 1e-6 * np.eye(4)[k]
        d = (_direct_columns(model, SPECTRAL_POLES + h) - _direct_columns(model, SPECTRAL_POLES - h)) / 2e-6
        d = (d @ coef) * model.weights
        ref[:, k] = -(d - U @ (U.T @ d))
    J = model.jacobian(SPECTRAL_POLES)  # central differences of the columns: error ~1e-9
    assert np.all(np.max(np.abs(J - ref), axis=0) < 1e-7 * np.max(np.abs(ref), axis=0))
    fit = posicast.identification.spectral.fit_spectrum(resonance_data(_demo_log()).spectrum)
    th = np.array([[math.log(m.omega), m.zeta] for m in fit.modes]).ravel()
    model.weights = 1.0 / np.maximum(model.solve(th)[0], model.floor)
    J, Jn = model.jacobian(th), numerical_jacobian(model.residual, th)
    assert np.max(np.abs(J - Jn)) < 0.05 * np.max(np.abs(Jn))


def test_spectral_lazy_jacobian_is_the_full_one():
    """The lazy form (a rejected step computes no Jacobian; a screened pole only its own columns) gives the
    same residual and the same columns as the full Jacobian (to rounding: the products run on fewer columns),
    also when the remembered pole factors are hit."""
    model = _spectral_model()
    r, J = model.residual_and_jacobian(SPECTRAL_POLES)
    fresh = _spectral_model()
    r2, jac = fresh.residual_and_jacobian_lazy(SPECTRAL_POLES, first=2)
    assert np.array_equal(r, r2)
    assert np.max(np.abs(jac() - J[:, 2:])) <= 1e-13 * np.max(np.abs(J))
    r3, jac3 = model.residual_and_jacobian_lazy(SPECTRAL_POLES)  # factors remembered from the first call
    assert np.array_equal(r, r3) and np.max(np.abs(jac3() - J)) <= 1e-13 * np.max(np.abs(J))


@pytest.mark.parametrize("n", [40, 300, 2000, 4095])
def test_whiteness_lags_are_np_correlates(n):
    """The Ljung-Box statistic's lags as m + 1 dot products: the same numbers as np.correlate's full
    autocorrelation, bit for bit (which the shortcut replaces below 4096 samples), white or coloured."""
    from scipy import stats

    from posicast.identification.fit_statistics import whiteness

    rng = np.random.default_rng(n)
    for e in (rng.standard_normal(n), np.cumsum(rng.standard_normal(n))):
        c = e - np.mean(e)
        m = min(20, n // 4)
        r = np.correlate(c, c, "full")[n - 1:n + m]
        q = n * (n + 2) * np.sum((r[1:] / r[0]) ** 2 / (n - np.arange(1, m + 1)))
        assert whiteness(e) == float(stats.chi2.sf(q, m))


def test_special_functions_are_scipy_stats_distributions():
    """issue #15: the tests and intervals call scipy.special's functions directly; they are what
    scipy.stats' distributions return (same numbers), on the arguments the fits use."""
    from scipy import special, stats

    for dof in (1, 2, 5, 37, 398, 1996, 199_990):
        assert special.stdtrit(dof, 0.975) == stats.t.ppf(0.975, dof)
        for k in (1, 2, 4):
            assert special.fdtri(k, dof, 0.999) == stats.f.ppf(0.999, k, dof)
            for W in (0.0, 0.3, 2.0, 17.0, 400.0):
                assert special.fdtrc(k, dof, W) == stats.f.sf(W, k, dof)
    for m in (2, 20):
        for q in (0.0, 1.5, 19.0, 31.4, 500.0):
            assert special.chdtrc(m, q) == stats.chi2.sf(q, m)
