"""Issue #16 acceptance 4: the exported C compiles with gcc -Wall -Werror and filters as shape_signal does."""

import json
import shutil
import subprocess

import numpy as np
import pytest

import posicast as pc
from posicast.io.export import export_shaper
from posicast.simulation.streaming import discretize, shape_signal

GCC = shutil.which("gcc")
FS = 500.0
MODE = pc.Mode.from_hz(4.0, 0.08)


def _signal(n=1500):
    t = np.arange(n) / FS
    return np.where(t > 0.1, 1.0, 0.0) + 0.3 * np.sin(7.0 * t) + np.where(t > 1.7, -2.0, 0.0)


def _run_c(text, x, tmp_path, tag):
    src = tmp_path / f"{tag}.h"
    exe = tmp_path / tag
    src.write_text(text)
    cmd = [GCC, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-DPOSICAST_EXAMPLE_MAIN", "-x", "c", str(src),
           "-o", str(exe)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    out = subprocess.run([str(exe)], input="\n".join(repr(float(v)) for v in x), capture_output=True, text=True,
                         check=True)
    return np.array([float(s) for s in out.stdout.split()])


CASES = [("zvd", {}, False), ("dzv", {}, False), ("dtzv", {}, False), ("dczv", {}, False), ("notch", {}, False),
         ("zv", {}, True), ("dzv", {}, True), ("zvd", {"sample_period": 0.002, "stride": "positive"}, False)]


@pytest.mark.skipif(GCC is None, reason="gcc not installed")
@pytest.mark.parametrize("form", ["sparse", "dense"])
@pytest.mark.parametrize("kind,kw,inverse", CASES, ids=[f"{k}{'-inv' if i else ''}{'-z' if kw else ''}"
                                                         for k, kw, i in CASES])
def test_exported_c_matches_shape_signal(kind, kw, inverse, form, tmp_path):
    S = pc.design(kind, MODE, **kw)
    x = _signal()
    ref = shape_signal(S, x, FS, inverse=inverse)
    for prec, tol in (("double", 1e-12), ("float", 1e-6)):
        text = export_shaper(S, FS, "c", name=f"sh_{kind}", form=form, inverse=inverse, precision=prec)
        assert "residual vibration after discretisation" in text
        y = _run_c(text, x, tmp_path, f"{kind}_{form}_{prec}")
        err = np.max(np.abs(y - ref)) / max(1.0, np.max(np.abs(ref)))
        print(kind, form, prec, "inverse" if inverse else "", f"max rel err {err:.2e}")
        assert err <= tol


@pytest.mark.skipif(GCC is None, reason="gcc not installed")
def test_running_sum_resync_in_c(tmp_path):
    # a long uniform kernel crossing several exact re-summations (RESYNC = 4 x span, >= 65536 samples)
    S = pc.design("dtazv", pc.Mode.from_hz(2.0, 0.05))
    fs = 20000.0
    x = np.sin(np.arange(140000) * 3e-4) + 0.5
    text = export_shaper(S, fs, "c", name="long")
    assert "#define LONG_RESYNC 65536ul" in text
    y = _run_c(text, x, tmp_path, "long")
    assert np.max(np.abs(y - shape_signal(S, x, fs))) <= 1e-12


def test_json_forms_and_header():
    S = pc.design("zv", pc.Mode.from_hz(120.0, 0.0))
    doc = json.loads(export_shaper(S, 1000.0))
    D = discretize(S, 1000.0)
    # the "2-6.5 % for a 120 Hz ZV at 1 kHz" (1.9 % undamped): the header states it
    assert doc["residual_vibration"][0]["residual"] == pytest.approx(D.residual, rel=1e-12)
    assert D.residual == pytest.approx(0.01947, abs=1e-5)
    assert "120 Hz: 1.95 %" in export_shaper(S, 1000.0, "c")
    dense = json.loads(export_shaper(S, 1000.0, form="dense"))
    w = np.zeros(len(dense["taps"]))
    w[doc["sparse"]["index"]] = doc["sparse"]["weight"]
    assert np.allclose(w, dense["taps"], atol=1e-16)
    inv = json.loads(export_shaper(pc.design("dzv", MODE), FS, inverse=True))
    assert inv["filter"] == "inverse" and inv["stability"]["verdict"] == "stable"
    assert len(inv["sparse"]["segments"]) == 1
    zs = json.loads(export_shaper(pc.design("zv", MODE, sample_period=0.02), 50.0))
    assert zs["residual_vibration"][0]["residual"] < 1e-15     # the z-plane design leaves nothing


def test_export_bad_input():
    S = pc.design("zv", pc.Mode(10.0, 0.0))
    with pytest.raises(ValueError, match="form must be one of"):
        export_shaper(S, 100.0, form="csr")
    with pytest.raises(ValueError, match="precision must be one of"):
        export_shaper(S, 100.0, "c", precision="half")
    with pytest.raises(ValueError, match="name must be a C identifier"):
        export_shaper(S, 100.0, "c", name="1x")
    with pytest.raises(ValueError, match="is unstable"):
        export_shaper(pc.Shaper([0.0, 0.2], [0.3, 0.7]), 100.0, "c", inverse=True)
    with pytest.raises(ValueError, match="IIR part"):
        export_shaper(pc.design("notch", MODE), FS, inverse=True)
    assert pc.export_shaper is export_shaper


def test_cli_export(tmp_path, capsys):
    from posicast.cli import main
    assert main(["export", "zvd", "--freq-hz", "28", "--zeta", "0.05", "--sample-rate", "100", "--zplane",
                 "--format", "json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    S = pc.design("zvd", pc.Mode.from_hz(28.0, 0.05), sample_period=0.01)
    assert doc["sparse"]["index"] == [0, 1, 2, 3, 4]
    assert np.allclose(doc["sparse"]["weight"], S.amplitudes, atol=1e-15)
    out = tmp_path / "inv.h"
    assert main(["export", "dzv", "--omega", "8.98", "--zeta", "0.14", "--sample-rate", "200", "--inverse",
                 "--precision", "float", "--output", str(out)]) == 0
    assert "inverse stability: stable" in out.read_text()
    assert main(["export", "zv", "--omega", "10", "--zeta", "0", "--sample-rate", "100", "--stride", "2"]) == 2
    assert "--stride applies only with --zplane" in capsys.readouterr().err
    assert main(["export", "zv", "--omega", "10", "--zeta", "0", "--sample-rate", "100", "--output", "x.png"]) == 2
