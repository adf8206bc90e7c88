"""The library's plots (issue #20): every ``*_plot`` returns ``(fig, ax)`` or ``(fig, axes)``, labels give
legends, the Bode phase is continuous and exact for delays, the Nyquist plot is zoomed on -1."""

import importlib
import inspect
import pkgutil

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

import posicast as pc  # noqa: E402
from posicast.core.transfer import delay  # noqa: E402
from posicast.loops.plots import NYQUIST_ZOOM, bode_plot, nyquist_plot, unwrapped_phase  # noqa: E402


def _plot_functions():
    """Every public module-level function named ``*_plot`` in the package, by qualified name."""
    found = {}
    for info in pkgutil.walk_packages(pc.__path__, "posicast."):
        if info.name == "posicast.__main__":  # runs the command line
            continue
        mod = importlib.import_module(info.name)
        for name, obj in vars(mod).items():
            if name.endswith("_plot") and not name.startswith("_") and inspect.isfunction(obj) \
                    and obj.__module__ == info.name:
                found[f"{info.name}.{name}"] = obj
    return found


def _loop():
    S = pc.design("dzv", pc.Mode(10.0, 0.03))
    return pc.inverse_shaper(G=([1], [1, 1, 0]), F=([1, 0], [1, 0.6, 100]), C=([10, 10], [0.01, 1]), S=S)


def _calibration():
    from posicast.identification import calibrate
    from pathlib import Path

    return calibrate([str(Path(__file__).parent / "data" / "real" / "bassco_ender3_resonances_x_20210821.csv")],
                     band=(30.0, 60.0))


def _identification():
    d = pc.testing.synthetic(pc.Mode.from_hz(28.0, 0.05), "random_binary", sample_rate=400.0, n=800, seed=1)
    return pc.identify(d.t, d.u, d.y, n_modes=1), d


def _sweep():
    return pc.sweep(lambda a, b: a * b, {"a": [1.0, 2.0], "b": [3.0, 4.0]}, client="serial", progress=False)


def _tuned():
    return pc.tune_pi(([1.0], [1.0, 2.0, 1.0]), ms=1.4)


# how to call each plot function (a new *_plot without a line here fails test_every_plot_function_is_walked)
CALLS = {
    "posicast.analysis.plots.sensitivity_plot": lambda f: f([pc.design("zv", pc.Mode(1.0, 0.0))]),
    "posicast.analysis.plots.impulse_plot": lambda f: f(pc.design("zvd", pc.Mode(1.0, 0.1))),
    "posicast.loops.plots.bode_plot": lambda f: f(_loop(), omega=np.logspace(-1, 2, 100)),
    "posicast.loops.plots.nyquist_plot": lambda f: f(_loop(), omega=np.logspace(-1, 2, 100)),
    "posicast.loops.plots.spectrum_plot": lambda f: f(_loop(), (-6.0, 2.0, -30.0, 30.0)),
    "posicast.tune.plots.region_plot": lambda f: f(_tuned()),
    "posicast.tune.plots.regions_plot": lambda f: f([_tuned()], labels=["PI"]),
    "posicast.tune.plots.tuning_nyquist_plot": lambda f: f(_tuned()),
    "posicast.identification.plots.fit_plot": lambda f: f(_identification()[0], y=_identification()[1].y),
    "posicast.identification.plots.calibration_plot": lambda f: f(_calibration()),
}


def _is_axes_result(res):
    if not (isinstance(res, tuple) and len(res) == 2 and isinstance(res[0], Figure)):
        return False
    ax = res[1]
    if isinstance(ax, Axes):
        return True
    axes = [a for a in np.ravel(np.asarray(ax, dtype=object)) if a is not None]
    return bool(axes) and all(isinstance(a, Axes) for a in axes)


def test_every_plot_function_is_walked():
    assert set(_plot_functions()) == set(CALLS)


@pytest.mark.parametrize("name", sorted(CALLS))
def test_every_plot_function_returns_the_figure_and_its_axes(name):
    res = CALLS[name](_plot_functions()[name])
    assert _is_axes_result(res), f"{name} returned {type(res).__name__}"
    plt.close("all")


def test_plot_methods_return_the_figure_and_its_axes():
    t = np.arange(0, 2, 0.01)
    resp = pc.simulate(pc.feedforward(G=([1], [1, 1]), C=2.0), t, w=np.ones_like(t))
    r = _tuned()
    for res in (resp.plot(), pc.sensitivity_curve(pc.design("zv", pc.Mode(2.0, 0.0))).plot(), r.plot(),
                r.nyquist_plot(), r.region.plot(), _sweep().plot("value")):
        assert _is_axes_result(res)
    plt.close("all")


