"""``posicast stability`` and ``posicast simulate`` (issue #20): hostile inputs are one line and exit 2 with
no file written; every figure option writes exactly the file named; progress goes to stderr only."""

import json
import time
from pathlib import Path

import pytest

from posicast.cli import main
from posicast.commands.progress import steps, working

REAL_PSD = Path(__file__).parent / "data" / "real" / "bassco_ender3_resonances_x_20210821.csv"
LOOP = ["--num", "1", "--den", "1 1 0", "--kp", "10", "--kd", "10", "--derivative-filter", "0.01",
        "--shaper", "zv", "--omega", "10", "--zeta", "0.03"]


@pytest.mark.parametrize("argv, word", [
    (["stability", "--num", "1 x", "--den", "1 1"], "--num must be numbers"),
    (["stability", "--num", "1", "--den", "1; 1 @-1"], "--den delay must be"),
    (["stability", "--num", "1", "--den", "1; 1 @nan"], "--den delay must be"),
    (["stability", "--num", "1", "--den", "1;"], "a term without coefficients"),
    (["stability", "--num", "1", "--den", "inf 1"], "--den"),
    (["stability", "--num", "1"], "--den is required"),
    (["stability", "--case", "nowhere"], "--case must be one of"),
    (["stability", "--case", "gantry_crane", "--den", "1 1"], "--den goes with --num"),
    (["stability", "--num", "1", "--den", "1 1", "--roots", "0"], "--roots"),
    (["stability", "--num", "1", "--den", "1 1", "--shaper", "zv"], "--omega and --zeta"),
    (["stability", "--num", "1", "--den", "1 1", "--omega", "3"], "--omega and --zeta go together"),
    (["stability", "--num", "1", "--den", "1 1", "--architecture", "feedforward"], "needs a controller"),
    (["stability", "--num", "1", "--den", "1 1", "--controller-den", "1 2"], "--controller-num is required"),
    (["stability", "--num", "1", "--den", "1 1", "--kp", "1", "--controller-num", "1"], "not both"),
    (["stability", "--num", "1", "--den", "1 1", "--kp", "nan"], "--kp"),
    (["stability", "--num", "1", "--den", "1 1", "--kp", "1", "--derivative-filter", "0.1"], "needs --kd"),
    (["stability", "--num", "1", "--den", "1 1", "--delay", "-1"], "--delay"),
    (["stability", "--num", "1", "--den", "0"], "--num/--den: den must not be identically zero"),
    (["stability", *LOOP[:4], "--controller-num", "1", "--controller-den", "0 0"], "--controller-num/--controller-den"),
    (["simulate", *LOOP, "--t-end", "-1"], "--t-end"),
    (["simulate", *LOOP, "--dt", "0"], "--dt"),
    (["simulate", *LOOP, "--t-end", "1", "--dt", "2"], "--dt must be shorter"),
    (["simulate", *LOOP, "--t-end", "1e9", "--dt", "1e-3"], "steps, more than"),
    (["simulate", *LOOP, "--signals", "y,q"], "--signals"),
    (["simulate", *LOOP, "--signals", ","], "--signals must name"),
    (["simulate", *LOOP, "--signals", "w,d"], "--signals must name at least one loop output"),
    (["simulate", "--num", "1", "--den", "1 1"], "simulate runs a loop"),
    (["simulate", *LOOP, "--input", "no_such_file.csv"], "no_such_file.csv"),
    (["simulate", *LOOP, "--disturbance", "1", "nan"], "--disturbance"),
    (["simulate", *LOOP, "--sample-rate", "-5"], "--sample-rate"),
    (["simulate", *LOOP, "--out", "run.png"], "--out"),
])
def test_hostile_inputs_are_one_line_exit_2_nothing_written(argv, word, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main([*argv, "--plot", "f.png"]) == 2
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.startswith("posicast: error:"), err
    assert word in err, err
    assert out == "" and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv", [
    ["stability", *LOOP, "--plot", "spec.svg"],
    ["stability", "--num", "1", "--den", "1 0; 1 @1", "--plot", "spec.pdf"],
    ["simulate", *LOOP, "--t-end", "2", "--plot", "resp.pdf", "--out", "resp.csv"],
    ["tune", "--num", "1", "--den", "1 2 1", "--controller", "pi", "--ms", "1.4", "--plot", "region.jpg",
     "--nyquist", "nyq.svg"],
    ["sensitivity", "zv", "--omega", "5", "--zeta", "0.05", "--out", "sens.tiff"],
    ["calibrate", str(REAL_PSD), "--plot", "cal.png"],
])
def test_each_figure_option_writes_exactly_the_file_named(argv, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 0
    named = {argv[i + 1] for i, a in enumerate(argv) if a in ("--plot", "--nyquist", "--out")}
    assert {p.name for p in tmp_path.iterdir()} == named
    magic = {".svg": b"<?xml", ".pdf": b"%PDF", ".jpg": b"\xff\xd8", ".tiff": b"II*\x00", ".csv": b"t,",
             ".png": b"\x89PNG"}
    for name in named:
        assert (tmp_path / name).read_bytes().startswith(magic[name[name.rindex("."):]])
    out = capsys.readouterr().out
    assert all(f"wrote {name}" in out for name in named)


def test_simulate_reads_a_reference_file(tmp_path, capsys):
    ref = tmp_path / "ref.csv"
    ref.write_text("t,w\n" + "".join(f"{k * 0.25},{min(k, 4) * 0.25}\n" for k in range(20)))
    out = tmp_path / "r.csv"
    assert main(["simulate", *LOOP, "--t-end", "3", "--dt", "0.01", "--input", str(ref), "--out", str(out),
                 "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    rows = [line.split(",") for line in out.read_text().splitlines()[1:]]
    w = {round(float(r[0]), 6): float(r[1]) for r in rows}
    assert w[0.0] == 0.0 and w[0.24] == 0.0 and w[0.25] == 0.25 and w[0.99] == 0.75 and w[1.2] == 1.0  # held
    assert w[3.0] == 1.0
    assert data["step_response"] == {}  # no step: no step metrics


def test_step_metrics_skip_a_swing_that_returns_to_zero(capsys):
    """The crane's sway y = F z has F(0) = 0 (seed 001 eq. 11): no overshoot for it, even when a sampled run
    ends mid-swing with y away from 0 (here y(20 s) = 0.019 after a load step, which read as a 5600 % overshoot of a 0.019 move).
    The hoist z (DC gain 1) keeps its metrics, equal to the response's own."""
    import numpy as np

    import posicast as pc

    argv = ["simulate", "--case", "gantry_crane", "--kp", "30", "--kd", "1", "--derivative-filter", "0.01",
            "--shaper", "dezv", "--t-end", "20", "--sample-rate", "100", "--disturbance", "10", "0.1", "--json"]
    assert main(argv) == 0
    data = json.loads(capsys.readouterr().out)
    assert abs(data["final"]["y"]) > 0.01  # the run ends mid-swing: the last sample alone would count it
    assert set(data["step_response"]) == {"z"}
    crane = pc.cases.ALL["gantry_crane"]
    C = pc.TransferFunction.from_poly([1.0 + 30.0 * 0.01, 30.0], [0.01, 1.0])  # 30 + s / (0.01 s + 1)
    loop = pc.control_action(G=crane.G, F=crane.F, C=C, S=pc.design("dezv", crane.mode))
    t = np.arange(2001) * 0.01
    r = pc.simulate(loop, t, w=np.ones_like(t), d=0.1 * (t >= 10), sample_rate=100.0, outputs=("z",))
    assert data["step_response"]["z"]["overshoot_percent"] == pytest.approx(r.overshoot("z", start=0.0), rel=1e-9)


def test_simulate_reference_file_is_held_in_its_own_time(tmp_path, capsys):
    """A reference file is breakpoints held until the next one: any spacing, any number of rows (it used to
    need 16 evenly spaced rows, the identifier's rule), and in the file's time: a file that starts at 2 s
    starts the reference at 2 s (it used to be moved to 0)."""
    ref = tmp_path / "ref.csv"
    ref.write_text("time,w\n2,0.5\n3.25,1\n")
    out = tmp_path / "r.csv"
    assert main(["simulate", *LOOP, "--t-end", "4", "--dt", "0.25", "--input", str(ref), "--out", str(out),
                 "--signals", "w,z"]) == 0
    rows = [line.split(",") for line in out.read_text().splitlines()[1:]]
    w = {float(r[0]): float(r[1]) for r in rows}
    assert [w[k] for k in (0.0, 1.75, 2.0, 3.0, 3.25, 4.0)] == [0.0, 0.0, 0.5, 0.5, 1.0, 1.0]
    bad = tmp_path / "bad.csv"
    bad.write_text("t,w\n0,0\n1,1\n1,2\n")
    assert main(["simulate", *LOOP, "--input", str(bad), "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("posicast: error: --input:") and "line 4: time 1 s does not increase" in err
    assert not (tmp_path / "x.csv").exists()


def test_progress_is_on_stderr_after_a_delay_and_quiet_silences_it(capsys):
    with working("long work", delay=0.0):
        time.sleep(0.8)
    out, err = capsys.readouterr()
    assert out == "" and "long work" in err
    with working("long work", quiet=True, delay=0.0):
        time.sleep(0.3)
    with working("quick work"):  # under the 1 s delay: nothing
        pass
    say = steps(delay=0.0)
    say("step one")
    steps(quiet=True, delay=0.0)("hidden")
    out, err = capsys.readouterr()
    assert out == "" and "quick work" not in err and "hidden" not in err and "] step one" in err


def test_progress_on_a_terminal_is_one_tqdm_status_line(monkeypatch):
    """stderr a TTY: the messages redraw one line in place (tqdm), ended by a newline when the work ends."""
    import io
    import sys

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    term = Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    with working("certifying", delay=0.0):
        time.sleep(0.7)
    with steps(delay=0.0) as say:
        say("file 1 of 2")
        say("file 2 of 2")
    text = term.getvalue()
    lines = text.split("\n")
    assert len(lines) == 3 and lines[2] == ""  # two status lines, each closed by one newline
    assert lines[0].startswith("\rcertifying: 00:0") and "[" not in lines[0]  # tqdm's form, not the log form
    assert lines[1].rstrip().endswith("file 2 of 2: 00:00") and "\rfile 1 of 2" in lines[1]
    with steps(quiet=True, delay=0.0) as say:
        say("hidden")
    assert term.getvalue() == text


def test_json_stays_parseable_with_progress(capsys, monkeypatch):
    """Progress shown from the start (delay 0): stdout is still exactly one JSON document."""
    import posicast.commands.progress as progress

    monkeypatch.setattr(progress, "DELAY", 0.0)
    assert main(["stability", *LOOP, "--architecture", "inverse_shaper", "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["stable"] is False and "certifying" in err


def test_tune_without_a_controller_says_why_no_figure_is_written(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["tune", "--num", "1", "--den", "1 1 0", "--ms", "0.9", "--nyquist", "n.png", "--json"]) == 1
    out, err = capsys.readouterr()
    assert json.loads(out)["gains"] is None
    assert err == "posicast: warning: --nyquist n.png not written: no controller to draw\n"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("band, word", [
    ((60.0, 30.0), "band must satisfy 0 <= low < high"),
    ((-5.0, 30.0), "band must satisfy 0 <= low < high"),
    ((float("nan"), 30.0), "band"),
    ((500.0, 600.0), "leaves less than 4 bins"),
    ((30.0,), "band"),
])
def test_calibrate_band_is_checked(band, word, tmp_path, monkeypatch, capsys):
    import posicast as pc

    with pytest.raises((ValueError, TypeError), match=word):
        pc.calibrate([str(REAL_PSD)], band=band)
    monkeypatch.chdir(tmp_path)
    if len(band) == 2:
        assert main(["calibrate", str(REAL_PSD), "--band", *map(str, band), "--plot", "c.png"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and word.split()[0] in err and list(tmp_path.iterdir()) == []
