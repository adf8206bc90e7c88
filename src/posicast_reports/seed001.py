"""Seed 001's case study: PD design for the gantry crane with every shaper (Table 1, Fig. 5-7).

The crane (``posicast.cases.gantry_crane``: G eq. 10 with its typo fixed, F eq. 11)
is controlled by a PD (eq. 9) in the control-action structure with ``Ms = 1.2``
and in the inverse-shaper structure with ``Ms = 2``; the four distributed-delay
shapers (eq. 12), the notch (eq. 13) and no shaper are compared.

**Our values differ from Table 1, and the difference is the paper's model.**
On eq. 10 as printed, every design posicast finds sits exactly on its Ms circle
(checked against brute force), with ``Kp`` 18-55 % above Table 1; the paper's
own gains have ``Ms`` 1.15-1.19 instead of 1.2 and 1.60-1.78 instead of 2 on that
model, so they are inside the region, not on its boundary.  Adding a pure loop
delay of about 11.5 ms (:data:`PAPER_DELAY`, fitted by :func:`fit_paper_delay`)
to G puts all twelve paper points on their Ms circles and reproduces every
``Kp`` and ``Kd`` of Table 1 to a few per cent, with the same optimum (maximum
``Kp``, eq. 16).  So the method and the optimum agree; the model the paper
designed on carried about 11 ms of dead time (e.g. a controller or inverter
cycle) that eq. 10 does not print.

The shaper parameters are ours: ``A`` matches Table 1 to 3 digits; ``tau`` is
0.2847 s for DeZV against the printed 0.286 because the paper tuned its
shapers to ``omega ~ 5.46-5.47 rad/s`` rather than 5.49: with ``T = pi / omega``
every printed ``tau`` and ``A`` is reproduced to its digits for
``5.4551 <= omega <= 5.4711`` (``T = 0.5742-0.5759 s``; the paper's
"``T = pi / omega = 0.574 s``" fits the low end, ``omega = 5.468-5.471``,
whereas ``pi / 5.49 = 0.5722 s``).  ``T = 0.574 s`` at
``omega = 5.49`` would move ``tau`` further away (0.2838 s for DeZV).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from scipy.optimize import minimize_scalar

from posicast.cases import ALL, CRANE_TABLE1, Case
from posicast.core.transfer import delay as pure_delay
from posicast.loops import Loop
from posicast.shapers import Shaper, design
from posicast.tune.design import TuningResult, tune_pd

__all__ = ["PAPER_DELAY", "STRUCTURES", "SHAPERS", "Table1Row", "table1", "paper_point_ms", "fit_paper_delay",
           "crane_shaper"]

# Loop delay [s] that makes posicast's optimum reproduce seed 001 Table 1: least squares on the
# logarithms of all 24 gains; fit_paper_delay() re-derives it (0.01150 s, rms error 2.0 %; the optimum
# is flat: 0.0116 s gives 2.05 %).
PAPER_DELAY = 0.0115

#: (structure, Ms, suffix of the Table 1 columns)
STRUCTURES: tuple[tuple[str, float, str], ...] = (("control_action", 1.2, "d"), ("inverse_shaper", 2.0, "i"))
SHAPERS: tuple[str | None, ...] = ("dezv", "dtzv", "dczv", "dtazv", "notch", None)


def _case() -> Case:
    return ALL["gantry_crane"]


def crane_shaper(kind: str | None) -> Shaper | None:
    """The shaper of a Table 1 row for the crane's sway mode (None: no shaper)."""
    return None if kind is None else design(kind, _case().mode)


def _paper_key(kind: str | None, suffix: str) -> str:
    if kind is not None:
        return kind
    return "none_direct" if suffix == "d" else "none_inverse"


