"""The user-first report (issue #20): ``posicast report DATA``, the demo's first parts, the page's number formats.

The pages are parsed (stdlib ``html.parser``): a table of contents whose every link resolves, the user-first
parts first, the configuration lines equal to the library's calibration of the same log, and no table cell
with the defects the issue lists (an empty band shown as ``1.0000–1.0000``, ``0.0000`` in a column that
also holds a number in scientific notation, rows that disagree with the count in the text).
"""

from __future__ import annotations

import cmath
import io
import json
import math
import re
from html.parser import HTMLParser
from pathlib import Path
from types import SimpleNamespace

import pytest

import posicast
from posicast.cli import main
from posicast.report import format_column, format_number, load_plant, plant_spec, write_report
from posicast.report.page import Page
from posicast.testing import synthetic
from posicast_reports.demo import EXAMPLE_LOG, EXAMPLE_PLANT, REPOSITORY, user_first
from posicast_reports.html import Report

LOG = REPOSITORY / EXAMPLE_LOG
PLANT = REPOSITORY / EXAMPLE_PLANT
# what the issue saw: an empty band, a fixed zero beside scientific notation
EMPTY_BAND = re.compile(r"(\d\.\d+)\s*[–-]\s*\1(?!\d)")


class _Page(HTMLParser):
    """The parts of a page the tests read: ids, TOC links, headings, tables (cells by column), config blocks."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.ids: set[str] = set()
        self.toc_links: list[str] = []
        self.headings: list[tuple[str, str]] = []  # (tag, text)
        self.tables: list[list[list[str]]] = []
        self.configs: list[tuple[dict[str, str], str]] = []
        self.paragraphs: list[str] = []
        self._stack: list[tuple[str, dict[str, str]]] = []
        self._text: list[str] = []
        self.feed(text)

    def handle_starttag(self, tag: str, attrs: list) -> None:
        a = {k: v or "" for k, v in attrs}
        if "id" in a:
            self.ids.add(a["id"])
        if tag == "a" and any(t == "nav" for t, _ in self._stack):
            self.toc_links.append(a.get("href", ""))
        if tag == "table":
            self.tables.append([])
        if tag == "tr" and self.tables:
            self.tables[-1].append([])
        if tag in ("td", "th", "h2", "h3", "pre", "p"):
            self._text = []
        self._stack.append((tag, a))

    def handle_endtag(self, tag: str) -> None:
        while self._stack:
            t, a = self._stack.pop()
            if t == tag:
                break
        text = "".join(self._text).strip()
        if tag in ("td", "th") and self.tables and self.tables[-1]:
            self.tables[-1][-1].append(text)
        elif tag in ("h2", "h3"):
            self.headings.append((tag, text))
        elif tag == "pre" and "config" in a.get("class", ""):
            self.configs.append((a, "".join(self._text)))
        elif tag == "p":
            self.paragraphs.append(text)

    def handle_data(self, data: str) -> None:
        self._text.append(data)


def _check_page(page: _Page) -> None:
    """The checks every user-first page passes (issue #20 acceptance 4)."""
    assert page.toc_links, "no table of contents"
    for href in page.toc_links:
        assert href.startswith("#") and href[1:] in page.ids, href
    assert len(page.toc_links) == len(page.headings)
    for table in page.tables:
        rows = table[1:]
        for j in range(max(len(r) for r in table)):
            col = [r[j] for r in rows if j < len(r)]
            sci = any(re.fullmatch(r"[-+]?\d\.\d+e[-+]\d+", c) for c in col)
            fixed_zero = any(re.fullmatch(r"[-+]?0\.0+", c) for c in col)
            assert not (sci and fixed_zero), (table[0], col)
            assert not any(EMPTY_BAND.search(c) for c in col), (table[0], col)
    # "N settings" beside its table: the count in the text is the table's row count
    counts = [int(m.group(1)) for p in page.paragraphs for m in [re.search(r": (\d+) settings", p)] if m]
    config_tables = [t for t in page.tables if t and t[0][:1] == ["type"]]
    assert counts == [len(t) - 1 for t in config_tables]


@pytest.fixture(scope="module")
def demo_front(tmp_path_factory: pytest.TempPathFactory) -> tuple[_Page, posicast.Calibration]:
    out = tmp_path_factory.mktemp("front")
    report = Report("front", out)
    cal = user_first(report)
    assert cal is not None
    return _Page(report.write().read_text(encoding="utf-8")), cal


def test_demo_opens_with_the_user_first_parts(demo_front) -> None:
    page, cal = demo_front
    _check_page(page)
    parts = [text for tag, text in page.headings if tag == "h2"]
    assert parts[:2] == ["Your data → your shaper", "Your plant → your loop"]
    configs = [text.splitlines() for _, text in page.configs]
    assert configs == [rec.config for rec in cal.recommendations]
    # the library's calibration of the same file, computed independently of the page
    again = posicast.calibrate(LOG).recommendation("klipper")
    assert configs[0] == again.config and "shaper_type_y: mzv" in configs[0]
    # the model of Klipper's own pick reproduces what the owner published for this run (MANIFEST.md)
    assert again.reference is not None and again.reference.setting.describe().startswith("mzv @ 40.8 Hz")


def test_demo_front_shows_the_commands(demo_front) -> None:
    page, _ = demo_front
    assert any(h == ("h3", "Certified stability") for h in page.headings)
    assert "Tuned PI" in [t for _, t in page.headings]


def test_report_command_for_a_log(tmp_path, capsys) -> None:
    out = tmp_path / "out"
    assert main(["report", str(LOG), "--out", str(out), "--json", "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["kind"] == "log" and Path(summary["index"]) == out / "index.html"
    page = _Page((out / "index.html").read_text(encoding="utf-8"))
    _check_page(page)
    rec = posicast.calibrate(LOG).recommendation("klipper")
    assert summary["config"] == rec.config == page.configs[0][1].splitlines()
    assert [f.name for f in out.iterdir() if f.suffix == ".png"] == ["01_calibration.png"]


def test_report_command_for_a_plant(tmp_path, capsys) -> None:
    out = tmp_path / "out"
    assert main(["report", str(PLANT), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert text.startswith(f"wrote {out / 'index.html'}") and "your controller + zvdk: stable" in text
    page = _Page((out / "index.html").read_text(encoding="utf-8"))
    _check_page(page)
    verdicts = next(t for t in page.tables if t[0][:2] == ["loop", "verdict"])
    assert [r[1] for r in verdicts[1:]] == ["stable"] * 4


def test_write_report_plant_numbers(tmp_path) -> None:
    """The tuned PI is posicast.tune_pi's on the same loop; the verdicts are the loops' certified stability."""
    s = write_report(PLANT, tmp_path)
    c = posicast.cases.ALL["two_mass"]
    S = posicast.design("zvdk", c.mode, k=2)
    r = posicast.tune_pi(c.G, S, "control_action", ms=1.4)
    assert abs(s.details["tuned"]["gains"]["ki"] / r.ki - 1) < 1e-6
    assert s.details["loops"][1]["stable"] is posicast.control_action(G=c.G, C=c.C, S=S).stability().stable is True


def _flat_log(path: Path) -> Path:
    path.write_text("freq,psd_x,psd_y,psd_z,psd_xyz\n" + "".join(
        f"{1.5625 * k:.1f},1.000e+03,1.000e+03,1.000e+03,3.000e+03\n" for k in range(130)))
    return path


def test_report_refusals_write_nothing(tmp_path, capsys) -> None:
    out = tmp_path / "out"
    not_a_log = tmp_path / "notes.csv"
    not_a_log.write_text("a,b\n1,2\n3,4\n")
    bad_plant = tmp_path / "p.json"
    bad_plant.write_text('{"plant": {"num": [1], "den": [1, 1]}, "colour": "red"}')
    for argv, status, words in (
            ([str(not_a_log)], 2, "posicast: error:"),
            ([str(_flat_log(tmp_path / "resonances_x_flat.csv"))], 1, "no resonance found"),
            ([str(bad_plant)], 2, "unknown key(s) in the plant file: colour"),
            ([str(PLANT), str(LOG)], 2, "not both"),
            ([str(tmp_path / "missing.json")], 2, "cannot read"),
    ):
        assert main(["report", *argv, "--out", str(out), "--quiet"]) == status
        captured = capsys.readouterr()
        assert captured.out == "" and captured.err.count("\n") == 1 and words in captured.err, captured.err
        assert not out.exists()


def test_report_of_an_input_output_csv_points_to_calibrate(tmp_path, capsys) -> None:
    """calibrate asks for --input/--output, which report does not have: report says where to go instead."""
    d = synthetic(posicast.Mode.from_hz(28.0, 0.05), "step", n=400, seed=1)
    io = tmp_path / "io.csv"
    io.write_text("time,input,output\n" + "".join(f"{t:.6f},{u:.6g},{y:.6g}\n" for t, u, y in zip(d.t, d.u, d.y)))
    with pytest.raises(ValueError) as lib:
        posicast.calibrate(str(io))
    assert "(--input, --output)" in str(lib.value)
    out = tmp_path / "out"
    assert main(["report", str(io), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err == (f"posicast: error: {io}: not a Klipper file; the report reads resonance tests; for an input/output "
                   "record run 'posicast calibrate FILE --input COLUMN --output COLUMN'\n")
    assert not out.exists()


@pytest.mark.parametrize("data, words", [
    ({"plant": {"num": [1, 0, 0], "den": [1, 1]}}, "plant must be proper"),
    ({"plant": {"num": [1], "den": [0, 0]}}, "plant.den must not be all zeros"),
    ({"plant": {"num": [1], "den": [1, 1]}}, "no lightly damped mode"),
    ({"plant": {"num": [1], "den": [1, 1, 4]}, "mode": {"freq_hz": 1, "omega": 2, "zeta": 0.1}}, "mode must be"),
    ({"plant": {"num": [1], "den": [1, 1, 4]}, "tune": {"controller": "pid"}}, "tune.controller must be one of"),
    ({"plant": {"num": [1], "den": [1, 1, 4]}, "tune": {"ms": 0.5}}, "tune.ms must be in (1, 10]"),
    ({"plant": {"num": [1], "den": [1, 1, 4]}, "horizon": 1e9}, "horizon must be at most"),
    ({"plant": {"num": [1], "den": [1, 1, 4], "delay": -1}}, "plant.delay must be"),
    ({"plant": {"num": [1], "den": [1, 1, 4]}, "shaper": "zz"}, "shaper.kind must be one of"),
    ({"plant": {"num": [1], "den": [1, 1, 4]}, "architecture": "inside"}, "architecture must be one of"),
    ([1, 2], "data must be a plant description"),
])
def test_plant_file_errors_name_the_key(data, words) -> None:
    with pytest.raises((ValueError, TypeError), match=re.escape(words)):
        plant_spec(data)


def test_plant_file_mode_from_the_load_and_delay(tmp_path) -> None:
    """The mode is the load's least damped pole pair (seed 000 eq. 26: 10 rad/s, zeta 0.03); a delay is kept."""
    p = tmp_path / "loop.json"
    p.write_text(json.dumps({"plant": {"num": [1], "den": [1, 1, 0], "delay": 0.01},
                             "load": {"num": [1, 0], "den": [1, 0.6, 100]}}))
    spec = load_plant(p)
    assert abs(spec.mode.omega - 10.0) < 1e-12 and abs(spec.mode.zeta - 0.03) < 1e-12
    assert spec.mode_source == "the load's least damped poles"
    assert abs(spec.G(2j) - cmath.exp(-0.02j) / ((2j) ** 2 + 2j)) < 1e-15
    assert spec.horizon == pytest.approx(40 * 2 * 3.141592653589793 / 10.0)


def test_one_number_format_per_column() -> None:
    assert format_column([0.0, 1.7e-17, 0.0553]) == ["0", "< 1e-12", "0.0553"]
    assert format_column([0.0, 0.25]) == ["0.0000", "0.2500"]
    assert format_column([0.0, 2.4e-8, 0.5, 22.52]) == ["0", "2.400e-08", "0.5000", "22.52"]
    assert format_column([1.5, 123456.0, 0.0123]) == ["1.500", "1.235e+05", "0.01230"]
    # one decimal, a value that needs more: two significant digits for all (was 1.5567 -> "2", 0.127 -> "0.1")
    assert format_column([1.5567, 0.0, 0.127, 0.0227], 1) == ["1.6", "0", "0.13", "0.023"]
    # whole numbers stay whole past 1e5 (was "1.2e+05" beside "60116" in the max_accel column)
    assert format_column([60116.0, 123456.0, 15542.0], 0) == ["60116", "123456", "15542"]
    assert format_column([float("nan"), None, float("-inf"), 2]) == ["–", "–", "−∞", "2"]
    assert format_number(-3e-13) == "< 1e-12"
    page = Page("t")
    with pytest.raises(ValueError, match="digits must have one entry per column"):
        page.table(["a", "b"], [[1.0, 2.0]], digits=[3])
    with pytest.raises(TypeError, match="title must be a string"):
        page.section(3)  # type: ignore[arg-type]


def test_toc_and_anchors_are_unique() -> None:
    page = Page("t")
    ids = [page.part("A"), page.section("Same"), page.section("Same"), page.part("B"), page.section("x" * 80)]
    assert ids == ["a", "same", "same-2", "b", "x" * 60]
    parsed = _Page(page.html())
    assert parsed.toc_links == [f"#{i}" for i in ids] and set(ids) <= parsed.ids


def test_reproduce_shaper_table_has_no_empty_band() -> None:
    """An empty 5 % band reads 'none' with the reason, not 0.0000 / 1.0000–1.0000; |S(p)| has one format."""
    from posicast_reports.reproduce import LINK, _band, _shaper_table

    report = Report("t", "unused")
    report.section("shapers")
    _shaper_table(report, LINK[1])
    page = _Page(report.html())
    _check_page(page)
    width, band = _band(SimpleNamespace(width=0.0, low=1.0, high=1.0), 0.071)  # what insensitivity gives then
    assert band == "none: V at the model 7.1 % > 5 %" and math.isnan(width)


def _heading_only(name: str):
    """A stand-in for an expensive report section: its heading, ``name``, and nothing else."""
    def add(report: Report, *args, **kwargs) -> None:
        report.section(name)
    return add


def _part_html(text: str, title: str) -> str:
    """The HTML of the part titled ``title``: from its heading to the next part's."""
    start = text.index(f">{title}</h2>")
    end = text.find("<h2", start)
    return text[start:] if end < 0 else text[start:end]


def test_demo_links_the_seed_reproductions(tmp_path, monkeypatch) -> None:
    """``make demo`` says near the top and in its contents that the seed reproductions are a separate report,
    written by ``make reproduce``, and links it (``reproduce/index.html``, where ``make reproduce`` writes it).

    The sections are replaced by their headings: this checks the page's structure and links, not the numbers
    (the sections' content did not change when they moved between the reports; that was checked once, section
    by section, against the all-in-one demo)."""
    from posicast_reports import demo, reproduce

    def front(report: Report) -> None:
        report.part("Your data → your shaper")
        report.part("Your plant → your loop")

    monkeypatch.setattr(demo, "user_first", front)
    for name in ("calibration_section", "optimal_section", "sweep_section"):
        monkeypatch.setattr(demo, name, _heading_only(name))
    out = tmp_path / "report"
    stderr = io.StringIO()
    text = demo.build_report(out, demo.Progress(stderr)).read_text(encoding="utf-8")
    page = _Page(text)
    _check_page(page)
    assert [t for tag, t in page.headings if tag == "h2"] == [
        "Your data → your shaper", "Your plant → your loop", "Printer calibration",
        "Seed reproductions: a separate report", "Beyond the seeds"]
    assert [t for tag, t in page.headings if tag == "h3"] == ["calibration_section", "optimal_section",
                                                             "sweep_section"]
    link = f'<a href="{demo.REPRODUCE_LINK}">'
    top = text[:text.index("<nav")]
    for html_ in (top, _part_html(text, "Seed reproductions: a separate report")):
        assert link in html_ and "written by <code>make reproduce</code>" in html_
    assert out / demo.REPRODUCE_LINK == out / "reproduce" / "index.html"  # the Makefile's folder
    assert (out / "reproduce" / reproduce.DEMO_LINK).resolve() == (out / "index.html").resolve()
    assert [line.split("]")[0].split()[0] for line in stderr.getvalue().splitlines()] == ["[demo"] * 5


def test_reproduce_holds_the_seed_sections_in_order(tmp_path, monkeypatch) -> None:
    """``make reproduce`` holds seed 002's identification and the seed sections, in the demo's former order,
    links back to the demo report and prints a progress line per section.

    Seed 002's trials run once per scenario (not 30 and 100); the other expensive sections are replaced by
    their headings, the sensitivity figures left out."""
    from posicast_reports import reproduce
    from posicast_reports.identification_report import SEED002_TITLE, seed002_identification_section

    monkeypatch.setattr(reproduce, "seed002_identification_section",
                        lambda report: seed002_identification_section(report, trials=1, acceptance_trials=1))
    monkeypatch.setattr(reproduce, "_sensitivity_figures", lambda report, mode, tag: None)
    for name in ("_spectra_section", "_simulation_section", "seed001_section", "seed003_section"):
        monkeypatch.setattr(reproduce, name, _heading_only(name))
    stderr = io.StringIO()
    out = tmp_path / "report" / "reproduce"
    text = reproduce.build_report(out, reproduce.Progress(stderr, name="reproduce")).read_text(encoding="utf-8")
    page = _Page(text)
    _check_page(page)
    assert page.headings == [
        ("h2", "Identification (seed 002)"), ("h3", SEED002_TITLE), ("h2", "Seed reproductions"),
        ("h3", "Seed 001 gantry crane sway mode: ω = 5.49 rad/s, ζ = 0.008"),
        ("h3", "Seed 000 Quanser flexible-link mode: ω = 8.98 rad/s, ζ = 0.14"),
        ("h3", "Seed 001 Table 1: distributed-delay shaper parameters"),
        ("h3", "Seed 000: DZV for the flexible-link experiment"),
        ("h3", "EI shaper: Singhose's damped curve fit against the exact solution"),
        ("h3", "_spectra_section"), ("h3", "_simulation_section"), ("h3", "seed001_section"),
        ("h3", "seed003_section")]
    top = text[:text.index("<nav")]
    assert f'<a href="{reproduce.DEMO_LINK}">' in top and "<code>make reproduce</code>" in top
    lines = stderr.getvalue().splitlines()
    assert len(lines) == 9 and all(line.startswith("[reproduce ") for line in lines)
    assert lines[0].split("] ")[1].startswith("identification (seed 002")


def test_readme_plant_file_is_the_example() -> None:
    """The README's plant file is examples/plant_two_mass.json (the demo's), and it loads."""
    text = (REPOSITORY / "README.md").read_text(encoding="utf-8")
    start = text.index("### A report for your own data")
    block = text[text.index("```json", start) + len("```json"): text.index("```", text.index("```json", start) + 7)]
    assert json.loads(block) == json.loads(PLANT.read_text(encoding="utf-8"))
    spec = plant_spec(json.loads(block))
    assert (spec.shaper, dict(spec.shaper_params), spec.controller, spec.ms) == ("zvdk", {"k": 2}, "pi", 1.4)
    assert abs(spec.mode.omega - 3.2073511) < 1e-6  # seed 003: 3.2074 rad/s


def test_plant_with_a_delay_keeps_its_verdicts(tmp_path) -> None:
    """Seed 000 section V with 5 ms of dead time and the inverse DZV, a PD tuned: the simulator cannot run a
    rational block with a delay, so the responses say why; the certified verdicts and the tuning are there."""
    p = tmp_path / "s0.json"
    p.write_text(json.dumps({"plant": {"num": [1], "den": [1, 1, 0], "delay": 0.005},
                             "load": {"num": [1, 0], "den": [1, 0.6, 100]},
                             "controller": {"num": [10, 10], "den": [0.01, 1]}, "shaper": "dzv",
                             "architecture": "inverse_shaper", "tune": {"controller": "pd", "ms": 2}}))
    s = write_report(p, tmp_path / "out")
    assert [x["stable"] for x in s.details["loops"]] == [True] * 4 and s.figures == ()
    page = _Page(s.index.read_text(encoding="utf-8"))
    _check_page(page)
    notes = [r[-1] for t in page.tables if t[0][-1:] == ["note"] for r in t[1:]]
    assert len(notes) == 4 and all(n.startswith("not simulated: ") for n in notes)
    assert s.details["tuned"]["gains"]["kd"] > 0 and s.details["tuned"]["stable"]


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def test_figure_laid_out_is_saved_whole_and_loose_text_is_kept() -> None:
    """A tight_layout figure is saved at its canvas size in one pass (issue #15: the tight bbox cost a
    third pass over every artist); a figure-level text placed outside the canvas still forces the tight
    bbox, so it is not clipped; a figure without a layout engine is cropped as before."""
    import matplotlib.pyplot as plt

    page = Page("t")
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot([0, 1], [0, 1])
    ax.set_title("title")
    fig.tight_layout()
    page.figure(fig, "laid_out")
    assert _png_size(page._figures[-1][1]) == (400, 300)  # dpi 100, the canvas as laid out

    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot([0, 1], [0, 1])
    fig.tight_layout()
    fig.text(1.2, 0.5, "far to the right")  # outside the canvas: the tight bbox must grow to hold it
    page.figure(fig, "loose_text")
    assert _png_size(page._figures[-1][1])[0] > 400

    fig, ax = plt.subplots(figsize=(4, 3))  # no layout engine: cropped to its content
    ax.plot([0, 1], [0, 1])
    page.figure(fig, "plain")
    w, h = _png_size(page._figures[-1][1])
    assert w < 400 and h < 300
