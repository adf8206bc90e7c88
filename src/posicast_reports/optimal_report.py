"""Report section for ``make demo``: optimal shapers (issue #17) against the closed forms.

Three tables and one figure, about 1-2 s: the specified-insensitivity shaper against every
closed-form family on several bands, the unity-magnitude shapers against their published
forms, and the 42 Hz / 63 Hz two-mode case with at most 5 impulses against convolutions of
single-mode shapers.
"""

from __future__ import annotations

import math
from functools import reduce

import matplotlib.pyplot as plt
import numpy as np

from posicast.analysis import residual_vibration
from posicast.modes import Mode
from posicast.shapers import design, shortest_shaper
from posicast.shapers.negative import um_fit_times

from .html import Report

__all__ = ["optimal_section", "CLOSED_FORMS", "BANDS"]

CLOSED_FORMS = [("ZV", "zv", {}), ("ZVD", "zvd", {}), ("ZVDD", "zvdd", {}), ("ZVDDD", "zvddd", {}),
                ("MZV", "mzv", {}), ("EI", "ei", {"vtol": 0.05}), ("2-hump EI", "ei2", {"vtol": 0.05}),
                ("3-hump EI", "ei3", {"vtol": 0.05})]
BANDS = [(0.95, 1.05), (0.9, 1.1), (0.8, 1.2), (0.7, 1.3), (0.6, 1.4)]
M42, M63 = Mode.from_hz(42.0, 0.05), Mode.from_hz(63.0, 0.05)


def _worst(S, modes, band, n: int = 2001) -> float:
    r = np.linspace(band[0], band[1], n)
    return max(float(np.max(residual_vibration(S, r * m.omega, m.zeta))) for m in modes)


def _si_table(report: Report, mode: Mode) -> dict:
    rows, designed = [], {}
    closed = [(label, design(kind, mode, **params)) for label, kind, params in CLOSED_FORMS]
    for band in BANDS:
        S = designed[band] = design("si", mode, vtol=0.05, band=band)
        best = None
        for label, C in closed:
            if _worst(C, [mode], band) <= 0.05 * (1 + 1e-9) and (best is None or C.duration < best[1]):
                best = (label, C.duration)
        o = S.optimality
        rows.append([f"{band[0]:g}-{band[1]:g}", S.duration / mode.damped_period, S.n_impulses,
                     _worst(S, [mode], band), o.lower_bound / mode.damped_period, o.status,
                     math.nan if o.kkt_residual is None else o.kkt_residual,
                     best[0] if best else "none", best[1] / mode.damped_period if best else math.nan])
    report.table(["band (ratio)", "SI duration [T_d]", "impulses", "max V on band", "certified lower bound [T_d]",
                  "status", "KKT residual", "shortest closed form meeting the band", "its duration [T_d]"], rows)
    return designed


def _figure(report: Report, mode: Mode, si: dict) -> None:
    r = np.linspace(0.5, 1.5, 1001)
    fig, ax = plt.subplots(figsize=(7, 3.6))
    for label, S in [("SI 0.8-1.2", si[(0.8, 1.2)]), ("SI 0.9-1.1", si[(0.9, 1.1)]),
                     ("EI 5 %", design("ei", mode, vtol=0.05)), ("ZVD", design("zvd", mode)),
                     ("UM-ZV", design("um_zv", mode)),
                     ("UM-SI 0.9-1.1 (+-1)", design("um_si", mode, vtol=0.05, band=(0.9, 1.1)))]:
        ax.plot(r, 100 * residual_vibration(S, r * mode.omega, mode.zeta),
                label=f"{label} ({S.duration / mode.damped_period:.3f} T_d)")
    ax.axhline(5.0, color="k", lw=0.8, ls=":")
    ax.set_xlabel("omega / omega_model")
    ax.set_ylabel("residual vibration [%]")
    ax.set_ylim(0, 40)
    ax.legend(fontsize=8)
    report.figure(fig, "optimal_si", "Specified-insensitivity shapers against EI, ZVD, UM-ZV and the unity-magnitude "
                  "SI shaper (impulses +-1) for the same +-10 % band (zeta = 0.05).")


