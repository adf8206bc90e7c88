"""Issue #15 (wave 5): the spectral fit's evaluations side by side, and its QR projection.

Each batched or shortened computation is checked against the plain one it replaces: a row of
:meth:`SpectralModel.batch` against :meth:`~SpectralModel.residual_and_jacobian_lazy` of the same poles, the
batched Levenberg-Marquardt against the single fit row by row, the QR basis against an SVD.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import posicast
from posicast.identification import spectral
from posicast.identification.resonance import resonance_data
from posicast.identification.spectral_model import SpectralModel, pole_bounds
from posicast.testing.synthetic_data import klipper_dataset

HELD = np.array([math.log(2 * math.pi * 41.0), 0.09])
STARTS = np.array([[math.log(2 * math.pi * f), z] for f in (30.0, 63.0, 90.0) for z in (0.005, 0.06, 0.2)])


@pytest.fixture(scope="module")
def spectrum():
    log = klipper_dataset([posicast.Mode.from_hz(42.0, 0.08), posicast.Mode.from_hz(63.0, 0.06)], gains=[0.6, 0.4],
                          seed=1)
    return resonance_data(log).spectrum


def test_batch_rows_are_single_evaluations(spectrum):
    """Every row of a batch (held poles + that row's pole) is the single evaluation of those poles, the
    Jacobian along the row's pole the single one's last two columns (to rounding: the design's condition number, ~4e4 here, times 1e-16)."""
    model = SpectralModel(spectrum)
    b = model.batch(HELD, STARTS)
    J = b.jacobian(range(STARTS.shape[0]))
    assert b.r.shape == (STARTS.shape[0], model.f.size) and J.shape == (STARTS.shape[0], model.f.size, 2)
    for c, x in enumerate(STARTS):
        r, jac = model.residual_and_jacobian_lazy(np.r_[HELD, x], first=HELD.size)
        assert np.max(np.abs(b.r[c] - r)) <= 1e-9 * np.max(np.abs(r))
        assert np.max(np.abs(J[c] - jac())) <= 1e-8 * np.max(np.abs(J[c]))
    two = model.batch(np.zeros(0), STARTS[[0, 4]].reshape(1, 4))  # two free poles in one row
    r, jac = model.residual_and_jacobian_lazy(STARTS[[0, 4]].ravel())
    assert np.max(np.abs(two.r[0] - r)) <= 1e-9 * np.max(np.abs(r))
    assert np.max(np.abs(two.jacobian([0])[0] - jac())) <= 1e-8 * np.max(np.abs(jac()))


def test_qr_basis_is_the_svd_projection(spectrum):
    """The QR basis spans what the SVD of the scaled design spans (same residual, same least-squares
    coefficients as numpy's lstsq); a rank-deficient design falls back to the truncated SVD (minimum norm)."""
    model = SpectralModel(spectrum)
    y = model.P * model.weights
    As, scale = model._scaled(model._poles(STARTS[[1, 4]].ravel()).inv_den, 5)
    for A in (As, np.hstack([As, As[:, :1]])):  # full rank; a repeated column
        b = model._basis(A, np.ones(A.shape[1]))
        U, sv, _ = np.linalg.svd(A, full_matrices=False)
        U = U[:, sv > 1e-12 * sv[0]]
        assert U.shape[1] == As.shape[1] and b.Q.shape == A.shape  # the repeated column: a zero column of Q
        assert np.linalg.matrix_rank(b.Q) == U.shape[1]
        assert np.max(np.abs(b.Q @ b.proj - U @ (U.T @ y))) < 1e-12 * np.max(np.abs(y))
        coef = b.pinv @ b.proj
        ref = np.linalg.lstsq(A, y, rcond=1e-12)[0]
        assert np.max(np.abs(coef - ref)) < 1e-9 * np.max(np.abs(ref))


@pytest.mark.parametrize("held", [HELD, np.zeros(0)])
def test_batched_levenberg_marquardt_is_each_fit_alone(spectrum, held):
    """The screen's fits side by side end where each fit run alone ends (the same steps, to rounding)."""
    model = SpectralModel(spectrum)
    lo, hi = pole_bounds(model, 1)
    lo, hi = lo + 1e-9, hi - 1e-9
    X, cost = spectral._levenberg_marquardt_batch(lambda X: model.batch(held, X), STARTS, lo, hi, max_iter=15,
                                                  rtol=1e-5)
    for c, x0 in enumerate(STARTS):
        x = spectral._levenberg_marquardt(lambda x: model.residual_and_jacobian_lazy(np.r_[held, x],
                                                                                     first=held.size),
                                          x0, lo, hi, max_iter=15, rtol=1e-5)
        assert np.max(np.abs(X[c] - x)) < 1e-9, (c, X[c], x)
        assert abs(cost[c] / np.sum(model.residual(np.r_[held, x]) ** 2) - 1) < 1e-9


@pytest.mark.parametrize("version", ["v0.13", "master"])
def test_vibration_grid_is_the_formula(version):
    """Seed 004 eq. 1-3 in complex double precision, ``|sum A_i e^{s (T_i - T_n)}|`` with ``s = zeta w + j w_d``,
    against the single-precision grid (the latest impulse's exponentials skipped; unsorted times take the
    general path), for every Klipper shaper type over a scan's frequencies."""
    from posicast.firmware import Klipper, vibration_grid

    rng = np.random.default_rng(3)
    bins, zetas = np.sort(rng.uniform(5.0, 200.0, 40)), np.array([0.0, 0.075, 0.15, 0.3])
    w = 2 * np.pi * bins[:, None]
    s = zetas[None, :] * w + 1j * w * np.sqrt(1 - zetas[None, :] ** 2)
    cases = [st.impulses(1.0, 0.1) for st in Klipper(version).types().values()]
    cases.append((rng.random(4), rng.random(4)))  # the last impulse is not the latest
    for A, T1 in cases:
        T = T1[None, :] / np.arange(20.0, 150.0, 1.3)[:, None]
        d = T - T.max(axis=1, keepdims=True)
        ref = np.abs(np.einsum("fi,fki->fk", A[None, :] / A.sum(), np.exp(s.reshape(-1)[None, :, None] * d[:, None, :])))
        V = vibration_grid(A, T, bins, zetas)
        assert np.max(np.abs(V.reshape(ref.shape) - ref)) < 2e-5  # float32 phases up to ~130 rad: ~1e-5


def test_flat_spectrum_refusal_names_the_lowest_bin(tmp_path):
    """A flat spectrum is explained exactly: every bin's excess is 1 to rounding, and the refusal names the
    lowest bin (not whichever bin rounding favours)."""
    flat = tmp_path / "resonances_x_flat.csv"
    flat.write_text("freq,psd_x,psd_y,psd_z,psd_xyz\n" + "".join(
        f"{1.5625 * k:.1f},1.000e+03,1.000e+03,1.000e+03,3.000e+03\n" for k in range(130)))
    with pytest.raises(posicast.identification.NoModeFound, match=r"largest excess 1x at 6\.2 Hz"):
        posicast.calibrate(flat)


def _lane_reference(x: np.ndarray, decay: np.ndarray, Ar: np.ndarray, m: int, width: int, last: float) -> np.ndarray:
    """The documented order of ``firmware.base._lane_sums``, written out: term ``i`` is
    ``(x_i decay_i) A_i`` (``A_i last`` from impulse ``m`` on), summed into partial sum ``i mod width`` in
    increasing ``i``, then ``(p0 + p1) + (p2 + p3)``; float32 throughout."""
    n = Ar.shape[1]
    terms = [(x[:, i] * decay[:, i]) * Ar[:, i, None] if i < m else
             np.broadcast_to(Ar[:, i, None] * np.float32(last), x[:, 0].shape) for i in range(n)]
    lanes = [np.zeros(x[:, 0].shape, np.float32) for _ in range(4)]
    for k in range(min(width, n)):
        lanes[k] = terms[k].copy()
        for i in range(k + width, n, width):
            lanes[k] = lanes[k] + terms[i]
    return (lanes[0] + lanes[1]) + (lanes[2] + lanes[3])


@pytest.mark.parametrize("layout", ["shared", "per_shaper", "one_shaper"])
def test_vibration_grid_sums_in_the_documented_order(layout):
    """Issue #15 (wave 6): the impulse sums on the long axis follow their documented order exactly (a
    rounding-level change flips a near-tie pick of the demo's synthetic log), and agree with the einsum
    formulation (``_einsum_sums``, kept for many impulses) to float32 rounding.  (On numpy 2.4 for x86-64
    the two are equal bit for bit, checked in wave 6; einsum's order is numpy's and the CPU's to choose,
    so that is not asserted here.)"""
    from posicast.firmware import base

    rng = np.random.default_rng(5)
    bins, zetas = np.sort(rng.uniform(5.0, 200.0, 37)), np.array([0.05, 0.1, 0.15])
    for n in range(1, 16):
        rows = 1 if layout == "one_shaper" else 40
        T = np.sort(rng.random((rows, n)), axis=1) / rng.uniform(20.0, 150.0, (rows, 1))
        A = rng.random(n) if layout != "per_shaper" else rng.random((rows, n))
        A = np.broadcast_to(A / A.sum(axis=-1, keepdims=True), T.shape)
        w = 2.0 * np.pi * bins[:, None]
        sigma = (zetas[None, :] * w).ravel().astype(np.float32)
        imag = (w * np.sqrt(1.0 - zetas[None, :] ** 2)).ravel().astype(np.float32)
        D = (T - T.max(axis=1, keepdims=True)).astype(np.float32)
        Ar = A.astype(np.float32)
        m = n - 1 if n > 1 else n
        decay = np.exp(D[:, :m, None] * sigma)
        phase = D[:, :m, None] * imag
        ref = base._einsum_sums(phase.copy(), decay, Ar, m)
        width = 1 if Ar.flags.f_contiguous and not Ar.flags.c_contiguous else 4
        got = [base._lane_sums(np.cos(phase), decay, Ar, m, width),
               base._lane_sums(np.sin(phase), decay, Ar, m, width, last=0.0)]
        for g, x, last in zip(got, (np.cos(phase), np.sin(phase)), (1.0, 0.0)):
            assert np.array_equal(g, _lane_reference(x, decay, Ar, m, width, last)), (layout, n)
        np.testing.assert_allclose(np.hypot(*got), np.hypot(*ref), rtol=0, atol=2e-6, err_msg=f"{layout} {n}")
        assert np.array_equal(base._vibration_grid(A, T, bins, zetas).reshape(rows, -1),
                              np.hypot(*got).astype(float)), (layout, n)


def test_excited_end_ignores_a_nan_bin():
    """The excited band's end is the first largest drop, from 60 Hz on, between the medians of the 6-bin
    windows before and from a bin: a PSD of 1 below 120 Hz and 1e-3 from it falls 1000x, first at 118 Hz
    (the window 118-123 Hz is already mostly low), so the band ends 2 bins earlier, at 116 Hz.  One NaN bin
    elsewhere (its windows' drops are NaN) does not hide that (the vectorised scan of wave 6 took argmax
    over NaN)."""
    from posicast.identification.resonance import _excited_end

    f = np.arange(0.0, 200.0, 1.0)
    P = np.where(f < 120.0, 1.0, 1e-3)
    P[70] = np.nan
    end, why = _excited_end(f, P)
    assert end == pytest.approx(118.0 - 2.0, abs=1e-12)
    assert "1000x" in why and "118 Hz" in why
