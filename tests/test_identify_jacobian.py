"""Issue #15 (part B): the output-error fit's closed-form Jacobian and its shortcuts on long records."""

from __future__ import annotations

import math

import numpy as np
import pytest

import posicast
from posicast.identification import output_error
from posicast.identification.fit_statistics import numerical_jacobian
from posicast.identification.output_error import OEModel
from posicast.testing import synthetic

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
