"""Every subcommand's ``--json`` (issue #20): one JSON document on stdout, its numbers those of the library call.

Each test runs the subcommand in this process, parses stdout with a strict parser (no NaN or
infinity) and compares with the same computation done through the Python API.
"""

import json
from importlib.metadata import version
from pathlib import Path

import numpy as np
import pytest

import posicast as pc
from posicast.analysis import insensitivity, sensitivity_curve
from posicast.cli import _build_parser, main
from posicast.io.export import export_shaper
from posicast.shapers import registry

REAL = Path(__file__).parent / "data" / "real"
PSD_FILE = REAL / "bassco_ender3_resonances_x_20210821.csv"


def _strict(text):
    return json.loads(text, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))


def _json(capsys, *argv, status=0):
    rc = main([*argv, "--json"])
    out, err = capsys.readouterr()
    assert rc == status, err
    return _strict(out)


def test_every_subcommand_has_json():
    """The parser itself: no subcommand (or sweep kind) without --json."""
    parser = _build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    missing = []
    for name, p in sub.choices.items():
        kinds = [a for a in p._actions if a.dest == "sweep"]
        parsers = kinds[0].choices.items() if kinds else [(name, p)]
        for nm, q in parsers:
            if not any("--json" in a.option_strings for a in q._actions):
                missing.append(nm)
    assert missing == []


def test_version_is_the_package_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out == f"posicast {version('posicast')}\n"


def test_design_json(capsys):
    data = _json(capsys, "design", "ei", "--freq-hz", "42", "--zeta", "0.08", "--vtol", "0.05")
    assert data == pc.design("ei", pc.Mode.from_hz(42.0, 0.08), vtol=0.05).to_dict()


def test_kinds_json(capsys):
    data = _json(capsys, "kinds")
    assert [d["kind"] for d in data] == list(registry.KINDS)
    assert {d["kind"]: d["summary"] for d in data}["zv"] == registry.KINDS["zv"].summary