def test_labels_give_legends():
    t = np.arange(0, 2, 0.01)
    loop = pc.feedforward(G=([1], [1, 1]), C=2.0)
    resp = pc.simulate(loop, t, w=np.ones_like(t))
    fig, axes = resp.plot(["y", "u"], label="P = 2")
    resp2 = pc.simulate(pc.feedforward(G=([1], [1, 1]), C=4.0), t, w=np.ones_like(t))
    resp2.plot(["y", "u"], axes=axes, label="P = 4")
    for ax in axes:
        assert [x.get_text() for x in ax.get_legend().get_texts()] == ["P = 2", "P = 4"]
    assert resp.plot(["y"])[1][0].get_legend() is None  # no label, no legend
    fig, ax = pc.sweeps.plots.histogram(_sweep(), "value", label="a b")
    assert [x.get_text() for x in ax.get_legend().get_texts()] == ["a b"]
    plt.close("all")


def _rational_phase(num_roots, den_roots, w):
    """Continuous phase of prod(j w - z) / prod(j w - p): each factor's angle is continuous in w for a
    root off the imaginary axis (left: in (-pi/2, pi/2); right: pi - atan((w - Im)/Re))."""
    def factor(r):
        a, b = -r.real, w - r.imag  # j w - r = a + j b
        return np.arctan2(b, a) if a > 0 else np.pi - np.arctan2(b, -a)
    return sum(factor(z) for z in num_roots) - sum(factor(p) for p in den_roots)


@pytest.mark.parametrize("tau", [0.1, 0.5, 2.0])
def test_bode_phase_of_a_delay_system_is_the_analytic_phase(tau):
    """G = e^{-s tau} (s + 2) / ((s^2 + 0.4 s + 100)(s + 1)): the phase is -w tau plus the rational part's,
    to 1e-9, on the 2000-point grid where np.unwrap jumped by 2 pi (issue #20: near 4-10 krad/s)."""
    num, den = [1.0, 2.0], np.polymul([1.0, 0.4, 100.0], [1.0, 1.0])
    G = pc.as_transfer((num, den)) * delay(tau)
    w = np.logspace(-2, 4, 2000)
    exact = -w * tau + _rational_phase(np.roots(num), np.roots(den), w)
    ph = unwrapped_phase(G, w)
    assert np.max(np.abs(ph - exact)) < 1e-9
    old = np.unwrap(np.angle(G.freqresp(w)))
    assert np.max(np.abs(old - exact)) > 6.0  # the old way did jump
    fig, (am, ap) = bode_plot(G, omega=w)
    np.testing.assert_allclose(ap.lines[0].get_ydata(), np.degrees(exact), rtol=0, atol=1e-7)
    plt.close(fig)


def test_phase_of_an_unstable_zero_and_a_loop_channel_is_continuous():
    num, den = [1.0, -3.0], [1.0, 0.2, 25.0]  # a right-half-plane zero
    G = pc.as_transfer((num, den)) * delay(0.5)
    w = np.geomspace(0.01, 3e3, 700)
    exact = -0.5 * w + _rational_phase(np.roots(num), np.roots(den), w)
    assert np.max(np.abs(unwrapped_phase(G, w) - exact)) < 1e-9
    # a loop channel with a lumped shaper inside (several delays): steps stay below pi on a fine grid too
    H = _loop().transfer("w", "y")
    coarse = np.geomspace(0.1, 1e4, 300)
    fine = np.geomspace(0.1, 1e4, 299 * 1000 + 1)  # fine[::1000] is the coarse grid
    np.testing.assert_allclose(unwrapped_phase(H, coarse), unwrapped_phase(H, fine)[::1000], atol=1e-8)
    with pytest.raises(ValueError, match="increasing"):
        unwrapped_phase(G, [2.0, 1.0])
    with pytest.raises(TypeError, match="H must be"):
        unwrapped_phase("G", w)


def test_nyquist_plot_is_zoomed_on_the_critical_point_with_the_ms_circle():
    loop = pc.control_action(G=([1], [1, 1, 0]), C=([10, 10], [0.01, 1]))  # an integrator: |L| -> inf
    fig, ax = nyquist_plot(loop, ms=2.0)
    assert ax.get_xlim() == (-1 - NYQUIST_ZOOM, -1 + NYQUIST_ZOOM) and ax.get_ylim() == (-NYQUIST_ZOOM, NYQUIST_ZOOM)
    circle = next(ln for ln in ax.lines if ln.get_label() == "Ms = 2")
    assert abs(circle.get_xdata().max() + 0.5) < 1e-3  # centre -1, radius 1/2
    assert any(t.get_text() == "Ms = 2" for t in ax.texts)  # labelled beside the circle
    fig, ax = nyquist_plot(loop, ms=2.0, zoom=False)
    assert max(np.abs(ax.get_ylim())) > 100  # autoscaled: the curve goes far (Im L -> -inf at 0)
    fig, ax = nyquist_plot(loop, ms=2.0, zoom=1.0)
    assert ax.get_xlim() == (-2.0, 0.0)
    with pytest.raises(ValueError, match="zoom"):
        nyquist_plot(loop, zoom=-1.0)
    plt.close("all")


def test_readme_plots_example_runs():
    import doctest
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    block = next(b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "unwrapped_phase" in b)
    test = doctest.DocTestParser().get_doctest(block, {}, "README plots", "README.md", 0)
    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
    runner.run(test)
    assert runner.failures == 0 and runner.tries >= 4