@dataclass(frozen=True)
class Table1Row:
    """One design of the Table 1 comparison.

    Attributes
    ----------
    shaper : str or None
    structure : str
    ms_target : float
    result : TuningResult
        posicast's design on the model (with ``delay`` added to G).
    delay : float
        Loop delay added to G [s] (0: eq. 10 as printed).
    tau, A : float or None
        The shaper's delay and direct gain (eq. 12), ours.
    paper : dict
        Table 1's ``tau, A, Kp, Kd`` for this row.
    """

    shaper: str | None
    structure: str
    ms_target: float
    result: TuningResult
    delay: float
    tau: float | None
    A: float | None
    paper: dict

    @property
    def label(self) -> str:
        return "S = 1" if self.shaper is None else {"dezv": "DeZV", "dtzv": "DtZV", "dczv": "DcZV",
                                                    "dtazv": "DtaZV", "notch": "notch"}[self.shaper]

    def kp_error(self) -> float:
        """Relative difference of our ``Kp`` to the paper's."""
        return float(self.result.kp / self.paper["Kp"] - 1.0)

    def kd_error(self) -> float:
        return float(self.result.kd / self.paper["Kd"] - 1.0)


def paper_point_ms(structure: str, kind: str | None, kp: float, kd: float, delay: float = 0.0,
                   omega: np.ndarray | None = None) -> float:
    """Peak sensitivity of the loop with the paper's gains, on eq. 10 as printed (plus ``delay``).

    The peak on ``omega`` (default 0.01-300 rad/s, 15001 points) refined between its grid
    neighbours (a 150001-point grid reads up to 7e-8 lower).
    """
    case = _case()
    G = case.G if delay == 0 else case.G * pure_delay(delay)
    sens = Loop(structure, G=G, C=([kd, kp], [1.0]), F=case.F, S=crane_shaper(kind)).sensitivity
    w = np.linspace(0.01, 300.0, 15001) if omega is None else np.asarray(omega, dtype=float)
    mag = np.abs(sens.freqresp(w))
    i = int(np.argmax(mag))
    lo, hi = w[max(i - 1, 0)], w[min(i + 1, w.size - 1)]
    res = minimize_scalar(lambda x: -abs(sens(1j * x)), bounds=(lo, hi), method="bounded", options={"xatol": 1e-9})
    return float(max(mag[i], -res.fun))


def table1(delay: float = 0.0, shapers: Sequence[str | None] = SHAPERS, n_lines: int = 161,
           derivative_filter: float | None = None) -> list[Table1Row]:
    """Design the twelve PD controllers of seed 001 Table 1 (two structures x six shapers).

    Parameters
    ----------
    delay : float
        Loop delay added to the plant (``PAPER_DELAY`` reproduces the paper).
    shapers : sequence
        Subset of :data:`SHAPERS`.
    n_lines : int
        Region resolution.
    derivative_filter : float, optional
        Design realisable PDs ``Kp + Kd s / (Tf s + 1)`` instead (for simulation).
    """
    case = _case()
    G = case.G if delay == 0 else case.G * pure_delay(delay)
    rows = []
    for structure, ms, suffix in STRUCTURES:
        for kind in shapers:
            S = crane_shaper(kind)
            r = tune_pd(G, S, structure, ms=ms, F=case.F, n_lines=n_lines, derivative_filter=derivative_filter)
            p = CRANE_TABLE1[_paper_key(kind, suffix)]
            params = {} if S is None else dict(S.params)
            rows.append(Table1Row(kind, structure, ms, r, float(delay), params.get("tau"), params.get("A"),
                                  {"tau": p["tau"], "A": p["A"], "Kp": p["Kp_" + suffix], "Kd": p["Kd_" + suffix]}))
    return rows


def _log_error(rows: Sequence[Table1Row]) -> float:
    errs = []
    for r in rows:
        errs += [math.log(r.result.kp / r.paper["Kp"]), math.log(r.result.kd / r.paper["Kd"])]
    return float(np.sqrt(np.mean(np.square(errs))))


def fit_paper_delay(bounds: tuple[float, float] = (0.008, 0.014), n_lines: int = 81) -> tuple[float, float]:
    """The loop delay whose designs best reproduce Table 1: ``(delay, rms relative error)``.

    Least squares on the logarithms of all 24 gains (12 ``Kp``, 12 ``Kd``), a
    bounded 1-D search.  About a minute.
    """
    res = minimize_scalar(lambda d: _log_error(table1(d, n_lines=n_lines)), bounds=bounds, method="bounded",
                          options={"xatol": 1e-5})
    return float(res.x), float(math.expm1(res.fun))

