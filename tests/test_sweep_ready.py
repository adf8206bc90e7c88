"""The ready-made sweeps (issue #19, item 4): stability chart vs D-decomposition, seed 003 Monte Carlo,
a folder of calibration logs.

References: the D-decomposition boundary (the tuner's curves, refined exactly) checked by the
characteristic's value on the imaginary axis and by bisection of the certified verdict; the
two-mass loop's closed-loop poles from numpy (the shaper sits outside the loop, so the
characteristic is a polynomial); :func:`posicast.calibrate` run directly.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import posicast
from posicast.cases import TWO_MASS_UNCERTAINTY, modes_of, two_mass_plant
from posicast.sweeps.charts import gain_breaks, seed000_chart, seed000_loop
from posicast.sweeps.farm import calibration_table
from posicast.spectra.verdict import unstable_count
from posicast.sweeps.montecarlo import TWO_MASS_RANGES, two_mass_grid, two_mass_monte_carlo

REAL = Path(__file__).resolve().parent / "data" / "real"


# ---------------------------------------------------------------------- stability chart
def test_seed000_chart_agrees_with_the_d_decomposition_to_the_grid_resolution() -> None:
    gains = np.linspace(0.05, 1.5, 16)
    chart = seed000_chart(gains, [-0.5, 0.0, 0.5], client="serial")
    assert chart.result.complete
    assert chart.disagreements() == []
    step = gains[1] - gains[0]
    for i, e in enumerate([-0.5, 0.0, 0.5]):
        stable = chart.result["stable"][:, i]
        assert stable[0] and not stable[-1]
        edges = chart.stability_edges(e)
        assert len(edges) == 1  # one stable interval from small gains up to the boundary
        # the chart's last stable grid gain is within one step below the boundary
        last = gains[np.flatnonzero(stable)[-1]]
        assert 0 < edges[0] - last <= step
        # the boundary is the first positive crossing of the D-decomposition
        br = chart.breaks[i]
        first = br.gain[(br.gain > 0) & (br.kind == "c")][0]
        assert edges[0] == first


def test_d_decomposition_boundary_is_a_root_on_the_axis_and_the_bisected_verdict() -> None:
    br = gain_breaks(seed000_loop(1.0, 0.0), (0.05, 1.5))
    k, w = float(br.gain[0]), float(br.omega[0])
    assert br.kind[0] == "c" and k == pytest.approx(0.7948368, abs=1e-6)
    chi = seed000_loop(k, 0.0).characteristic
    scale = max(abs(chi(1j * w * f)) for f in (0.9, 1.1))
    assert abs(chi(1j * w)) < 1e-9 * scale  # a root exactly on the imaginary axis at j omega
    lo, hi = 0.7, 0.9  # bisect the certified verdict: the boundary is where it flips
    while hi - lo > 1e-4:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if posicast.stability(seed000_loop(mid, 0.0)).stable else (lo, mid)
    assert lo <= k <= hi


def test_chart_refuses_a_loop_whose_controller_does_not_scale_with_the_gain() -> None:
    from posicast.sweeps.charts import stability_chart

    def offset(gain: float, delay_error: float) -> posicast.Loop:
        return seed000_loop(1.0 + gain, delay_error)

    with pytest.raises(ValueError, match="must be k times a fixed controller"):
        stability_chart(offset, {"gain": [0.5], "delay_error": [0.0]}, client="serial")


def test_gain_breaks_bad_window() -> None:
    with pytest.raises(ValueError, match="low < high"):
        gain_breaks(seed000_loop(), (1.0, 0.5))
    with pytest.raises(ValueError, match="delay_error must be in"):
        seed000_loop(1.0, -1.0)


# ---------------------------------------------------------------------- seed 003 Monte Carlo
def _poles_stable(c1: float, c2: float, k2: float) -> bool:
    """Closed-loop poles of P C / (1 + P C) from numpy: with the shaper in front of the loop (feedforward)
    the characteristic is a polynomial."""
    C = posicast.cases.ALL["two_mass"].C.to_scipy()
    P = two_mass_plant(c1, c2, k2).to_scipy()
    char = np.polyadd(np.polymul(C.den, P.den), np.polymul(C.num, P.num))
    return bool(np.max(np.roots(char).real) < 0)


def test_two_mass_grid_matches_independent_poles_and_cancels_the_nominal_mode() -> None:
    r = two_mass_grid(architecture="feedforward", simulate_step=False, client="serial")
    assert r.shape == (3, 3, 3) and r.complete
    for idx in np.ndindex(r.shape):
        c1, c2, k2 = (TWO_MASS_UNCERTAINTY[n][i] for n, i in zip(("c1", "c2", "k2"), idx))
        assert bool(r["stable"][idx]) == _poles_stable(c1, c2, k2) == (r["abscissa"][idx] < 0)
        assert r["mode_hz"][idx] == pytest.approx(modes_of(two_mass_plant(c1, c2, k2))[0].freq_hz, rel=1e-12)
    assert r["vibration"].ravel()[13] == pytest.approx(0.0, abs=1e-12)  # index 13: the nominal plant
    assert int(np.argmin(r["vibration"])) == 13 and np.all(r["vibration"].ravel()[[0, 26]] > 1e-2)
    assert not np.all(r["stable"])  # the PI alone does not hold the 27 plants (seed 003 Fig. 9's warning)


def test_two_mass_monte_carlo_in_the_loop_draws_within_the_ranges() -> None:
    r = two_mass_monte_carlo(4, seed=7, client="serial", batch_size=2)  # seed 003's shaper inside the loop
    assert r.shape == (4,) and r.complete
    for name, (lo, hi) in TWO_MASS_RANGES.items():
        assert np.all((r[name] >= lo) & (r[name] <= hi))
    for i in range(4):  # the root search's verdict against the argument principle's count (another method)
        loop = posicast.control_action(G=two_mass_plant(r["c1"][i], r["c2"][i], r["k2"][i]),
                                       C=posicast.cases.ALL["two_mass"].C, S=posicast.design(
                                           "zvdk", posicast.cases.ALL["two_mass"].mode, k=2))
        count = unstable_count(loop.characteristic, ignore=loop.cancelled)
        assert bool(r["stable"][i]) == (count == 0) == (r["abscissa"][i] < 0)
    ok = r["stable"]
    assert np.all(np.isfinite(r["overshoot"][ok])) and np.all(r["settling_time"][ok] > 0)
    assert np.all(np.isnan(r["overshoot"][~ok]))
    assert np.all(r["ms"] > 1.0)  # ||S||inf >= 1 for a loop gain that decays (Bode's integral)


# ---------------------------------------------------------------------- calibration farm
def test_folder_of_calibration_logs_to_one_table(tmp_path: Path) -> None:
    names = ["bassco_ender3_resonances_x_20210821.csv"]
    for nm in names:
        shutil.copy(REAL / nm, tmp_path / nm)
    (tmp_path / "broken_resonances_x.csv").write_text("hello world\n")
    r = calibration_table(tmp_path, client="serial", store=tmp_path / "farm.zarr")
    assert r.status.tolist() == ["ok", "error"]
    assert r.errors[1].startswith("ValueError: ") and r.errors[1].endswith("no data rows after the header (line 1)")
    assert r.errors[0] == ""
    direct = posicast.calibrate(str(tmp_path / names[0]))
    best = direct.recommendations[0].best
    assert r["shaper_type"][0] == best.setting.shaper_type.name and r["shaper_freq"][0] == best.setting.freq
    assert r["axis"][0] == "x" and r["modes"][0] == len(direct.modes)
    r.to_csv(tmp_path / "farm.csv")
    assert (tmp_path / "farm.csv").read_text().count("\n") == 3
    with pytest.raises(ValueError, match="no file matching"):
        calibration_table(tmp_path, "*.log", client="serial")


def test_readme_sweep_example_runs() -> None:
    text = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    start = text.index("from posicast.sweeps.charts import seed000_chart")
    block = text[text.rindex("```python", 0, start) + len("```python"): text.index("```", start)]
    exec(compile("\n".join(line[2:] for line in block.splitlines()), "README.md", "exec"), {})


def test_report_section_rows_agree(tmp_path: Path) -> None:
    from posicast_reports.html import Report
    from posicast_reports.sweep_report import sweep_section

    report = Report("t", tmp_path)
    sweep_section(report)
    page = report.write().read_text(encoding="utf-8")
    assert "0 disagreements" in page and page.count(">yes<") == 5 and ">NO<" not in page
