"""From identified modes to the best setting a firmware can run, and to posicast's own optimum.

**What is scored.**  Every shaper type the firmware offers, at every frequency it
accepts (0.2 Hz steps) and at two design damping ratios (the firmware's default 0.1
and the identified dominant mode's), on the impulses the firmware itself computes
(:mod:`posicast.firmware`):

* ``vibration``: posicast's worst case.  With measured spectra (every printer file):
  the residual vibration (seed 004 eq. 1-3) averaged over the spectrum's significant
  bins weighted by their power, worst over the identified damping range and a
  ``+-margin`` drift of the spectrum (a machine's modes move with position and load);
  this replaces the single assumed damping of the firmware tools.  Without spectra
  (input/output data): the largest residual vibration over each mode's 95 % box
  (frequency interval widened by ``margin``), weighted by the mode's share;
* ``firmware_vibration``: Klipper's own remaining-vibrations metric on the measured
  spectra (worst of damping 0.075, 0.1, 0.15 and of the files), when spectra exist;
* smoothing and ``max_accel`` as Klipper's calibration computes them (the only
  published measure; used for every firmware, for comparison).

**What is chosen.**  By default the best trade-off: Klipper's own score
``smoothing (w^1.5 + 0.2 w + 0.01)`` (shaper_calibrate.py), but on posicast's worst
case ``w`` rather than on vibrations at assumed dampings.  With a target ``vtol``, the
least smoothing among the settings whose worst case stays within it (the trade-off,
with a warning line, when none does); ``max_smoothing`` bounds the smoothing.  With
spectra, the firmware tool's own pick is computed too (Klipper's selection rules,
:func:`posicast.firmware.klipper.klipper_recommendation`), and a setting is only
eligible if Klipper's metric rates it at most ``slack`` (default one point) worse
than that pick and that pick does not dominate it (as good or better in both
vibration and smoothing): posicast never prints a line the firmware's own tool beats
on its own terms.

**posicast's optimum** (no firmware limits): posicast's exact designs (``zv``,
``mzv``, ``zvd``, ``ei``, ``ei2``, ``ei3``) at each mode and their convolutions over
the modes, the shortest within ``vtol`` over the boxes; for JSON or C export.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple, Sequence

import numpy as np

from .. import _validate as v
from ..firmware import Firmware, Klipper, Setting, ShaperType, vibration_grid
from ..firmware.base import smoothing_offsets, unchecked_vibration_grid
from ..firmware.klipper import DEFAULT_DAMPING, _above_threshold, firmware_vibrations, klipper_recommendation
from ..modes import Mode
from ..shapers import Shaper, design
from .results import Interval

__all__ = ["ModeBox", "mode_boxes", "Candidate", "Recommendation", "recommend_setting", "optimum",
           "klipper_smoothing"]

Spectra = list[tuple[np.ndarray, np.ndarray]]
_MAX_GRID = 800


@dataclass(frozen=True)
class ModeBox:
    """One mode's uncertainty for scoring: frequency (rad/s) and damping ranges, and its weight."""

    mode: Mode
    omega: tuple[float, float]
    zeta: tuple[float, float]
    weight: float

    def grid(self, n_w: int = 9, n_z: int = 3) -> tuple[np.ndarray, np.ndarray]:
        """Frequencies (Hz) and damping ratios spanning the box."""
        f = np.linspace(self.omega[0], self.omega[1], n_w) / (2.0 * math.pi)
        z = np.linspace(self.zeta[0], self.zeta[1], n_z)
        return f, z


