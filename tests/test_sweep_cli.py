"""``posicast sweep ...`` (issue #19 item 5): the same options as posicast.sweep; one-line errors, exit 2,
no traceback, nothing written on error."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from posicast.cli import main
from posicast.sweeps import load


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def test_chart_writes_table_figure_and_store(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    csv, png, store = tmp_path / "c.csv", tmp_path / "c.png", tmp_path / "c.zarr"
    rc, out, err = _run(capsys, "sweep", "chart", "--gain", "0.5,0.7,0.9", "--delay-error=-0.5,0.5", "--serial",
                        "--csv", str(csv), "--plot", str(png), "--store", str(store), "--quiet")
    assert rc == 0, err
    assert "D-decomposition check: agrees to the grid resolution" in out
    assert "delay_error -0.5: gain 0.769334" in out  # the tuner's crossing, refined (see test_sweep_ready)
    lines = csv.read_text().splitlines()
    assert lines[0] == "gain,delay_error,stable,marginal,unstable_roots,status,error" and len(lines) == 7
    assert png.stat().st_size > 1000
    assert load(store).complete
    # the same command again resumes: nothing computed
    rc, out, _ = _run(capsys, "sweep", "chart", "--gain", "0.5,0.7,0.9", "--delay-error=-0.5,0.5", "--serial",
                      "--store", str(store), "--quiet")
    assert rc == 0 and "computed" not in out


def test_failed_points_exit_1_with_their_messages(capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _ = _run(capsys, "sweep", "function", "posicast.sweeps.montecarlo:two_mass_point", "--grid", "c1=50,-1",
                      "--grid", "c2=0.1", "--grid", "k2=10", "--grid", "simulate_step=0", "--serial", "--quiet")
    assert rc == 1
    assert "1 ok, 1 failed" in out and "ValueError: c1 must be finite and > 0, got -1.0" in out


@pytest.mark.parametrize("argv, message", [
    (["chart", "--gain", "0.1:1.2:x"], "--gain must be START:STOP:NUM or comma-separated numbers, got '0.1:1.2:x'"),
    (["function", "posicast.sweeps.charts:seed000_loop", "--grid", "gain="], "--grid gain must be START:STOP:NUM"),
    (["function", "posicast.sweeps.charts:seed000_loop", "--grid", "gian=1"], "unknown parameter 'gian'"),
    (["function", "posicast.nothing:f", "--grid", "x=1"], "function 'posicast.nothing:f' cannot be imported"),
    (["function", "math:hypot", "--uniform", "x=1:0", "--n", "3", "--seed", "1"], "LOW < HIGH"),
    (["montecarlo", "--n", "0"], "n must be an integer"),
    (["calibrate", "/nonexistent/folder"], "folder '/nonexistent/folder' is not a directory"),
    (["calibrate", "."], "--plot draws a chart"),
])
def test_bad_input_is_one_line_exit_2(argv: list[str], message: str, tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    extra = ["--plot", str(tmp_path / "f.png")] if argv[0] == "calibrate" and argv[1] == "." else []
    rc, out, err = _run(capsys, "sweep", *argv, *extra, "--serial", "--quiet", "--csv", str(tmp_path / "t.csv"))
    assert rc == 2
    assert err.count("\n") == 1 and err.startswith("posicast: error: ") and message in err
    assert "Traceback" not in err and list(tmp_path.iterdir()) == []


def test_unreachable_scheduler_one_line_nothing_written(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    rc, _, err = _run(capsys, "sweep", "chart", "--gain", "0.5", "--delay-error", "0", "--scheduler",
                      f"tcp://127.0.0.1:{port}", "--timeout", "0.5", "--store", str(tmp_path / "s.zarr"),
                      "--csv", str(tmp_path / "t.csv"))
    assert rc == 2 and err.count("\n") == 1
    assert f"posicast: error: no Dask scheduler at 'tcp://127.0.0.1:{port}'" in err
    assert list(tmp_path.iterdir()) == []


def test_bad_output_paths_refused_before_work(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc, _, err = _run(capsys, "sweep", "chart", "--gain", "0.5", "--serial", "--csv", str(tmp_path / "t.txt"))
    assert rc == 2 and "--csv" in err and "extension" in err
    rc, _, err = _run(capsys, "sweep", "chart", "--gain", "0.5", "--serial", "--plot", str(tmp_path / "t"))
    assert rc == 2 and "--plot" in err
    rc, _, err = _run(capsys, "sweep", "chart", "--serial", "--workers", "2")
    assert rc == 2 and "not allowed with argument" in err
    assert list(tmp_path.iterdir()) == []