def test_sensitivity_json_without_a_figure(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    data = _json(capsys, "sensitivity", "zv", "ei", "--omega", "5", "--zeta", "0.05", "--tol", "0.1")
    mode = pc.Mode(5.0, 0.05)
    for row, kind in zip(data["shapers"], ("zv", "ei")):
        S = pc.design(kind, mode)
        ins = insensitivity(S, 0.1, reference="end")
        assert row["kind"] == kind and row["duration"] == S.duration
        assert row["insensitivity"] == ins.width and row["band"] == [ins.low, ins.high]
        np.testing.assert_array_equal(row["vibration"], sensitivity_curve(S).vibration)
    assert data["out"] is None and list(tmp_path.iterdir()) == []


def test_export_json(capsys, tmp_path):
    data = _json(capsys, "export", "zvd", "--freq-hz", "28", "--zeta", "0.05", "--sample-rate", "1000",
                 "--format", "json")
    S = pc.design("zvd", pc.Mode.from_hz(28.0, 0.05))
    assert data["export"] == json.loads(export_shaper(S, 1000.0, "json"))
    assert data["shaper"] == S.to_dict() and data["output"] is None
    # C to a file: the file holds the C text, stdout the JSON document
    out = tmp_path / "zvd.h"
    data = _json(capsys, "export", "zvd", "--freq-hz", "28", "--zeta", "0.05", "--sample-rate", "1000",
                 "--output", str(out))
    assert data["export"] is None and data["output"] == str(out)
    assert out.read_text() == export_shaper(S, 1000.0, "c")


def test_identify_json(capsys, tmp_path):
    d = pc.testing.synthetic(pc.Mode.from_hz(28.0, 0.05), "random_binary", sample_rate=400.0, n=2000, noise=0.002,
                             seed=3)
    f = tmp_path / "io.csv"
    f.write_text("time,u,y\n" + "".join(f"{t!r},{u!r},{y!r}\n" for t, u, y in zip(d.t.tolist(), d.u.tolist(), d.y.tolist())))
    data = _json(capsys, "identify", str(f), "--input", "u", "--output", "y", "--modes", "1")
    ds = pc.identification.load_csv(f)
    r = pc.identify(ds.t, ds.column("u"), ds.column("y"), n_modes=1)
    assert data["method"] == "oe" and len(data["modes"]) == 1
    assert data["modes"][0]["omega"] == r.modes[0].omega and data["modes"][0]["zeta"] == r.modes[0].zeta
    assert data["modes"][0]["omega_95"] == list(r.intervals[0].omega)
    assert abs(data["modes"][0]["freq_hz"] - 28.0) < 0.5  # and it is the true mode


@pytest.mark.parametrize("method", ["arx", "freq"])
def test_identify_one_mode_methods_run_with_the_default_modes(method, capsys, tmp_path):
    """--modes defaults to 'auto', which only oe and psd can do; arx and freq (seed 002: one mode) used to
    stop with "n_modes='auto' is available for method='oe' and 'psd' only" unless --modes 1 was given."""
    d = pc.testing.synthetic(pc.Mode.from_hz(28.0, 0.05), "random_binary", sample_rate=400.0, n=2000, noise=0.002,
                             seed=3)
    f = tmp_path / "io.csv"
    f.write_text("time,u,y\n" + "".join(f"{t!r},{u!r},{y!r}\n" for t, u, y in zip(d.t.tolist(), d.u.tolist(), d.y.tolist())))
    data = _json(capsys, "identify", str(f), "--input", "u", "--output", "y", "--method", method)
    ds = pc.identification.load_csv(f)
    r = pc.identify(ds.t, ds.column("u"), ds.column("y"), n_modes=1, method=method)
    assert data["method"] == method and len(data["modes"]) == 1
    assert data["modes"][0]["omega"] == r.modes[0].omega and data["modes"][0]["zeta"] == r.modes[0].zeta


def test_calibrate_json_with_a_band(capsys):
    data = _json(capsys, "calibrate", str(PSD_FILE), "--band", "30", "60")
    cal = pc.calibrate([str(PSD_FILE)], band=(30.0, 60.0))
    assert data == _strict(json.dumps(cal.to_dict()))
    freqs = [m["freq_hz"] for m in data["files"][0]["modes"]]
    assert freqs and all(30.0 <= f <= 60.0 for f in freqs)
    # without the band the 118 Hz mode is found too: the band did restrict the search
    full = pc.calibrate([str(PSD_FILE)])
    assert any(m.freq_hz > 100.0 for m in full.modes)


def test_tune_json(capsys):
    data = _json(capsys, "tune", "--num", "1", "--den", "1 2 1", "--controller", "pi", "--ms", "1.4")
    r = pc.tune_pi(([1.0], [1.0, 2.0, 1.0]), ms=1.4)
    assert data["gains"]["kp"] == r.kp and data["gains"]["ki"] == r.ki and data["ms"] == r.ms
    assert data["stable"] is True


def test_qft_json(capsys):
    data = _json(capsys, "qft", "--uncertainty", "10", "--structure", "lead", status=1)  # one lead: infeasible
    r = pc.qft_design(pc.PlantSet.two_mass(10.0), pc.cases.ALL["two_mass"].extras["F_m"], stability=1.413,
                      matching=0.1, structure=("lead",))
    assert data["feasible"] is False and data["violated"] == list(r.violated) and r.violated
    assert data["high_frequency_gain"] == r.high_frequency_gain and data["margins"] == dict(r.margins)
    assert data["den"] == [float(x) for x in r.controller.to_scipy().den]


def test_sweep_json(capsys):
    data = _json(capsys, "sweep", "chart", "--gain", "0.5,0.9", "--delay-error=0", "--serial", "--quiet")
    from posicast.sweeps.charts import seed000_chart

    chart = seed000_chart([0.5, 0.9], [0.0], client="serial", progress=False)
    assert data["counts"] == {"ok": 2, "error": 0, "missing": 0}
    assert data["table"]["stable"] == [bool(x) for x in chart.result["stable"].ravel()]
    assert data["stability_edges"]["0.0"] == [float(k) for k in chart.stability_edges(0.0)]


LOOP_ARGS = ("--num", "1", "--den", "1 1 0", "--kp", "10", "--kd", "10", "--derivative-filter", "0.01",
             "--shaper", "zv", "--omega", "10", "--zeta", "0.03")


def _loop(architecture):
    C = pc.TransferFunction.from_poly([10.0 * 0.01 + 10.0, 10.0], [0.01, 1.0])  # 10 + 10 s / (0.01 s + 1)
    return pc.Loop(architecture, G=([1.0], [1.0, 1.0, 0.0]), C=C, S=pc.design("zv", pc.Mode(10.0, 0.03)))


def test_stability_json_of_a_loop(capsys):
    data = _json(capsys, "stability", *LOOP_ARGS, "--architecture", "inverse_shaper", "--roots", "4")
    loop = _loop("inverse_shaper")
    st, sa = loop.stability(), loop.spectral_abscissa()
    assert data["stable"] is False and data["stable"] == st.stable and data["kind"] == "neutral"
    assert data["reason"] == st.reason
    assert data["spectral_abscissa"]["value"] == float(sa) and data["spectral_abscissa"]["error"] == sa.error
    np.testing.assert_array_equal(np.array(data["rightmost"]) @ [1, 1j], loop.rightmost(4))
    assert len(data["unstable_roots"]) == 6  # seed 000's inverse ZV: three unstable pairs (README)


def test_stability_json_of_a_quasi_polynomial_system(capsys):
    """``--den "1 0; 1 @1"`` is s + e^{-s}: its rightmost pair is -0.3181 +- 1.3372j (Lambert W: W0(-1))."""
    data = _json(capsys, "stability", "--num", "1", "--den", "1 0; 1 @1", "--roots", "2")
    from scipy.special import lambertw

    w0 = complex(lambertw(-1.0, 0))
    got = np.array(data["rightmost"]) @ [1, 1j]
    np.testing.assert_allclose(sorted(got, key=lambda z: z.imag), [np.conj(w0), w0], rtol=1e-10)
    assert data["stable"] is True and data["loop"] is False and data["kind"] == "retarded"


def test_simulate_json_and_csv(capsys, tmp_path):
    out = tmp_path / "run.csv"
    data = _json(capsys, "simulate", *LOOP_ARGS, "--t-end", "4", "--dt", "0.01", "--sample-rate", "100",
                 "--disturbance", "2", "0.1", "--out", str(out))
    t = np.arange(401) * 0.01
    r = pc.simulate(_loop("control_action"), t, w=np.ones_like(t), d=0.1 * (t >= 2), sample_rate=100.0,
                    outputs=("u", "z", "y"))
    assert data["mode"] == "sampled" and data["steps"] == 401
    for s in ("w", "u", "z", "y"):
        assert data["final"][s] == float(r.signals[s][-1])
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    assert out.read_text().splitlines()[0] == "t,w,u,z,y"
    np.testing.assert_array_equal(table[:, 0], r.time)
    np.testing.assert_array_equal(table[:, 4], r.signals["y"])
    assert data["step_response"]["y"]["overshoot_percent"] == r.overshoot("y", start=0.0)
    assert data["step_response"]["z"]["settling_time"] == r.settling_time("z", start=0.0)