def mode_boxes(modes: Sequence[Mode], intervals: Sequence[Interval], shares: Sequence[float] | None = None,
               margin: float = 0.05) -> list[ModeBox]:
    """The boxes of identified modes: intervals widened by ``margin``, weights ``share / max share``."""
    margin = _margin(margin)
    modes = v.sequence(modes, "modes", min_len=1)
    intervals = v.sequence(intervals, "intervals")
    if not all(isinstance(m, Mode) for m in modes):
        raise TypeError("modes must be posicast Mode objects")
    if len(intervals) != len(modes):
        raise ValueError(f"intervals must have one entry per mode ({len(modes)}), got {len(intervals)}")
    ivs = []
    for k, iv in enumerate(intervals):
        try:
            (w0, w1), (z0, z1) = iv
        except (TypeError, ValueError):
            raise TypeError(f"intervals[{k}] must be an Interval ((omega_lo, omega_hi), (zeta_lo, zeta_hi))") from None
        w0, w1 = v.positive(w0, f"intervals[{k}].omega[0]"), v.positive(w1, f"intervals[{k}].omega[1]")
        z0, z1 = v.real(z0, f"intervals[{k}].zeta[0]"), v.real(z1, f"intervals[{k}].zeta[1]")
        if not (w0 <= w1 and 0.0 <= z0 <= z1 and w1 < 1e12):
            raise ValueError(f"intervals[{k}] must have 0 < omega_lo <= omega_hi < 1e12 and 0 <= zeta_lo <= zeta_hi, "
                             f"got {iv!r}")
        ivs.append(Interval((w0, w1), (z0, z1)))
    intervals = ivs
    if shares is not None and not isinstance(shares, (list, tuple, np.ndarray)):
        raise TypeError(f"shares must be a sequence of numbers (one per mode) or None, got {type(shares).__name__}")
    if shares is not None and len(shares) > 0:
        sh = v.strict_real_array(shares, "shares")
        if sh.shape != (len(modes),) or np.any(sh < 0):
            raise ValueError(f"shares must be {len(modes)} values >= 0 (one per mode), got {sh.tolist()}")
    else:
        sh = np.ones(len(modes))
    w = sh / sh.max() if sh.max() > 0 else np.ones(len(modes))
    out = []
    for m, iv, wk in zip(modes, intervals, w):
        lo, hi = iv.omega
        z0, z1 = max(iv.zeta[0], 0.0), min(max(iv.zeta[1], m.zeta), 0.95)
        out.append(ModeBox(m, (lo * (1 - margin), hi * (1 + margin)), (z0, z1), float(wk)))
    return out


@dataclass(frozen=True)
class Candidate:
    """One scored firmware setting.

    Attributes
    ----------
    setting : Setting
        Firmware, shaper type, frequency, design damping.
    vibration : float
        posicast's worst case (module docstring), 0..1.
    per_mode : tuple of float
        Without spectra, the weighted worst case per mode; with spectra, the one value.
    firmware_vibration : float or None
        Klipper's remaining vibrations on the measured spectra, 0..1 (None without spectra).
    smoothing : float
        Klipper's smoothing at 5000 mm/s^2, mm.
    max_accel : float
        Acceleration at which the smoothing reaches 0.12 mm, mm/s^2.
    """

    setting: Setting
    vibration: float
    per_mode: tuple[float, ...]
    firmware_vibration: float | None
    smoothing: float
    max_accel: float

    @property
    def label(self) -> str:
        return self.setting.describe()

    @property
    def shaper(self) -> Shaper:
        return self.setting.shaper()

    def row(self) -> str:
        fv = "   -  " if self.firmware_vibration is None else f"{100 * self.firmware_vibration:6.1f}"
        return (f"{self.setting.shaper_type.written:>16} {self.setting.freq:7.1f} {self.setting.damping:6.3f} "
                f"{100 * self.vibration:8.1f} {fv} {self.smoothing:9.3f} {self.max_accel:9.0f}")


HEADER = f"{'type':>16} {'freq Hz':>7} {'damp':>6} {'worst %':>8} {'fw %':>6} {'smooth mm':>9} {'max_accel':>9}"


@dataclass
class Recommendation:
    """The recommendation for one firmware (and axis).

    Attributes
    ----------
    firmware : Firmware
    axis : str or None
    best : Candidate
    per_type : dict of str to Candidate
        The best setting of each shaper type (same rule as ``best``).
    reference : Candidate or None
        The firmware tool's own pick on the same spectra (Klipper's rules).
    config : list of str
        The lines to paste.
    reasoning : list of str
    """

    firmware: Firmware
    axis: str | None
    best: Candidate
    per_type: dict[str, Candidate]
    reference: Candidate | None
    config: list[str]
    reasoning: list[str] = field(default_factory=list)

    def table(self) -> str:
        lines = [HEADER] + [c.row() + ("   <- recommended" if c.setting == self.best.setting else "")
                            for c in self.per_type.values()]
        if self.reference is not None:
            lines.append(self.reference.row() + f"   <- {self.firmware.name}'s own tool")
        return "\n".join(lines)


