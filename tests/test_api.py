"""One public surface (issue #14, part 1): every object answers the same spectral verbs, each with a
free-function twin; no function hides a module; one word per concept."""

from __future__ import annotations

import importlib
import pkgutil
import subprocess
import sys
import warnings

import numpy as np
import pytest

import posicast
from posicast import Mode, QuasiPolynomial, TransferFunction

REGION = (-6.0, 2.0, -40.0, 40.0)


def _plant() -> TransferFunction:
    return TransferFunction.from_poly([1.0], [1.0, 3.0, 2.0])  # 1 / ((s + 1)(s + 2))


# ------------------------------------------------------------------ each verb accepts each object
def test_poles_of_a_rational_plant_are_the_roots_of_its_denominator():
    G = _plant()
    for r in (posicast.poles(G, REGION), G.poles(REGION), posicast.roots(G, REGION)):
        assert isinstance(r, posicast.Roots)
        np.testing.assert_allclose(np.sort(r.roots.real), [-2.0, -1.0], atol=1e-12)  # analytic
    assert G.zeros(REGION).count == 0
    assert posicast.poles((np.array([1.0]), np.array([1.0, 3.0, 2.0])), REGION).count == 2  # (num, den) tuple


def test_zero_vibration_shaper_zeros_sit_on_the_modes_poles():
    # ZV for an undamped mode omega = 10: S(s) = (1 + e^{-s pi/10}) / 2, zeros at s = j 10 (2k + 1) (analytic)
    S = posicast.design("zv", Mode(10.0, 0.0))
    for z in (posicast.zeros(S, (-1, 1, 0, 60)), S.zeros((-1, 1, 0, 60))):
        np.testing.assert_allclose(z.roots, [10j, 30j, 50j], atol=1e-9)
    assert S.poles((-50, 50, -50, 50)).count == 0  # a lumped shaper is entire
    # a damped mode: the ZV zero is the mode's pole (seed 000: the shaper cancels the mode)
    m = Mode(10.0, 0.1)
    z = posicast.design("zv", m).zeros((-3, 1, 0, 12))
    assert abs(z.roots[0] - m.pole) < 1e-10


def test_distributed_shaper_removable_point_is_neither_pole_nor_zero():
    S = posicast.design("dzv", Mode(10.0, 0.03))
    c = posicast.spectra.characteristic_of(S)
    np.testing.assert_array_equal(c.removable, [0j])
    assert S.poles((-50, 50, -50, 50)).count == 0
    assert not np.any(np.abs(S.zeros((-5, 5, -25, 25)).roots) < 1e-6)
    assert S.transfer.removable_points().tolist() == [0j]


def test_loop_verbs_equal_the_characteristic_roots_less_the_cancelled_points():
    S = posicast.design("dzv", Mode(10.0, 0.03))
    loop = posicast.inverse_shaper(G=(1, [1, 1, 0]), C=([10, 10], [0.01, 1]), S=S)
    independent = posicast.spectra.rootfinder.roots(loop.characteristic, REGION, ignore=loop.cancelled)
    for r in (posicast.poles(loop, REGION), posicast.roots(loop, REGION)):
        np.testing.assert_array_equal(r.roots, independent.roots)
    st = posicast.stability(loop)
    assert st.stable == loop.stability().stable
    assert float(posicast.spectral_abscissa(loop)) == float(loop.spectral_abscissa())
    tf = loop.transfer("w", "y")
    z = posicast.zeros(loop, REGION, channel=("w", "y"))
    ref = posicast.spectra.rootfinder.roots(tf.num, REGION, ignore=loop.channel_cancelled("w", "y"))
    np.testing.assert_array_equal(z.roots, ref.roots)
    with pytest.raises(ValueError, match=r"channel=\(src, dst\)"):
        posicast.zeros(loop, REGION)


def test_rational_loop_poles_match_numpy():
    # no shaper, rational blocks: the closed-loop poles are the roots of den_G den_C + num_G num_C (numpy)
    loop = posicast.control_action(G=(1, [1, 1, 0]), C=([4.0, 2.0], [1.0]))
    expected = np.roots(np.polyadd(np.polymul([1, 1, 0], [1.0]), np.polymul([1], [4.0, 2.0])))
    got = posicast.poles(loop, (-10, 10, -10, 10)).roots
    np.testing.assert_allclose(np.sort_complex(got), np.sort_complex(expected), atol=1e-10)


def test_quasi_polynomial_methods_are_twins_of_the_free_functions():
    h = QuasiPolynomial([[1.0, 1.0], [0.5, 0.0]], [0.0, 1.0])  # s + 1 + 0.5 e^{-s}
    np.testing.assert_array_equal(h.roots(REGION).roots, posicast.roots(h, REGION).roots)
    assert h.stability().stable and posicast.stability(h).stable
    assert float(h.spectral_abscissa()) == float(posicast.spectral_abscissa(h))
    np.testing.assert_array_equal(h.rightmost(2), posicast.rightmost(h, 2))
    with pytest.raises(TypeError, match="no poles"):
        posicast.poles(h, REGION)


def test_stability_of_a_transfer_function_reads_its_poles():
    unstable = TransferFunction.from_poly([1.0], [1.0, -1.0])  # pole at +1
    st = posicast.stability(unstable)
    assert not st.stable and unstable.stability().reason == st.reason == "1 root with Re s >= 0, the rightmost at 1"
    assert round(float(_plant().spectral_abscissa()), 12) == -1.0


