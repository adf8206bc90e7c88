"""Fixed-structure controllers that are affine in two free gains.

Every family is ``C(s) = (n0(s) + kx nx(s) + ky ny(s)) / dC(s)`` with fixed
polynomials: the H-infinity region method (seed 001 section 3) needs the
controller to be affine in the two gains of the plane, so that every
constraint ``|W X(j omega)| < gamma`` becomes a quadratic in one gain when the
other is fixed.  ``kx`` is the scanned gain (the horizontal axis of the
region plots) and ``ky`` the gain the secondary criterion maximises (vertical
axis).

==========================  ==========================================  ==========  ===========
family                      C(s)                                        kx (scan)   ky (max)
==========================  ==========================================  ==========  ===========
PI                          ``Kp + Ki / s``                             Kp          Ki (eq. 8)
PD                          ``Kp + Kd s`` (seed 001 eq. 9)              Kd          Kp (eq. 16)
PD, derivative filter Tf    ``Kp + Kd s / (Tf s + 1)``                  Kd          Kp
PID, one gain fixed         ``Kp + Ki / s + Kd s / (Tf s + 1)``         the other   Ki, or Kp
==========================  ==========================================  ==========  ===========

The PD orientation is seed 001 eq. 16: ``C / s = Kd + Kp / s`` is a PI
controller for ``s G``, so ``Kd`` plays the proportional and ``Kp`` the
integral gain, and "maximum integral gain" means maximum ``Kp``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from .. import _validate as v
from ..core.transfer import TransferFunction

__all__ = ["ControllerFamily", "pi_family", "pd_family", "pid_family", "GAIN_NAMES"]

GAIN_NAMES = ("kp", "ki", "kd")
# Derivative filter time constants accepted [s] (0, or within this range: 1/Tf stays far inside the floats).
FILTER_RANGE = (1e-12, 1e12)
# Largest fixed gain magnitude accepted (the scanned gains go 10^4 times beyond the natural scale).
MAX_GAIN = 1e12


def _pad(*polys: np.ndarray) -> list[np.ndarray]:
    n = max(len(p) for p in polys)
    return [np.concatenate([np.zeros(n - len(p)), p]) for p in polys]


@dataclass(frozen=True)
class ControllerFamily:
    """``C(s) = (n0 + kx nx + ky ny) / dC`` (numpy descending-power polynomials).

    Attributes
    ----------
    name : str
        ``'pi'``, ``'pd'`` or ``'pid'``.
    x, y : str
        Names of the scanned gain and of the maximised gain (``'kp'``, ``'ki'``, ``'kd'``).
    fixed : Mapping[str, float]
        Gains held fixed (PID with one gain fixed).
    derivative_filter : float
        ``Tf`` of the derivative term ``Kd s / (Tf s + 1)`` (0: ideal derivative).
    dC, n0, nx, ny : ndarray
        The polynomials, padded to one length.

    Examples
    --------
    >>> f = pd_family()
    >>> f.x, f.y
    ('kd', 'kp')
    >>> C = f.controller(0.5, 2.0)             # Kd = 0.5, Kp = 2
    >>> complex(C(1j))
    (2+0.5j)
    >>> dict(f.gains(0.5, 2.0))
    {'kp': 2.0, 'ki': 0.0, 'kd': 0.5}
    """

    name: str
    x: str
    y: str
    dC: np.ndarray
    n0: np.ndarray
    nx: np.ndarray
    ny: np.ndarray
    fixed: Mapping[str, float] = field(default_factory=dict)
    derivative_filter: float = 0.0

    def __post_init__(self) -> None:
        for name in ("name", "x", "y"):
            if not isinstance(getattr(self, name), str):
                raise TypeError(f"{name} must be a string, got {type(getattr(self, name)).__name__}")
        for name in ("x", "y"):
            v.choice(getattr(self, name), name, GAIN_NAMES)
        if self.x == self.y:
            raise ValueError(f"x and y must be different gains, got {self.x!r} twice")
        if not isinstance(self.fixed, Mapping):
            raise TypeError(f"fixed must be a mapping of gain names to values, got {type(self.fixed).__name__}")
        fixed = {}
        for k, val in self.fixed.items():
            v.choice(k, "fixed gain", GAIN_NAMES)
            fixed[k] = v.real_in_range(val, f"fixed[{k!r}]", -MAX_GAIN, MAX_GAIN)
        object.__setattr__(self, "fixed", MappingProxyType(fixed))
        object.__setattr__(self, "derivative_filter", _filter(self.derivative_filter))
        polys = []
        for name in ("dC", "n0", "nx", "ny"):
            arr = np.atleast_1d(v.strict_real_array(getattr(self, name), name))
            if arr.ndim != 1:
                raise ValueError(f"{name} must be a 1-D polynomial (descending powers), got shape {arr.shape}")
            polys.append(arr)
        if not np.any(polys[0]):
            raise ValueError("dC must not be identically zero")
        dC, n0, nx, ny = _pad(*polys)
        for arr in (dC, n0, nx, ny):
            arr.flags.writeable = False
        object.__setattr__(self, "dC", dC)
        object.__setattr__(self, "n0", n0)
        object.__setattr__(self, "nx", nx)
        object.__setattr__(self, "ny", ny)

    # ------------------------------------------------------------------ gains
    def gains(self, kx: float, ky: float) -> Mapping[str, float]:
        """All three gains ``{'kp', 'ki', 'kd'}`` at the plane point ``(kx, ky)`` (absent ones are 0)."""
        out = {g: 0.0 for g in GAIN_NAMES}
        out.update(self.fixed)
        out[self.x] = float(kx)
        out[self.y] = float(ky)
        return MappingProxyType(out)

    def numerator(self, kx: float, ky: float) -> np.ndarray:
        return self.n0 + kx * self.nx + ky * self.ny

    def controller(self, kx: float, ky: float) -> TransferFunction:
        """``C(s)`` at the plane point ``(kx, ky)`` as an exact transfer function."""
        return TransferFunction.from_poly(np.trim_zeros(self.numerator(kx, ky), "f") if np.any(
            self.numerator(kx, ky)) else [0.0], np.trim_zeros(self.dC, "f"))

    def term(self, which: str) -> TransferFunction:
        """One affine term as a transfer function: ``'0'`` (fixed part), ``'x'`` or ``'y'``."""
        num = {"0": self.n0, "x": self.nx, "y": self.ny}[which]
        trimmed = np.trim_zeros(num, "f")
        return TransferFunction.from_poly(trimmed if trimmed.size else [0.0], np.trim_zeros(self.dC, "f"))

    @property
    def is_proper(self) -> bool:
        """True if ``C`` is proper for every gain (no ideal derivative)."""
        deg_d = len(np.trim_zeros(self.dC, "f")) - 1
        return all(len(np.trim_zeros(p, "f")) - 1 <= deg_d for p in (self.n0, self.nx, self.ny) if np.any(p))

    def describe(self) -> str:
        """``C(s)`` in words, e.g. ``'Kp + Kd s'``."""
        parts = {"kp": "Kp", "ki": "Ki/s", "kd": "Kd s" if self.derivative_filter == 0 else
                 f"Kd s/({self.derivative_filter:g} s + 1)"}
        present = [g for g in GAIN_NAMES if g in (self.x, self.y) or g in self.fixed]
        text = " + ".join(parts[g] for g in present)
        if self.fixed:
            text += " (" + ", ".join(f"{k[0].upper()}{k[1:]} = {val:g} fixed" for k, val in self.fixed.items()) + ")"
        return text


def _filter(tf: Any) -> float:
    if tf is None:
        return 0.0
    val = v.finite_real(tf, "derivative_filter")
    if val < 0:
        raise ValueError(f"derivative_filter must be >= 0 (a time constant in s), got {val:g}")
    lo, hi = FILTER_RANGE
    if val != 0 and not lo <= val <= hi:
        raise ValueError(f"derivative_filter must be 0 or in [{lo:g}, {hi:g}] s, got {val:g}")
    return val


def pi_family() -> ControllerFamily:
    """``C = Kp + Ki / s = (Kp s + Ki) / s``; scan Kp, maximise Ki (seed 001 eq. 8)."""
    return ControllerFamily("pi", "kp", "ki", dC=[1.0, 0.0], n0=[0.0], nx=[1.0, 0.0], ny=[1.0])


def pd_family(derivative_filter: float | None = None) -> ControllerFamily:
    """``C = Kp + Kd s / (Tf s + 1)`` (``Tf = 0``: seed 001 eq. 9); scan Kd, maximise Kp (eq. 16)."""
    Tf = _filter(derivative_filter)
    return ControllerFamily("pd", "kd", "kp", dC=[Tf, 1.0], n0=[0.0], nx=[1.0, 0.0], ny=[Tf, 1.0],
                            derivative_filter=Tf)


def pid_family(fixed: Mapping[str, Any], maximize: str | None = None,
               derivative_filter: float | None = None) -> ControllerFamily:
    """``C = Kp + Ki / s + Kd s / (Tf s + 1)`` with one gain fixed.

    Parameters
    ----------
    fixed : {'kp': value} or {'ki': value} or {'kd': value}
        The gain held fixed; the other two span the plane.
    maximize : str, optional
        The free gain to maximise; default ``'ki'`` (minimum integral error,
        seed 001 eq. 8) unless ``ki`` is fixed, then ``'kp'``.
    derivative_filter : float, optional
        ``Tf >= 0``.
    """
    if not isinstance(fixed, Mapping):
        raise TypeError(f"fixed must be a mapping with exactly one of 'kp', 'ki', 'kd', e.g. {{'kd': 0.5}}; "
                        f"got {type(fixed).__name__}")
    if len(fixed) != 1:
        raise ValueError("fixed must be a mapping with exactly one of 'kp', 'ki', 'kd', e.g. {'kd': 0.5}")
    (name, value), = fixed.items()
    if not isinstance(name, str) or name not in GAIN_NAMES:
        raise ValueError(f"fixed gain must be one of {GAIN_NAMES}, got {name!r}")
    value = v.real_in_range(value, f"fixed[{name!r}]", -MAX_GAIN, MAX_GAIN)
    free = [g for g in GAIN_NAMES if g != name]
    if maximize is None:
        maximize = "ki" if "ki" in free else "kp"
    v.choice(maximize, "maximize", free)
    Tf = _filter(derivative_filter)
    scan = free[0] if free[1] == maximize else free[1]
    if name == "ki" and value == 0.0:
        # no integral action: drop the integrator, else s would cancel and leave a pole at 0 for every gain
        polys = {"kp": np.array([Tf, 1.0]), "kd": np.array([1.0, 0.0])}
        return ControllerFamily("pid", scan, maximize, dC=[Tf, 1.0], n0=[0.0], nx=polys[scan], ny=polys[maximize],
                                fixed={name: value}, derivative_filter=Tf)
    # C = (Kp s (Tf s + 1) + Ki (Tf s + 1) + Kd s^2) / (s (Tf s + 1))
    polys = {"kp": np.array([Tf, 1.0, 0.0]), "ki": np.array([0.0, Tf, 1.0]), "kd": np.array([1.0, 0.0, 0.0])}
    return ControllerFamily("pid", scan, maximize, dC=[Tf, 1.0, 0.0], n0=value * polys[name],
                            nx=polys[scan], ny=polys[maximize], fixed={name: value}, derivative_filter=Tf)