def _margin(margin: Any) -> float:
    return v.real_in_range(margin, "margin", 0.0, 0.5, hi_open=True)


@v.renamed_keywords(shaper="S")
def klipper_smoothing(S: Shaper, accel: float = 5000.0, scv: float = 5.0) -> float:
    """Klipper's smoothing of an impulse shaper (mm): the offset after a 90 or 180 degree turn.

    As ``_get_shaper_smoothing`` of Klipper's shaper_calibrate.py: ``accel`` in mm/s^2,
    ``scv`` the square corner velocity in mm/s.  NaN for distributed or IIR shapers.

    Examples
    --------
    >>> from posicast import Mode, design
    >>> a = klipper_smoothing(design("zv", Mode.from_hz(50, 0.1)))
    >>> b = klipper_smoothing(design("zvd", Mode.from_hz(50, 0.1)))
    >>> 0 < a < b
    True
    """
    v.instance_of(S, Shaper, "S", "a shaper (a posicast Shaper)")
    accel = v.positive(accel, "accel")
    scv = v.nonnegative(scv, "scv")
    if S.distributed or S.continuous is not None:
        return float("nan")
    T, A = S.impulses
    c1, c2, c3 = smoothing_offsets(A, T)
    return float(max(math.sqrt(2.0) * (scv * c1 + 0.5 * accel * c2), 0.5 * accel * c3))


# ----------------------------------------------------------------------------- scoring


@dataclass
class _Scored:
    st: ShaperType
    damping: float
    freqs: np.ndarray
    vib: np.ndarray
    per_mode: np.ndarray
    fv: np.ndarray
    sm: np.ndarray
    ma: np.ndarray


def machine_damping(boxes: list[ModeBox], share: float = 0.2) -> tuple[float, float, float]:
    """Damping ratios to score with: the lowest, middle and highest of the main modes' intervals.

    Main modes are those with at least ``share`` of the largest one's weight; the range is
    clipped to [0.02, 0.3] (below, no printer frame is that lightly damped; above, every
    firmware shaper's residual is already small).
    """
    main = [b for b in boxes if b.weight >= share] or boxes
    lo = min(max(b.zeta[0], 0.02) for b in main)
    hi = max(min(b.zeta[1], 0.3) for b in main)
    lo, hi = min(lo, 0.3), max(hi, 0.02)
    if hi < lo:
        lo, hi = hi, lo
    mid = float(np.median([min(max(b.mode.zeta, lo), hi) for b in main]))
    return (lo, mid, hi)


def _score_type(fw: Firmware, st: ShaperType, damping: float, freqs: np.ndarray, boxes: list[ModeBox],
                spectra: Spectra, dampings: tuple[float, ...], margin: float) -> _Scored:
    A, T1 = st.impulses(1.0, damping)
    T = fw.times(T1[None, :] / freqs[:, None])
    if spectra:
        # remaining vibrations on the measured spectra (Klipper's measure) at the machine's own damping
        # range, with the spectrum stretched by +-margin (modes drift with position and load)
        vib = np.zeros(freqs.size)
        drift = (1.0 - margin, 1.0, 1.0 + margin) if margin > 0 else (1.0,)
        for bins, psd in spectra:
            # the residual vibration (seed 004 eq. 1-3) averaged over the spectrum's significant bins (above
            # 1/20 of its maximum), weighted by their power: the share of the measured vibration left.  Unlike
            # Klipper's measure it does not subtract the 1/20 threshold (which reads a 7 % residual at the
            # peak as 2 %), so vtol means what it says
            b, p, _ = _above_threshold(bins, psd)
            V = unchecked_vibration_grid(A, T, np.concatenate([b * d for d in drift]), np.asarray(dampings))
            V = V.reshape(freqs.size, len(drift), b.size, len(dampings))
            R = np.einsum("fdbz,b->fdz", V, p) / float(p.sum())  # [F, drift, zeta]
            vib = np.maximum(vib, R.max(axis=(1, 2)))
        fv = firmware_vibrations(A, T, spectra)  # Klipper's own measure: its test dampings, no drift
        per = vib[:, None]
    else:
        per = np.empty((freqs.size, len(boxes)))
        for k, bx in enumerate(boxes):
            fb, zb = bx.grid()
            per[:, k] = bx.weight * vibration_grid(A, T, fb, zb).reshape(freqs.size, -1).max(axis=1)
        vib = per.max(axis=1)
        fv = np.full(freqs.size, np.nan)
    return _Scored(st, damping, freqs, vib, per, fv, *fw.smoothing_and_max_accel(A, T))