def _um_table(report: Report) -> None:
    rows = []
    for zeta in (0.0, 0.05, 0.1, 0.2):
        m = Mode(2 * math.pi, zeta)
        for kind in ("um_zv", "um_zvd"):
            S = design(kind, m)
            fit = um_fit_times(kind, m)
            rows.append([kind.upper().replace("_", "-"), zeta, ", ".join(f"{t:.5f}" for t in S.times),
                         ", ".join(f"{t:.5f}" for t in fit), S.duration / m.damped_period, abs(S(m.pole)),
                         S.params["l1_norm"]])
    report.table(["shaper", "zeta", "times [T_n] (solved)", "published fit [T_n]", "duration [T_d]", "|S(p)|",
                  "sum |A_i|"], rows, digits=5)


def _two_mode_table(report: Report) -> None:
    band = (0.9, 1.1)
    modes = [M42, M63]
    zz = design("zv", M42) * design("zv", M63)
    v_zz = _worst(zz, modes, band)
    cases = [
        ("optimal, <= 5 impulses, V <= 5 %", shortest_shaper(modes, vtol=0.05, band=band, max_impulses=5)),
        ("optimal, <= 5 impulses on a 0.1 ms grid", shortest_shaper(modes, vtol=0.05, band=band, max_impulses=5,
                                                                     sample_period=1e-4)),
        (f"optimal, <= 5 impulses, V <= ZV*ZV's {v_zz:.3f}",
         shortest_shaper(modes, vtol=v_zz, band=band, max_impulses=5)),
        ("optimal, <= 5 impulses, duration <= ZV*ZV's",
         shortest_shaper(modes, vtol=0.05, band=band, max_impulses=5, max_duration=zz.duration)),
        ("ZV(42) * ZV(63)", zz),
        ("ZV(42) * ZVD(63)", design("zv", M42) * design("zvd", M63)),
        ("ZVD(42) * ZVD(63)", reduce(lambda a, b: a * b, [design("zvd", m) for m in modes])),
        ("EI(42) * EI(63)", design("ei", M42, vtol=0.05) * design("ei", M63, vtol=0.05)),
    ]
    rows = []
    for label, S in cases:
        o = getattr(S, "optimality", None)
        rows.append([label, S.n_impulses, 1e3 * S.duration, _worst(S, [M42], band), _worst(S, [M63], band),
                     o.status if o else "closed form", 1e3 * o.lower_bound if o and o.lower_bound else math.nan])
    report.table(["shaper", "impulses", "duration [ms]", "max V 42 Hz +-10 %", "max V 63 Hz +-10 %", "status",
                  "certified lower bound [ms]"], rows)


def optimal_section(report: Report) -> None:
    """Issue #17: SI, unity-magnitude and limited-impulse shapers."""
    report.section(
        "Optimal shapers: specified insensitivity, unity magnitude, limited impulses (issue #17)",
        "Specified-insensitivity (SI) shapers are the shortest positive shapers keeping the residual vibration "
        "below vtol = 5 % over a band of frequency ratios (Singhose, Seering, Singer 1996/1997), here computed "
        "by an LP on a time grid, an SLSQP polish with exchanged frequencies, and an LP relaxation that proves "
        "a duration lower bound. The table compares each with the shortest closed-form family meeting the same "
        "band (zeta = 0.05; durations in damped periods).")
    mode = Mode(2 * math.pi, 0.05)
    _figure(report, mode, _si_table(report, mode))
    report.paragraph("Unity-magnitude shapers (impulses +1, -1, +1, ...; Singhose, Seering, Singer, ASME JDSMC 1997) "
                     "solved from their definitions, against the published cubic fits in zeta (times in undamped "
                     "periods T_n). The running sum of the impulses is 0 or 1: a step command within the actuator "
                     "range stays within it; for other inputs the shaped command is bounded by sum |A_i| times the "
                     "input's bound.")
    _um_table(report)
    report.paragraph("Two modes, 42 Hz and 63 Hz (zeta = 0.05), each with a +-10 % band: the shortest shaper "
                     "with at most 5 impulses (RepRapFirmware's custom-shaper limit) against convolutions of "
                     "single-mode shapers. 'duration <= ZV*ZV's' is infeasible at 5 %: the row shows the "
                     "least-vibration shaper of that duration, as the result reports it.")
    _two_mode_table(report)
