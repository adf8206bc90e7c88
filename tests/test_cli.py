"""The command line: JSON output, one-line errors with exit status 2."""

import json
import math
import os
import subprocess
import sys

import pytest

from posicast.cli import main


def test_design_json_is_machine_readable(capsys):
    assert main(["design", "zv", "--omega", "2", "--zeta", "0", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["impulses"]["amplitudes"] == [0.5, 0.5]
    assert abs(data["duration"] - math.pi / 2) < 1e-15


def test_design_text_and_freq_hz(capsys):
    assert main(["design", "dtzv", "--freq-hz", "1", "--zeta", "0.05"]) == 0
    out = capsys.readouterr().out
    assert "distributed" in out and "triangular" in out


def test_design_parameters_pass_through(capsys):
    assert main(["design", "mis_zvd", "--omega", "3", "--zeta", "0.1", "--n", "2", "--m", "3", "--json"]) == 0
    assert len(json.loads(capsys.readouterr().out)["impulses"]["times"]) == 6


def test_sensitivity_writes_figure(tmp_path, capsys):
    out = tmp_path / "fig.png"
    assert main(["sensitivity", "zv", "zvd", "ei", "--omega", "5", "--zeta", "0.05", "--out", str(out)]) == 0
    assert out.stat().st_size > 1000
    assert "insensitivity" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, word",
    [
        (["design", "zv", "--omega", "-1", "--zeta", "0.1"], "omega"),
        (["design", "zv", "--omega", "1", "--zeta", "1.2"], "zeta"),
        (["design", "ei", "--omega", "1", "--zeta", "0.1", "--vtol", "2"], "vtol"),
        (["design", "zvdk", "--omega", "1", "--zeta", "0.1", "--k", "-1"], "k"),
        (["design", "mis_zv", "--omega", "1", "--zeta", "0.1", "--n", "1"], "n"),
        (["design", "dezv", "--omega", "1", "--zeta", "0.1", "--T", "0"], "T"),
        (["design", "foo", "--omega", "1", "--zeta", "0.1"], "kind"),
        (["design", "zv", "--omega", "1", "--zeta", "0.1", "--vtol", "0.1"], "vtol"),
        (["design", "zv", "--zeta", "0.1"], "omega"),
        (["design", "zv", "--omega", "abc", "--zeta", "0.1"], "omega"),
        (["identify", "no_such_file.csv", "--modes", "9"], "--modes must be an integer in [1, 6]"),
        (["identify", "no_such_file.csv", "--modes", "two"], "--modes must be an integer in [1, 6]"),
    ],
)
def test_errors_are_one_line_exit_2(argv, word, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("posicast: error:")
    assert word in err


def test_installed_command_exits_2_without_traceback():
    r = subprocess.run([sys.executable, "-m", "posicast", "design", "zv", "--omega", "nan", "--zeta", "0.1"],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and r.stderr.count("\n") == 1


def test_tune_text_and_json(capsys, tmp_path):
    assert main(["tune", "--num", "1", "--den", "1 2 1", "--controller", "pi", "--ms", "1.4", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["stable"] and abs(data["ms"] - 1.4) < 1e-6
    assert abs(data["gains"]["ki"] - 1.0582) < 1e-3 and data["gains"]["kd"] is None
    plot = tmp_path / "region.png"
    assert main(["tune", "--case", "gantry_crane", "--shaper", "dezv", "--architecture", "inverse_shaper",
                 "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    assert "kp = 32.89" in out and "stable" in out and plot.stat().st_size > 1000


def test_tune_without_a_controller_exits_1_with_valid_json(capsys):
    """An unbounded (or empty) region is a result: printed, strict JSON (null, not NaN), exit status 1."""
    assert main(["tune", "--num", "1", "--den", "1 -1 0", "--json"]) == 1
    out = capsys.readouterr().out
    data = json.loads(out, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
    assert data["unbounded"] and data["gains"] is None and data["ms"] is None and "kp_range" in data["reason"]
    assert main(["tune", "--num", "1", "--den", "1 1 0", "--ms", "0.9"]) == 1
    assert "no admissible controller" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, word",
    [
        (["tune", "--num", "1 0 0", "--den", "1 1"], "proper"),
        (["tune", "--num", "1", "--den", "1 1 0", "--shaper", "zv"], "--omega and --zeta"),
        (["tune", "--case", "gantry_crane", "--ms", "-1"], "ms must be > 0"),
        (["tune", "--case", "nowhere"], "--case must be one of"),
        (["tune", "--num", "1", "--den", "1 1 0", "--delay", "nan"], "--delay must be a finite number"),
        (["tune", "--num", "1", "--den", "1 1 0", "--delay", "-0.1"], "--delay must be a finite number"),
        (["tune", "--case", "gantry_crane", "--shaper", "zv", "--omega", "5", "--zeta", "1.2"], "zeta"),
        (["tune", "--case", "gantry_crane", "--shaper", "zv", "--omega", "-5", "--zeta", "0.1"], "omega"),
        (["tune", "--num", "1"], "--den is required"),
        (["tune", "--num", "1 x", "--den", "1 1"], "--num must be numbers"),
        (["tune", "--case", "gantry_crane", "--kd-range", "3", "1"], "kd_range must have low < high"),
        (["tune", "--num", "1", "--den", "1 1", "--controller", "pi", "--derivative-filter", "0.1"], "do not apply"),
    ],
)
def test_tune_errors_are_one_line(argv, word, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert word in err and err.count("\n") == 1


# ---------------------------------------------------------------- issue #13: files, order of checks, one line
def _one_line_error(capsys, word):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("posicast: error:"), err
    assert word in err, err
    return err


@pytest.mark.parametrize("name", ["fig", "fig.txt", ".png", "fig.png/"])
def test_output_path_without_an_image_extension_is_refused_and_nothing_written(name, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    argv = ["sensitivity", "zv", "--omega", "5", "--zeta", "0.05", "--out", name]
    assert main(argv) == 2
    err = _one_line_error(capsys, "--out")
    assert repr(name) in err  # the user's path, not a temporary file
    assert list(tmp_path.iterdir()) == []


def test_output_directory_or_missing_parent_is_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "d.png").mkdir()
    assert main(["tune", "--num", "1", "--den", "1 2 1", "--controller", "pi", "--plot", "d.png"]) == 2
    _one_line_error(capsys, "is a directory")
    assert main(["tune", "--num", "1", "--den", "1 2 1", "--plot", str(tmp_path / "no" / "f.png")]) == 2
    _one_line_error(capsys, "does not exist")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.png"]


def test_bad_tolerance_is_refused_before_the_figure_is_written(tmp_path, capsys):
    out = tmp_path / "fig.png"
    for tol in ("nan", "0", "1", "-0.1", "inf"):
        assert main(["sensitivity", "zv", "--omega", "5", "--zeta", "0.05", "--tol", tol, "--out", str(out)]) == 2
        _one_line_error(capsys, "--tol")
    assert not out.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("ext, magic", [(".pdf", b"%PDF"), (".svg", b"<svg"), (".PNG", b"\x89PNG")])
def test_figure_is_written_at_the_exact_path_in_the_extensions_format(ext, magic, tmp_path, capsys):
    out = tmp_path / f"fig{ext}"
    assert main(["sensitivity", "zv", "--omega", "5", "--zeta", "0.05", "--out", str(out)]) == 0
    assert magic in out.read_bytes()[:400]
    assert [p.name for p in tmp_path.iterdir()] == [out.name]  # no temporary file left


def test_unwritable_target_names_the_users_path(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if os.access(ro, os.W_OK):  # running as root: permissions are not enforced
            pytest.skip("directory permissions are not enforced for this user")
        assert main(["sensitivity", "zv", "--omega", "5", "--zeta", "0.05", "--out", str(ro / "f.png")]) == 2
        err = _one_line_error(capsys, "not writable")
        assert str(ro / "f.png") in err and ".part" not in err
    finally:
        ro.chmod(0o700)


def test_tune_ms_beyond_the_float_range_is_a_named_error(capsys):
    assert main(["tune", "--case", "gantry_crane", "--ms", "1e300"]) == 2
    _one_line_error(capsys, "ms must be in")


def test_unexpected_exception_is_one_line_with_status_70(monkeypatch, capsys):
    import importlib

    shaper_design = importlib.import_module("posicast.shapers.registry")

    def broken(*args, **kwargs):
        raise OverflowError("math range error")

    monkeypatch.setattr(shaper_design, "design", broken)
    assert main(["design", "zv", "--omega", "1", "--zeta", "0.1"]) == 70
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("posicast: internal error: OverflowError: math range error")
    assert "POSICAST_TRACEBACK=1" in err


def test_written_figure_has_the_usual_file_mode(tmp_path):
    """The atomic write goes through a private temporary file; the result gets 0666 less the umask."""
    mask = os.umask(0o022)
    try:
        out = tmp_path / "fig.png"
        assert main(["sensitivity", "zv", "--omega", "5", "--zeta", "0.05", "--out", str(out)]) == 0
        assert out.stat().st_mode & 0o777 == 0o644
    finally:
        os.umask(mask)


def test_tune_structure_is_the_old_name_of_architecture(capsys):
    """issue #14: one word per concept; the 0.1 flag still works, with a warning line on stderr."""
    argv = ["tune", "--num", "1", "--den", "1 2 1", "--controller", "pi", "--ms", "1.4", "--json"]
    assert main(argv + ["--architecture", "feedforward"]) == 0
    new = json.loads(capsys.readouterr().out)
    assert main(argv + ["--structure", "feedforward"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out) == new and new["architecture"] == "feedforward"
    assert "--structure is now --architecture" in captured.err
    assert main(argv + ["--structure", "feedforward", "--architecture", "feedforward"]) == 2


def test_export_choices_match_the_exporter():
    """The CLI spells out posicast.io.export's choices (its parser imports nothing): they must agree."""
    from posicast.cli import _build_parser
    from posicast.io.export import EXPORT_FORMATS, EXPORT_FORMS, EXPORT_PRECISIONS

    sub = next(a for a in _build_parser()._actions if a.dest == "command").choices["export"]
    choices = {a.dest: set(a.choices) for a in sub._actions if a.choices}
    assert choices["format"] == set(EXPORT_FORMATS)
    assert choices["form"] == set(EXPORT_FORMS)
    assert choices["precision"] == set(EXPORT_PRECISIONS)


def test_a_warning_is_one_line_on_stderr(capsys):
    """A library warning while a subcommand runs (here: seed 002's adjacent taps at a short period) is one
    'posicast: warning: ...' line, and the command still succeeds."""
    from posicast.cli import main

    rc = main(["export", "zvd", "--freq-hz", "28", "--zeta", "0.05", "--sample-rate", "1000", "--zplane",
               "--stride", "1", "--format", "json"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 0 and len(err) == 1 and err[0].startswith("posicast: warning: the z-plane shaper")