def _grid(st: ShaperType, boxes: list[ModeBox], rel_step: float = 0.012) -> np.ndarray:
    """Shaper frequencies to try: 1.2 % steps from half the lowest main mode to twice the highest (refined later)."""
    main = [b for b in boxes if b.weight >= 0.2] or boxes
    f_lo = min(b.mode.freq_hz for b in main)
    f_hi = max(b.mode.freq_hz for b in main)
    lo = max(st.min_freq, 0.5 * f_lo)
    hi = min(st.max_freq, 2.0 * f_hi)
    if hi <= lo:
        return np.array([min(max(f_lo, st.min_freq), st.max_freq)])
    n = min(int(math.log(hi / lo) / math.log1p(rel_step)) + 1, _MAX_GRID)
    return _printable(np.geomspace(lo, hi, max(n, 2)), st)


def _printable(freqs: np.ndarray, st: ShaperType) -> np.ndarray:
    """Frequencies as the config lines print them (0.1 Hz), inside the type's range: what is scored is what runs."""
    f = np.unique(np.round(freqs, 1))
    return f[(f >= st.min_freq) & (f <= st.max_freq)]


def _candidate(fw: Firmware, sc: _Scored, i: int) -> Candidate:
    fv = float(sc.fv[i])
    return Candidate(Setting(fw, sc.st, float(sc.freqs[i]), sc.damping), float(sc.vib[i]),
                     tuple(float(x) for x in sc.per_mode[i]), None if math.isnan(fv) else fv, float(sc.sm[i]),
                     float(sc.ma[i]))


def _choose(vib: np.ndarray, fv: np.ndarray, sm: np.ndarray, vtol: float | None, max_smoothing: float | None,
            ref: Candidate | None, slack: float = 0.01) -> tuple[int, str]:
    """Index of the chosen setting and why (module docstring)."""
    ok = np.ones(vib.size, dtype=bool)
    if ref is not None and ref.firmware_vibration is not None:
        rv, rs = ref.firmware_vibration, ref.smoothing
        ok &= fv <= rv + slack
        ok &= ~((rv <= fv) & (rs <= sm) & ((rv < fv) | (rs < sm)))  # not dominated by the tool's own pick
    if max_smoothing is not None:
        ok &= sm <= max_smoothing
    if vtol is not None:
        feasible = ok & (vib <= vtol)
        if feasible.any():
            idx = np.flatnonzero(feasible)
            return int(idx[np.lexsort((vib[idx], sm[idx]))[0]]), "least smoothing within the vibration target"
    # Klipper's trade-off (shaper_calibrate.py's score), on posicast's worst case instead of one damping
    score = sm * (vib ** 1.5 + 0.2 * vib + 0.01)
    why = ("no setting reaches the vibration target; the best trade-off" if vtol is not None else
           "the best trade-off of vibration and smoothing")
    if ok.any():
        idx = np.flatnonzero(ok)
        return int(idx[np.argmin(score[idx])]), why
    return int(np.argmin(score)), why + " (no setting meets the constraints)"