def test_unknown_object_is_refused_by_name():
    with pytest.raises(TypeError, match="must be a QuasiPolynomial, TransferFunction, Shaper, Loop"):
        posicast.poles("s + 1", REGION)


# ------------------------------------------------------------------ one word per concept
def test_dc_gain_is_a_property_everywhere():
    S = posicast.design("zvd", Mode(5.0, 0.05))
    assert S.dc_gain == pytest.approx(1.0, abs=1e-12)
    assert S.transfer.dc_gain == pytest.approx(1.0, abs=1e-12)
    assert _plant().dc_gain == 0.5
    with pytest.warns(FutureWarning):
        assert _plant().dc_gain() == 0.5


def test_residual_vibration_takes_a_mode_as_design_does():
    m = Mode(10.0, 0.1)
    S = posicast.design("zv", Mode(9.0, 0.1))
    assert posicast.residual_vibration(S, m) == posicast.residual_vibration(S, 10.0, 0.1)
    with pytest.raises(TypeError, match="zeta must be omitted"):
        posicast.residual_vibration(S, m, 0.1)
    with pytest.raises(TypeError, match="zeta is required"):
        posicast.residual_vibration(S, 10.0)


# ------------------------------------------------------------------ no function hides a module
def _modules():
    for info in pkgutil.walk_packages(posicast.__path__, "posicast."):
        if info.name.rsplit(".", 1)[-1] in ("__main__",):
            continue
        yield info.name


@pytest.mark.parametrize("name", list(_modules()))
def test_no_function_hides_a_module(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        module = importlib.import_module(name)
        parent_name, _, attr = name.rpartition(".")
        parent = importlib.import_module(parent_name)
    assert getattr(parent, attr) is module, f"{parent_name}.{attr} is {getattr(parent, attr)!r}, not the module"


def test_every_public_name_resolves():
    for name in posicast.__all__:
        assert getattr(posicast, name) is not None
    assert set(posicast.__all__) <= set(dir(posicast))


def test_lazy_table_and_type_checking_imports_agree():
    """posicast/__init__.py loads its names lazily (issue #15); its TYPE_CHECKING imports, read by type
    checkers, and ``__all__`` must name exactly the names of its lazy table."""
    import ast
    from pathlib import Path

    tree = ast.parse(Path(posicast.__file__).read_text(encoding="utf-8"))
    block = next(n for n in tree.body if isinstance(n, ast.If) and getattr(n.test, "id", "") == "TYPE_CHECKING")
    typed = {a.asname or a.name for n in block.body if isinstance(n, ast.ImportFrom) for a in n.names}
    assert typed == set(posicast._PUBLIC) == set(posicast.__all__)
    assert len(posicast.__all__) == len(set(posicast.__all__))


def test_import_posicast_loads_no_heavy_module():
    """``import posicast`` loads no submodule and neither scipy nor matplotlib (issue #15: start-up)."""
    code = ("import sys, posicast; heavy = [m for m in ('scipy', 'matplotlib', 'posicast.tune', 'posicast.spectra') "
            "if m in sys.modules]; print(heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_every_method_takes_its_functions_arguments():
    S = posicast.design("dzv", Mode(10.0, 0.03))
    assert S.stability(ignore=[0j]).stable == posicast.stability(S, ignore=[0j]).stable
    assert float(S.spectral_abscissa(ignore=[0j])) == float(posicast.spectral_abscissa(S, ignore=[0j]))
    np.testing.assert_array_equal(S.roots((-50, 50, -50, 50)).roots, posicast.poles(S, (-50, 50, -50, 50)).roots)
    h = QuasiPolynomial.from_poly([1.0, 2.0])  # s + 2: its zeros are its roots
    np.testing.assert_array_equal(h.zeros(REGION).roots, [-2.0 + 0j])


def test_a_pair_read_as_a_quasi_polynomial_says_so():
    with pytest.raises(ValueError, match=r"read here as a quasi-polynomial \(coeffs, delays\).*from_poly"):
        posicast.stability(([1.0], [1.0, 3.0, 2.0]))


def test_moved_reports_name_their_new_place():
    for get in (lambda: posicast.demo, lambda: posicast.tune.seed001, lambda: posicast.io.Report):
        with pytest.raises(AttributeError, match="posicast_reports"):
            get()


def test_one_word_for_the_sample_rate_and_the_shaper_argument():
    """sample_rate (simulation's word) in identification and testing too; S (the loops' word) in analysis too."""
    from posicast import testing

    new = testing.synthetic(Mode(30.0, 0.05), "step", sample_rate=200.0, n=100, seed=1)
    assert new.sample_rate == 200.0
    with pytest.warns(FutureWarning, match="fs= is now sample_rate="):
        old = testing.synthetic(Mode(30.0, 0.05), "step", fs=200.0, n=100, seed=1)
    np.testing.assert_array_equal(old.y, new.y)
    with pytest.warns(FutureWarning, match="fs is now"):
        assert old.fs == 200.0
    S = posicast.design("zv", Mode(9.0, 0.1))
    with pytest.warns(FutureWarning, match="shaper= is now S="):
        assert posicast.residual_vibration(shaper=S, omega=10.0, zeta=0.1) == posicast.residual_vibration(S, 10.0, 0.1)
    with pytest.raises(TypeError, match="give S only"):
        posicast.residual_vibration(S=S, omega=10.0, zeta=0.1, shaper=S)
