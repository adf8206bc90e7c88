"""The designer's JSON API (posicast serve, issue #20) through Starlette's TestClient, no browser.

Every endpoint answers what the library computes for the same input (the page only displays),
and every hostile input is an HTTP 400 whose one line is the library's own message.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from starlette.testclient import TestClient

import posicast as pc
from posicast.identification import Interval
from posicast.identification.recommend import mode_boxes, recommend_setting
from posicast.firmware import Klipper
from posicast.serve import app as app_module
from posicast.serve.app import create_app
from posicast.simulation.streaming import discretize
from posicast.testing.synthetic_data import klipper_log, klipper_resonances, synthetic

ROOT = Path(__file__).resolve().parents[1]
PSD = ROOT / "tests" / "data" / "real" / "bassco_v24_calibration_data_y_20230306.csv"  # Klipper calibration_data


@pytest.fixture(scope="module")
def client():
    return TestClient(create_app())


def _upload(path: Path, **fields):
    return {"file": {"name": path.name, "text": path.read_text()}, **fields}


def _error(resp) -> str:
    assert resp.status_code == 400, resp.text
    body = resp.json()
    assert set(body) == {"error"} and "\n" not in body["error"]
    return body["error"]


def _raised(func, *args, **kw) -> str:
    with pytest.raises((ValueError, TypeError)) as exc:
        func(*args, **kw)
    return str(exc.value)


# ---------------------------------------------------------------- page and menus
def test_the_page_and_its_assets_are_served_from_the_package(client):
    page = client.get("/")
    assert page.status_code == 200 and "text/html" in page.headers["content-type"]
    for tab in ("tab-machine", "tab-design", "tab-loop", "m-config", "d-impulses", "l-verdict"):
        assert f'id="{tab}"' in page.text
    for asset in ("/static/app.js", "/static/style.css"):
        r = client.get(asset)
        assert r.status_code == 200 and len(r.text) > 1000
    assert "http://" not in page.text and "https://" not in page.text  # no CDN: nothing from the internet
    assert client.get("/static/nothing.js").status_code == 404


def test_kinds_lists_the_library_kinds_firmwares_and_architectures(client):
    info = client.get("/api/kinds").json()
    assert [k["kind"] for k in info["kinds"]] == list(pc.KINDS)
    assert {k["kind"] for k in info["kinds"] if k["sampled"]} == {"zv", "zvd", "zvdd", "zvddd", "zvdk"}
    assert info["architectures"] == ["feedforward", "control_action", "inverse_shaper", "model_matching"]
    assert "kalico" in info["firmwares"] and info["version"] == pc.__version__


# ---------------------------------------------------------------- machine
def test_machine_psd_file_gives_the_calibrate_config(client):
    r = client.post("/api/machine", json=_upload(PSD))
    assert r.status_code == 200, r.text
    out = r.json()
    cal = pc.calibrate(str(PSD))
    assert out["config"] == "\n".join(cal.config)
    modes = out["files"][0]["modes"]
    assert [m["freq_hz"] for m in modes] == pytest.approx([m.freq_hz for m in cal.modes], rel=1e-12)
    assert [x for m in modes for x in m["freq_hz_95"]] == pytest.approx(
        [x for iv in cal.intervals for x in iv.freq_hz], rel=1e-12)
    rec = out["recommendations"][0]
    lib = cal.recommendations[0]
    assert [c["type"] for c in rec["candidates"] if not c["own_tool"] or c["recommended"]][:len(lib.per_type)] \
        == [c.setting.shaper_type.written for c in lib.per_type.values()][:len(lib.per_type)]
    best = next(c for c in rec["candidates"] if c["recommended"])
    assert best["freq_hz"] == lib.best.setting.freq and best["smoothing_mm"] == pytest.approx(lib.best.smoothing)
    assert best["max_accel"] == pytest.approx(lib.best.max_accel)
    assert out["files"][0]["axis"] == "y" and out["files"][0]["name"] == PSD.name
    assert out["plots"]["psd"].lstrip().startswith("<?xml") and "frequency [Hz]" in out["plots"]["candidates"]


@pytest.mark.parametrize("choice, kw", [("kalico", {"klipper_version": "kalico"}),
                                        ("marlin", {"firmware": "marlin"}),
                                        ("reprapfirmware", {"firmware": "reprapfirmware"})])
def test_machine_firmware_choices_are_calibrate_options(client, choice, kw):
    out = client.post("/api/machine", json=_upload(PSD, firmware=choice)).json()
    assert out["config"] == "\n".join(pc.calibrate(str(PSD), **kw).config)


def test_machine_raw_accelerometer_log(client, tmp_path):
    path = klipper_log(tmp_path / "raw_x.csv", pc.Mode.from_hz(42.0, 0.06), seed=1, max_freq=90.0, hz_per_sec=2.0)
    out = client.post("/api/machine", json=_upload(path, axis="x")).json()
    cal = pc.calibrate(str(path), axis="x")
    assert out["config"] == "\n".join(cal.config)
    assert out["files"][0]["kind"] == cal.files[0].kind
    assert out["files"][0]["modes"][0]["freq_hz"] == pytest.approx(42.0, rel=0.02)  # the simulated mode


def test_machine_several_files_are_calibrated_together(client):
    x, y = (ROOT / "tests" / "data" / "real" / f"bassco_v0_resonances_{a}_20220703.csv" for a in "xy")
    body = {"files": [{"name": p.name, "text": p.read_text()} for p in (x, y)]}
    out = client.post("/api/machine", json=body).json()
    cal = pc.calibrate([str(x), str(y)])
    assert out["config"] == "\n".join(cal.config) and "shaper_type_x" in out["config"] and "shaper_type_y" in out["config"]
    assert [f["name"] for f in out["files"]] == [x.name, y.name] and [f["axis"] for f in out["files"]] == ["x", "y"]
    assert [r["axis"] for r in out["recommendations"]] == ["x", "y"]


def test_machine_typed_modes_are_scored_over_their_boxes(client):
    out = client.post("/api/machine", json={"modes": "45 0.05\n90 0.03", "margin": "0.1", "axis": "y"}).json()
    modes = [pc.Mode.from_hz(45, 0.05), pc.Mode.from_hz(90, 0.03)]
    zero = [Interval((m.omega, m.omega), (m.zeta, m.zeta)) for m in modes]
    rec = recommend_setting(Klipper(), mode_boxes(modes, zero, None, 0.1), None, axis="y", margin=0.1)
    assert out["config"] == "\n".join(rec.config) and "shaper_type_y" in out["config"]
    assert "psd" not in out["plots"] and "candidates" in out["plots"]


def test_machine_hostile_inputs_answer_400_with_the_message(client, tmp_path):
    assert _error(client.post("/api/machine", json={"file": {"name": "x.csv", "text": ""}})) == \
        "x.csv: the file is empty"
    text = "hello,world\nthis,is not a log\n"
    (tmp_path / "notes.csv").write_text(text)
    lib = _raised(pc.calibrate, str(tmp_path / "notes.csv"))
    got = _error(client.post("/api/machine", json={"file": {"name": "notes.csv", "text": text}}))
    assert got == lib.splitlines()[0].replace(str(tmp_path / "notes.csv"), "notes.csv")
    bad = {"nan 0.05": "modes line 1: frequency must be finite, got nan",
           "-5 0.05": "modes line 1: frequency must be > 0, got -5",
           "45 1.0": "modes line 1: damping must be in [0, 1), got 1 (an underdamped mode)",
           "9e5 0.05": "modes line 1: frequency must be <= 100000 Hz for a firmware's shaper, got 900000",
           "45": "modes line 1 must be 'frequency_Hz damping', got '45'",
           "": "modes must be one 'frequency_Hz damping' pair per line, got nothing",
           "\n".join(["45 0.05"] * 7): "modes: at most 6 modes, got 7"}
    for modes, msg in bad.items():
        assert _error(client.post("/api/machine", json={"modes": modes})) == msg
    assert _error(client.post("/api/machine", json={"modes": "45 0.05", "firmware": "grbl"})).startswith(
        "firmware must be one of")
    assert _error(client.post("/api/machine", json={"modes": "45 0.05", "margin": "0.7"})) == \
        _raised(pc.calibrate, str(PSD), margin=0.7)
    assert _error(client.post("/api/machine", json={"file": {"name": "a.csv", "text": 3}})) == \
        "file text must be a string, got int"
    assert _error(client.post("/api/machine", json={"files": []})) == "files must have at least 1 entry, got 0"
    many = [{"name": f"f{k}_x.csv", "text": "1"} for k in range(17)]
    assert _error(client.post("/api/machine", json={"files": many})) == "files: at most 16 files at once, got 17"


def test_machine_no_resonance_is_a_message(client, tmp_path):
    path = klipper_log(tmp_path / "quiet_x.csv", [], seed=2, test="none")
    lib = _raised(pc.calibrate, str(path))
    assert _error(client.post("/api/machine", json=_upload(path))) == lib.splitlines()[0].replace(str(path), path.name)
    # a PSD file of noise alone: the library's message is about the spectrum; the page adds which file
    psd = klipper_resonances(tmp_path / "resonances_x_quiet.csv", [], test="none", seed=3)
    lib = _raised(pc.calibrate, str(psd))
    assert lib.startswith("no resonance found in 6.2-134.4 Hz")
    assert _error(client.post("/api/machine", json=_upload(psd))) == "resonances_x_quiet.csv: " + lib.splitlines()[0]


# ---------------------------------------------------------------- design
def _design(client, kind="zvd", modes=((40.0, 0.05),), **fields):
    body = {"kind": kind, "modes": [{"freq_hz": str(f), "zeta": str(z)} for f, z in modes], **fields}
    return client.post("/api/design", json=body)


def test_design_impulses_insensitivity_and_z_plane_taps(client):
    out = _design(client, "zvd", ((45.0, 0.05),), sample_rate="1000").json()
    S = pc.design("zvd", pc.Mode.from_hz(45.0, 0.05))
    assert np.array(out["impulses"]) == pytest.approx(np.column_stack(S.impulses), rel=1e-15, abs=1e-15)
    ins = pc.insensitivity(S, 0.05)
    assert out["insensitivity"][0]["width"] == pytest.approx(ins.width, rel=1e-12)
    Z = pc.design("zvd", pc.Mode.from_hz(45.0, 0.05), sample_period=1e-3)  # seed 002 eq. 8
    rows = np.array(out["taps"]["rows"])
    assert rows[:, 0].tolist() == np.rint(Z.impulses[0] * 1000).tolist()
    assert rows[:, 2] == pytest.approx(Z.impulses[1], rel=1e-15)
    assert "z-plane" in out["taps"]["method"] and out["taps"]["sum"] == pytest.approx(1.0, abs=1e-12)
    svg = out["plots"]["sensitivity"]
    assert "mode frequency [Hz]" in svg and "residual vibration [%]" in svg


def test_design_parameters_two_modes_and_discretised_taps(client):
    out = _design(client, "ei", ((40.0, 0.05),), params={"vtol": "0.1"}, sample_rate="2000").json()
    S = pc.design("ei", pc.Mode.from_hz(40.0, 0.05), vtol=0.1)
    assert np.array(out["impulses"]) == pytest.approx(np.column_stack(S.impulses), rel=1e-12)
    D = discretize(S, 2000.0)
    idx = np.flatnonzero(D.taps)
    assert [r[0] for r in out["taps"]["rows"]] == idx.tolist()
    assert [r[2] for r in out["taps"]["rows"]] == pytest.approx(D.taps[idx].tolist(), rel=1e-15)
    two = _design(client, "zv", ((40.0, 0.05), (95.0, 0.02))).json()  # convolution of the per-mode designs
    S2 = pc.design("zv", pc.Mode.from_hz(40.0, 0.05)) * pc.design("zv", pc.Mode.from_hz(95.0, 0.02))
    assert np.array(two["impulses"]) == pytest.approx(np.column_stack(S2.impulses), rel=1e-12)
    assert [b["residual"] for b in two["insensitivity"]] == pytest.approx([0.0, 0.0], abs=1e-12)
    si = _design(client, "si", ((40.0, 0.05), (95.0, 0.02)), params={"vtol": "0.05"}).json()  # one design over both
    Ssi = pc.design("si", [pc.Mode.from_hz(40.0, 0.05), pc.Mode.from_hz(95.0, 0.02)], vtol=0.05)
    assert np.array(si["impulses"]) == pytest.approx(np.column_stack(Ssi.impulses), rel=1e-9, abs=1e-12)
    notch = _design(client, "notch").json()  # an IIR part: vibration against the unshaped response
    assert notch["iir"] and notch["insensitivity"][0]["width"] == pytest.approx(
        pc.insensitivity(pc.design("notch", pc.Mode.from_hz(40.0, 0.05)), 0.05, reference="unshaped").width)


def test_design_hostile_inputs_answer_400_with_the_message(client):
    assert _error(_design(client, modes=((-5, 0.05),))) == "freq_hz must be > 0, got -5"
    assert _error(_design(client, modes=(("nan", 0.05),))) == "freq_hz must be finite, got nan"
    assert _error(_design(client, modes=((40, 1.0),))) == _raised(pc.Mode.from_hz, 40.0, 1.0)
    assert _error(_design(client, modes=((40, "x"),))) == "zeta must be a number, got 'x'"
    assert _error(_design(client, "zzv")) == _raised(pc.design, "zzv", pc.Mode(1.0, 0.0))
    assert _error(_design(client, "zvdk", params={"k": "100000"})) == \
        "zvdk: the designer builds shapers of at most 2000 impulses; use the Python API for more"
    assert _error(_design(client, "zvdk", params={"k": "1.5"})) == "k must be an integer, got 1.5"
    assert _error(_design(client, "ei", params={"vtol": "1.5"})) == \
        _raised(pc.design, "ei", pc.Mode.from_hz(40.0, 0.05), vtol=1.5)
    assert _error(_design(client, sample_rate="-100")) == "sample_rate must be > 0, got -100"
    assert _error(_design(client, "ei", sample_rate="10")) == \
        _raised(discretize, pc.design("ei", pc.Mode.from_hz(40.0, 0.05)), 10.0)
    assert _error(_design(client, modes=())) == "modes must have at least 1 entry, got 0"
    span = pc.design("dtazv", pc.Mode.from_hz(40.0, 0.05)).duration * 1e8
    assert _error(_design(client, "dtazv", sample_rate="1e8")) == (
        f"sample_rate 1e+08 Hz spreads the dtazv shaper over {span:.3g} samples; the designer handles at most 1e+06 "
        "(lower the sample rate)")
    nan_json = '{"kind": "zv", "modes": [{"freq_hz": NaN, "zeta": 0}]}'  # Python's json reads NaN
    assert _error(client.post("/api/design", content=nan_json, headers={"content-type": "application/json"})) == \
        "freq_hz must be finite, got nan"
    assert _error(client.post("/api/design", content=b"")) == \
        "the request is empty: send the form's fields as a JSON object"
    assert _error(client.post("/api/design", content=b"{not json")) == \
        "the request is not JSON: send the form's fields as a JSON object"
    assert _error(client.post("/api/design", json=[1, 2])) == "the request must be a JSON object, got list"


# ---------------------------------------------------------------- export
def test_export_is_the_library_export_as_a_download(client):
    body = {"kind": "zvd", "modes": [{"freq_hz": "45", "zeta": "0.05"}], "sample_rate": "1000"}
    Z = pc.design("zvd", pc.Mode.from_hz(45.0, 0.05), sample_period=1e-3)
    r = client.post("/api/export", json={**body, "format": "json", "name": "x_axis"})
    assert r.status_code == 200 and r.headers["content-disposition"] == 'attachment; filename="x_axis.json"'
    assert json.loads(r.text) == json.loads(pc.export_shaper(Z, 1000.0, "json", name="x_axis"))
    c = client.post("/api/export", json={**body, "format": "c", "name": "x_axis", "form": "dense"})
    assert c.text == pc.export_shaper(Z, 1000.0, "c", name="x_axis", form="dense")
    assert c.headers["content-disposition"].endswith('filename="x_axis.h"')
    assert _error(client.post("/api/export", json={**body, "sample_rate": ""})) == \
        "sample_rate is required for an export (the controller's rate, Hz)"
    assert _error(client.post("/api/export", json={**body, "format": "c", "name": "2bad"})) == \
        _raised(pc.export_shaper, Z, 1000.0, "c", name="2bad")
    assert _error(client.post("/api/export", json={**body, "format": "xml"})).startswith("format must be one of")


# ---------------------------------------------------------------- loop
LOOP = {"G_num": "1", "G_den": "1 1 0", "G_delay": "0.02", "C_num": "2.05 5", "C_den": "0.01 1",
        "F_num": "157.9137", "F_den": "1 1.256637 157.9137", "shaper": "zvd", "freq_hz": "2", "zeta": "0.05",
        "architecture": "control_action"}


def _lib_loop(c_num=(2.05, 5.0), architecture="control_action", tau=0.02):
    G = pc.TransferFunction.from_poly([1], [1, 1, 0]) * pc.delay(tau)
    S = pc.design("zvd", pc.Mode.from_hz(2.0, 0.05))
    F = ([157.9137], [1, 1.256637, 157.9137])
    return pc.Loop(architecture, G=G, C=(list(c_num), [0.01, 1]), F=F, S=S), G, F, S


@pytest.mark.parametrize("c_num, arch, tau", [("2.05 5", "control_action", 0.02), ("60 400", "control_action", 0.02),
                                              ("2.05 5", "inverse_shaper", 0.02), ("2.05 5", "feedforward", 0.0),
                                              ("2.05 5", "control_action", 0.0), ("60 400", "control_action", 0.0)])
def test_loop_verdict_is_the_certified_library_verdict(client, c_num, arch, tau):
    out = client.post("/api/loop", json={**LOOP, "C_num": c_num, "architecture": arch, "G_delay": str(tau)}).json()
    loop = _lib_loop([float(x) for x in c_num.split()], arch, tau)[0]
    st = pc.stability(loop)
    assert out["verdict"]["stable"] == st.stable and out["verdict"]["reason"] == st.reason
    assert out["verdict"]["kind"] == st.kind and len(out["verdict"]["unstable_roots"]) == len(st.unstable_roots)
    poles = pc.poles(loop, out["region"]).roots
    assert out["n_poles"] == poles.size
    lead = poles[np.argmax(poles.real)]
    assert out["poles"][0].startswith(f"{lead.real:.4g}")
    if tau > 0:  # the simulator runs delay-free plants (the shaper carries the delays): it says so
        t = np.linspace(0.0, 1.0, 11)
        assert out["responses_error"] == _raised(pc.simulate, loop, t, w=np.ones_like(t))
    elif st.stable:  # the responses are posicast.simulate's
        t = np.linspace(0.0, out["metrics"]["t_end"], 1500)
        sim = pc.simulate(loop, t, w=np.ones_like(t), outputs=("z", "y", "u"))
        assert out["metrics"]["overshoot_percent"] == pytest.approx(sim.overshoot("y"), rel=1e-9)
        assert "time [s]" in out["plots"]["step"] and "Re s [1/s]" in out["plots"]["spectrum"]
    else:  # simulated over ten growth times of the rightmost pole: it shows
        assert "step_diverged" in out["metrics"] or out["metrics"]["step_peak"] > 1e3


def test_loop_with_an_iir_shaper_simulates_over_the_loop_time_scale(client):
    """A notch lasts forever (duration inf): the horizon follows the closed-loop poles, not the shaper."""
    out = client.post("/api/loop", json={**LOOP, "G_delay": "0", "shaper": "notch"}).json()
    poles = pc.poles(pc.control_action(G=([1], [1, 1, 0]), C=([2.05, 5], [0.01, 1]), F=([157.9137], [1, 1.256637,
                     157.9137]), S=pc.design("notch", pc.Mode.from_hz(2.0, 0.05))), out["region"]).roots
    assert out["metrics"]["t_end"] == pytest.approx(7.0 / -poles.real.max(), rel=1e-9)


def test_loop_improper_controller_keeps_the_verdict_and_says_why_no_response(client):
    out = client.post("/api/loop", json={**LOOP, "C_num": "2 5", "C_den": "1", "G_delay": "0"}).json()  # pure PD
    _, G, F, S = _lib_loop(tau=0.0)
    assert out["verdict"]["reason"] == pc.stability(pc.control_action(G=G, C=([2, 5], [1]), F=F, S=S)).reason
    assert out["responses_error"] == "the transfer function is improper (more zeros than poles): it cannot be simulated"


def test_loop_hostile_inputs_answer_400_with_the_message(client):
    cases = {
        (("G_den", "1 x 0"),): "plant denominator must be numbers separated by spaces, got 'x'",
        (("G_num", "nan"),): "plant numerator must be finite numbers, got nan",
        (("G_den", " ".join(["1"] * 42)),): "plant denominator has degree 41; the designer accepts degree <= 40",
        (("G_delay", "-0.1"),): _raised(pc.delay, -0.1).replace("tau", "plant delay"),
        (("C_num", ""),): "controller numerator must not be empty",
        (("zeta", "1.5"),): _raised(pc.Mode.from_hz, 2.0, 1.5),
        (("freq_hz", "-2"),): "shaper freq_hz must be > 0, got -2",
        (("architecture", "cascade"),): _raised(pc.Loop, "cascade", G=1, C=1),
        (("region", "1 2 3"),): "region must be 're_min re_max im_min im_max' with min < max, got '1 2 3'",
        (("G_den", "0"),): _raised(pc.as_transfer, ([1], [0]), "the plant (num, den)"),
    }
    for fields, msg in cases.items():
        assert _error(client.post("/api/loop", json={**LOOP, **dict(fields)})) == msg, fields


# ---------------------------------------------------------------- tune
def test_tune_pd_and_pi_are_the_library_tuners(client):
    body = {**LOOP, "G_delay": "0", "controller": "pd", "ms": "2", "derivative_filter": "0.01"}
    out = client.post("/api/tune", json=body).json()
    _, G, F, S = _lib_loop(tau=0.0)
    r = pc.tune_pd(G, S, "control_action", ms=2.0, F=F, derivative_filter=0.01)
    assert out["gains"] == pytest.approx(dict(r.gains), rel=1e-12) and out["ms"] == pytest.approx(r.ms)
    kp, kd = r.gains["kp"], r.gains["kd"]
    assert [float(x) for x in out["C_num"].split()] == pytest.approx([kp * 0.01 + kd, kp], rel=1e-9)
    assert out["C_den"] == "0.01 1" and out["summary"] == r.summary()
    pi = client.post("/api/tune", json={**body, "controller": "pi", "derivative_filter": ""}).json()
    rp = pc.tune_pi(G, S, "control_action", ms=2.0, F=F)
    assert pi["gains"] == pytest.approx(dict(rp.gains), rel=1e-12)
    assert [float(x) for x in pi["C_num"].split()] == pytest.approx([rp.gains["kp"], rp.gains["ki"]], rel=1e-9)
    assert pi["C_den"] == "1 0"
    empty = client.post("/api/tune", json={**body, "ms": "0.5"}).json()  # no controller: a result, said so
    r_empty = pc.tune_pd(G, S, "control_action", ms=0.5, F=F, derivative_filter=0.01)
    assert empty["gains"] is None and empty["C_num"] is None and empty["reason"] == r_empty.reason
    assert _error(client.post("/api/tune", json={**body, "ms": "-1"})) == \
        _raised(pc.tune_pd, G, S, "control_action", ms=-1.0)
    assert _error(client.post("/api/tune", json={**body, "controller": "pi"})) == \
        "derivative_filter applies to a pd controller only"
    assert _error(client.post("/api/tune", json={**body, "controller": "pid"})).startswith("controller must be one of")


# ---------------------------------------------------------------- errors that are bugs
def test_an_internal_error_is_one_line_with_status_500(monkeypatch):
    def boom(form):
        raise RuntimeError("planted\nsecond line")

    monkeypatch.setattr(app_module, "design_view", boom)
    r = TestClient(create_app()).post("/api/design", json={"kind": "zv"})
    assert r.status_code == 500 and r.json() == {"error": "internal error: RuntimeError: planted"}


# ---------------------------------------------------------------- the command
def test_posicast_serve_without_the_extra_names_the_pip_line(monkeypatch, capsys):
    from posicast import cli
    from posicast.commands import serve as command

    monkeypatch.setattr(command, "missing_requirements", lambda: ["starlette"])
    assert cli.main(["serve", "--no-browser"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "posicast: error: the designer needs starlette: pip install 'posicast[serve]'"
    monkeypatch.undo()
    assert cli.main(["serve", "--port", "70000", "--no-browser"]) == 2
    assert capsys.readouterr().err.strip() == "posicast: error: --port must be an integer in [0, 65535], got 70000"


@pytest.mark.parametrize("as_json", [False, True])
def test_posicast_serve_serves_the_page(as_json):
    """The real command in a subprocess: it prints its address (a sentence, or JSON) and answers there."""
    env = {**os.environ, "MPLBACKEND": "Agg"}
    cmd = [sys.executable, "-m", "posicast", "serve", "--port", "0", "--no-browser"] + (["--json"] if as_json else [])
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        line = proc.stdout.readline().strip()  # blocks until the server listens
        if as_json:
            info = json.loads(line)
            assert set(info) == {"url", "host", "port", "pid"} and info["pid"] == proc.pid
            assert info["host"] == "127.0.0.1" and info["url"] == f"http://localhost:{info['port']}/"
            url = info["url"]
        else:
            assert line.startswith("posicast designer at http://localhost:") and line.endswith("(Ctrl-C stops it)")
            url = line.split()[3]
        with urllib.request.urlopen(url, timeout=30) as resp:
            assert resp.status == 200 and b'id="tab-machine"' in resp.read()
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def test_readme_example():
    """README "Designer in the browser" runs as printed (its Python block is a doctest)."""
    import doctest

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text[text.index("### Designer in the browser"):]
    start = section.index("```python") + len("```python")
    block = section[start:section.index("```", start)]
    test = doctest.DocTestParser().get_doctest(block, {}, "README serve", "README.md", 0)
    runner = doctest.DocTestRunner()
    runner.run(test)
    assert runner.failures == 0 and runner.tries >= 5


# ---------------------------------------------------------------- second look (issue #20 review)
def test_machine_io_csv_messages_name_the_page_fields_and_no_empty_spectrum(client, tmp_path):
    d = synthetic(pc.Mode.from_hz(28.0, 0.05), "step", n=2000, noise=0.01, seed=1)
    text = "time,input,output\n" + "".join(f"{t:.6f},{u:.6g},{y:.6g}\n" for t, u, y in zip(d.t, d.u, d.y))
    (tmp_path / "io.csv").write_text(text)
    lib = _raised(pc.calibrate, str(tmp_path / "io.csv"))
    assert "(--input, --output)" in lib  # the command line's words; the page has fields
    got = _error(client.post("/api/machine", json={"file": {"name": "io.csv", "text": text}}))
    assert got == "io.csv: not a Klipper file; give the input and output columns " \
                  "(the Input column and Output column fields)"
    out = client.post("/api/machine", json={"file": {"name": "io.csv", "text": text}, "input": "input",
                                            "output": "output"}).json()
    cal = pc.calibrate(str(tmp_path / "io.csv"), input="input", output="output")
    assert out["config"] == "\n".join(cal.config)
    assert out["files"][0]["modes"][0]["freq_hz"] == pytest.approx(cal.modes[0].freq_hz, rel=1e-12)
    assert abs(out["files"][0]["modes"][0]["freq_hz"] - 28.0) < 0.2  # the true mode
    assert out["notes"] == ["the axis of io.csv is not in the file name: taken as x (choose the Axis)"]
    assert "psd" not in out["plots"]  # fitted in time: no spectrum to draw (was an empty frame)


def test_machine_two_axes_label_each_curve_with_its_axis(client):
    real = ROOT / "tests" / "data" / "real"
    files = [{"name": p.name, "text": p.read_text()} for p in
             (real / "bassco_v0_resonances_x_20220703.csv", real / "bassco_v0_resonances_y_20220703.csv")]
    out = client.post("/api/machine", json={"files": files}).json()
    for axis in "xy":
        assert f"{axis}: measured PSD" in out["plots"]["psd"]
        rec = next(r for r in out["recommendations"] if r["axis"] == axis)
        assert f"{axis}: {rec['best']}  (recommended)" in out["plots"]["candidates"]


def test_machine_vibration_target_below_one_percent_is_written_as_given(client):
    out = client.post("/api/machine", json={"file": {"name": PSD.name, "text": PSD.read_text()},
                                            "vtol": "0.001"}).json()
    cal = pc.calibrate(str(PSD), vtol=0.001)
    assert out["config"] == "\n".join(cal.config)
    assert "keeps the worst case within 0.1 %" in out["config"]  # was "within 0 %"


def test_design_notch_taps_at_a_sample_rate(client):
    """An IIR shaper lasts forever; its taps at a rate are the lumped part plus the (b, a) section
    (was refused: 'spreads the notch shaper over inf samples')."""
    out = _design(client, "notch", sample_rate="1000").json()
    D = discretize(pc.design("notch", pc.Mode.from_hz(40.0, 0.05)), 1000.0)
    assert out["duration"] is None and out["taps"]["iir"] is True
    assert out["taps"]["n_taps"] == int(np.count_nonzero(D.taps)) == 1
    r = client.post("/api/export", json={"kind": "notch", "modes": [{"freq_hz": "40", "zeta": "0.05"}],
                                         "sample_rate": "1000", "format": "json"})
    assert r.status_code == 200, r.text
    S = pc.design("notch", pc.Mode.from_hz(40.0, 0.05))
    assert json.loads(r.text) == json.loads(pc.export_shaper(S, 1000.0, "json", name="shaper"))


def test_export_file_name_says_what_it_holds(client):
    body = {"kind": "zvd", "modes": [{"freq_hz": "45", "zeta": "0.05"}], "sample_rate": "1000"}
    names = {}
    for fmt in ("c", "json"):
        for inverse in (False, True):
            r = client.post("/api/export", json={**body, "format": fmt, "inverse": inverse})
            assert r.status_code == 200, r.text
            names[fmt, inverse] = r.headers["content-disposition"]
    assert names["c", False].endswith('filename="shaper_zvd_1000Hz.h"')
    assert names["c", True].endswith('filename="shaper_zvd_1000Hz_inverse.h"')
    assert names["json", True].endswith('filename="shaper_zvd_1000Hz_inverse.json"')
    r = client.post("/api/export", json={**body, "name": "x_axis", "inverse": True})
    assert r.headers["content-disposition"].endswith('filename="x_axis_inverse.h"')


def test_design_band_that_reaches_the_search_limit_says_so(client):
    """ZVD(1 Hz, zeta 0.5) * ZVD(95 Hz): for the 95 Hz mode V stays below 5 % up to insensitivity's
    max_ratio (10 x the mode): the band's upper end is the search range's, not a crossing."""
    out = _design(client, "zvd", modes=((1.0, 0.5), (95.0, 0.02))).json()
    S = pc.design("zvd", pc.Mode.from_hz(1.0, 0.5)) * pc.design("zvd", pc.Mode.from_hz(95.0, 0.02))
    for band, m in zip(out["insensitivity"], S.modes):
        ins = pc.insensitivity(S, 0.05, mode=m)
        assert band["at_limit"] == ins.at_limit and band["width"] == pytest.approx(ins.width, rel=1e-12)
    assert out["insensitivity"][1]["at_limit"] is True and out["insensitivity"][1]["high"] == pytest.approx(10.0)
    assert _design(client, "zvd").json()["insensitivity"][0]["at_limit"] is False


def test_loop_response_step_messages_name_the_page_knob(client):
    """simulate's message names t and substeps, which the page does not show: it adds 'Simulate until'."""
    long = client.post("/api/loop", json={**LOOP, "G_delay": "0", "t_end": "1e6"}).json()
    assert long["verdict"]["stable"] is True
    assert "internal steps" in long["responses_error"]
    assert long["responses_error"].endswith("(the page simulates 1500 points up to 'Simulate until' = 1e+06 s: a "
                                            "shorter time gives a finer step and fewer steps)")