def recommend_setting(fw: Firmware, boxes: list[ModeBox], spectra: Spectra | None = None, *,
                      vtol: float | None = None,
                      max_smoothing: float | None = None, axis: str | None = None, margin: float = 0.05,
                      slack: float = 0.01, extra_types: Sequence[ShaperType] = ()) -> Recommendation:
    """Search every setting ``fw`` can run and choose one (module docstring).

    Parameters
    ----------
    fw : Firmware
    boxes : list of ModeBox
        From :func:`mode_boxes` (the modes of every file that must be covered).
    spectra : list of (freqs, psd), optional
        Klipper-normalised x + y + z spectra (``ResonanceData.firmware_freqs/psd``).
    vtol : float, optional
        Worst-case vibration target, in (0, 1): the least smoothing within it wins.  None
        (default): the best trade-off, Klipper's score ``smoothing (w^1.5 + 0.2 w + 0.01)``
        on posicast's worst case ``w``.
    margin : float
        Frequency drift of the machine's modes (with spectra: the spectrum is stretched by it).
    max_smoothing : float, optional
        Upper bound on Klipper's smoothing, mm.
    slack : float
        How much more remaining vibration than the firmware tool's own pick (by the tool's
        measure, 0..1) may be traded for less smoothing; 0 allows none.
    axis : str, optional
        Axis letter for the config lines.
    extra_types : sequence of ShaperType
        More types to try (Klipper master's parametric ``mzv(n, t)``, ``ei(v_tol)``).
    """
    v.instance_of(fw, Firmware, "fw", "a posicast.firmware.Firmware")
    boxes = _boxes_arg(boxes)
    if axis is not None:
        axis = v.choice(axis, "axis", ("x", "y", "z"))
    if vtol is not None:
        vtol = v.in_open_interval(vtol, "vtol", 0.0, 1.0)
    if max_smoothing is not None:
        max_smoothing = v.positive(max_smoothing, "max_smoothing")
    slack = v.real_in_range(slack, "slack", 0.0, 0.2)
    spectra = [_spectrum(sp, k) for k, sp in enumerate(v.sequence(spectra or [], "spectra"))]
    margin = _margin(margin)
    dampings = machine_damping(boxes)
    types = dict(fw.types())
    main = sorted((b for b in boxes if b.weight >= 0.2), key=lambda b: -b.weight)
    for st in list(fw.extra_types([b.mode for b in main])) + list(extra_types):
        types[st.written] = st
    ref = _reference(fw, spectra) if spectra else None
    rule = _Rule(vtol, max_smoothing, ref, slack)
    scored, skipped = _score_types(fw, types, boxes, spectra, dampings, margin, rule)
    if not scored:
        raise ValueError(f"no {fw.name} shaper type is valid here: " + "; ".join(skipped))
    if ref is not None:  # the tool's own pick is always eligible: at worst posicast agrees with it
        rs = ref.setting
        scored.append(_score_type(fw, rs.shaper_type, rs.damping, np.array([rs.freq]), boxes, spectra, dampings,
                                  margin))
        ref = Candidate(rs, float(scored[-1].vib[0]), (float(scored[-1].vib[0]),), ref.firmware_vibration,
                        ref.smoothing, ref.max_accel)
        rule = rule._replace(reference=ref)
    best, why = _pick(fw, scored, rule)
    per_type = {name: _pick(fw, mine, rule)[0] for name in types
                if (mine := [s for s in scored if s.st.written == name])}
    reasoning = _reasoning(fw, best, why, ref, vtol, margin, dampings, bool(spectra)) + [f"skipped {s}" for s in skipped]
    return Recommendation(fw, axis, best, per_type, ref, _config(fw, best, axis, vtol), reasoning)


def _config(fw: Firmware, best: Candidate, axis: str | None, vtol: float | None) -> list[str]:
    """The firmware's configuration lines for ``best``, behind a warning when it misses the target ``vtol``."""
    config = fw.config(best.setting, axis or "x")
    if vtol is not None and best.vibration > vtol:
        mark = "#" if isinstance(fw, Klipper) else ";"
        which = f"{fw.name} setting for axis {axis}" if axis else f"{fw.name} setting"
        config = [f"{mark} warning: no {which} keeps the worst case within {100 * vtol:g} %; this one "
                  f"leaves {100 * best.vibration:.1f} %"] + config
    return config


def _boxes_arg(boxes: object) -> list[ModeBox]:
    """``boxes`` as a non-empty list of :class:`ModeBox`."""
    boxes = v.sequence(boxes, "boxes", min_len=1)
    if not all(isinstance(b, ModeBox) for b in boxes):
        raise TypeError("boxes must be ModeBox objects (from posicast.identification.mode_boxes)")
    return boxes


class _Rule(NamedTuple):
    """How :func:`_choose` picks among scored settings: the vibration target, the smoothing bound, the
    firmware tool's own pick and the slack allowed against it."""

    vtol: float | None
    max_smoothing: float | None
    reference: Candidate | None
    slack: float


def _pick(fw: Firmware, scored: list[_Scored], rule: _Rule) -> tuple[Candidate, str]:
    """The chosen setting among every frequency of ``scored``, and why."""
    where = [(s, i) for s in scored for i in range(s.freqs.size)]
    k, why = _choose(np.concatenate([s.vib for s in scored]), np.concatenate([s.fv for s in scored]),
                     np.concatenate([s.sm for s in scored]), *rule)
    return _candidate(fw, *where[k]), why


def _score_types(fw: Firmware, types: dict[str, ShaperType], boxes: list[ModeBox], spectra: Spectra,
                 dampings: tuple[float, float, float], margin: float, rule: _Rule) -> tuple[list[_Scored], list[str]]:
    """Every type at its design dampings on its frequency grid, refined around its choice; and the types skipped."""
    dom = max(boxes, key=lambda b: b.weight).mode
    scored: list[_Scored] = []
    skipped: list[str] = []
    for st in types.values():
        designs = sorted({DEFAULT_DAMPING, round(min(max(dom.zeta, 0.01), 0.3), 3)})
        designs = [d for d in designs if d < st.max_damping]
        if not designs:
            skipped.append(f"{st.written} (valid for damping < {st.max_damping:g} only)")
            continue
        freqs = _grid(st, boxes)
        mine = [_score_type(fw, st, d, freqs, boxes, spectra, dampings, margin) for d in designs]
        # refine around this type's choice: +-1.5 % in 0.2 % steps
        k, _ = _choose(np.concatenate([m.vib for m in mine]), np.concatenate([m.fv for m in mine]),
                       np.concatenate([m.sm for m in mine]), *rule)
        at = mine[k // freqs.size]
        f0 = float(freqs[k % freqs.size])
        fine = _printable(f0 * (1.0 + 0.002 * np.arange(-7, 8)), st)
        scored += mine + ([_score_type(fw, st, at.damping, fine, boxes, spectra, dampings, margin)] if fine.size else [])
    return scored, skipped


def _pct(fraction: float) -> str:
    """A fraction in percent for the notes: one decimal from 1 %, two significant digits below (0.023, not 0.0).

    >>> _pct(0.137), _pct(0.00023), _pct(0.0), _pct(0.001)
    ('13.7', '0.023', '0', '0.1')
    """
    p = 100.0 * fraction
    return "0" if p == 0 else (f"{p:.1f}" if p >= 1 else f"{p:.2g}")


def _reasoning(fw: Firmware, best: Candidate, why: str, ref: Candidate | None, vtol: float | None, margin: float,
               dampings: tuple[float, float, float], with_spectra: bool) -> list[str]:
    measure = (f"residual vibration weighted by the measured spectrum, worst over damping {dampings[0]:.3f}-"
               f"{dampings[2]:.3f} (the identified range) and a +-{100 * margin:.0f} % frequency drift"
               if with_spectra else "residual vibration over the modes' 95 % boxes")
    target = "" if vtol is None else f" (target {_pct(vtol)} %)"
    reasoning = [f"{fw.name}: {why}: {best.label}; worst case {_pct(best.vibration)} %{target}, "
                 f"smoothing {best.smoothing:.3f} mm, max_accel {best.max_accel:.0f} mm/s^2",
                 f"worst case = {measure}"]
    if ref is not None and ref.firmware_vibration is not None and best.firmware_vibration is not None:
        reasoning.append(f"{fw.name}'s own tool would pick {ref.label} (its remaining vibrations "
                         f"{_pct(ref.firmware_vibration)} %, smoothing {ref.smoothing:.3f} mm, worst case "
                         f"{_pct(ref.vibration)} %); posicast's pick has {_pct(best.firmware_vibration)} % "
                         "by the same measure")
    return reasoning


def _spectrum(sp: Any, k: int) -> tuple[np.ndarray, np.ndarray]:
    try:
        f, p = sp
    except (TypeError, ValueError):
        raise TypeError(f"spectra[{k}] must be a pair (freqs, psd)") from None
    f, p = v.strict_real_array(f, f"spectra[{k}] freqs"), v.strict_real_array(p, f"spectra[{k}] psd")
    if f.ndim != 1 or f.shape != p.shape or f.size < 4:
        raise ValueError(f"spectra[{k}]: freqs and psd must be 1-D of the same length (at least 4)")
    if np.any(f < 0) or np.any(np.diff(f) <= 0) or np.any(p < 0) or not np.any(p > 0):
        raise ValueError(f"spectra[{k}]: freqs must increase from >= 0 Hz and psd must be >= 0, not all 0")
    return f, p


def _reference(fw: Firmware, spectra: Spectra) -> Candidate | None:
    """The firmware tool's own pick (Klipper's rules; for other firmware, the same rules on its types)."""
    if isinstance(fw, Klipper):
        pick, _ = klipper_recommendation(fw, spectra)
    else:
        names = tuple(n for n, st in fw.types().items() if DEFAULT_DAMPING < st.max_damping)
        if not names:
            return None
        pick, _ = klipper_recommendation(fw, spectra, types=names)  # type: ignore[arg-type]
    return Candidate(pick.setting, math.inf, (), pick.vibrations, pick.smoothing, pick.max_accel)  # scored later


# ----------------------------------------------------------------------------- posicast's optimum


OPTIMUM_KINDS: list[tuple[str, dict[str, Any]]] = [("zv", {}), ("mzv", {}), ("zvd", {}), ("ei", {"vtol": 0.05}),
                                                   ("ei2", {"vtol": 0.05}), ("ei3", {"vtol": 0.05})]


def optimum(boxes: list[ModeBox], *, vtol: float = 0.05) -> tuple[Shaper, float, str]:
    """posicast's shortest exact design within ``vtol`` over the boxes (one mode or all of them convolved).

    Returns ``(shaper, worst_vibration, description)``; the most robust when none is within ``vtol``.
    """
    vtol = v.in_open_interval(vtol, "vtol", 0.0, 1.0)
    boxes = _boxes_arg(boxes)
    dom = max(boxes, key=lambda b: b.weight)
    options: list[tuple[str, Shaper]] = []
    for kind, params in OPTIMUM_KINDS:
        try:
            S = design(kind, dom.mode, **params)
        except ValueError:
            continue
        options.append((f"{kind} at {dom.mode.freq_hz:.2f} Hz", S))
        if len(boxes) > 1:
            # the dominant mode's design is one of the factors: designed once (issue #15; the multi-hump
            # EI designs are solved numerically)
            def one(b: ModeBox, kind: str = kind, params: dict[str, Any] = params, S: Shaper = S) -> Shaper:
                return S if b is dom else design(kind, b.mode, **params)

            try:
                Sc = one(boxes[0])
                for b in boxes[1:]:
                    Sc = Sc * one(b)
            except ValueError:
                continue
            options.append((f"{kind} convolved over {len(boxes)} modes", Sc))
    best: tuple[float, float, str, Shaper] | None = None
    for label, S in options:
        T, A = S.impulses
        worst = max(b.weight * float(vibration_grid(A, T, *b.grid()).max()) for b in boxes)
        key = (0.0 if worst <= vtol else 1.0, S.duration if worst <= vtol else worst)
        if best is None or key < (best[0], best[1]):
            best = (key[0], key[1], label, S)
    if best is None:
        raise ValueError("no posicast design is valid for these modes")
    S = best[3]
    T, A = S.impulses
    worst = max(b.weight * float(vibration_grid(A, T, *b.grid()).max()) for b in boxes)
    return S, worst, best[2]
