"""A lightly damped vibration mode: natural frequency and damping ratio."""

from __future__ import annotations

import math
from dataclasses import dataclass

from . import _validate as v

__all__ = ["Mode", "OMEGA_MIN", "OMEGA_MAX"]

#: Range of natural frequencies (rad/s) a Mode accepts: far inside the float range, so that
#: periods, decay rates and their products with any delay of a shaper stay finite.
OMEGA_MIN = 1e-100
OMEGA_MAX = 1e100


@dataclass(frozen=True)
class Mode:
    """An underdamped mode with poles ``-zeta*omega +/- j*omega*sqrt(1 - zeta**2)``.

    Parameters
    ----------
    omega : float
        Natural (undamped) frequency in rad/s, in ``[1e-100, 1e100]``
        (:data:`OMEGA_MIN`, :data:`OMEGA_MAX`).
    zeta : float
        Damping ratio, ``0 <= zeta < 1``.

    Raises
    ------
    TypeError
        A parameter that is not a real number (str, bool, complex, None).
    ValueError
        A parameter outside its range (NaN, inf, 0, negative, ``zeta >= 1``).

    Examples
    --------
    >>> m = Mode(5.49, 0.008)          # seed 001's gantry crane sway mode
    >>> round(m.damped_omega, 4)
    5.4898
    >>> Mode.from_hz(28.0, 0.05).omega == 2 * math.pi * 28.0
    True
    >>> Mode(0.0, 0.1)
    Traceback (most recent call last):
    ...
    ValueError: omega must be in [1e-100, 1e+100], got 0
    """

    omega: float
    zeta: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "omega", v.real_in_range(self.omega, "omega", OMEGA_MIN, OMEGA_MAX))
        z = v.real_in_range(self.zeta, "zeta", 0.0, 1.0, hi_open=True, hint=" (an underdamped mode)")
        object.__setattr__(self, "zeta", z + 0.0)  # -0.0 -> 0.0

    @classmethod
    def from_hz(cls, freq_hz: float, zeta: float) -> Mode:
        """Mode from its natural frequency in Hz (``[1e-100, 1e100] / (2 pi)``)."""
        f = v.real_in_range(freq_hz, "freq_hz", OMEGA_MIN / (2.0 * math.pi), OMEGA_MAX / (2.0 * math.pi))
        return cls(2.0 * math.pi * f, zeta)

    @property
    def freq_hz(self) -> float:
        return self.omega / (2.0 * math.pi)

    @property
    def damped_omega(self) -> float:
        """Damped frequency ``Omega = omega sqrt(1 - zeta^2)`` (rad/s)."""
        return self.omega * math.sqrt(1.0 - self.zeta**2)

    @property
    def decay(self) -> float:
        """Decay rate ``beta = zeta omega`` (1/s)."""
        return self.zeta * self.omega

    @property
    def damped_period(self) -> float:
        """Damped period ``2 pi / Omega`` (s)."""
        return 2.0 * math.pi / self.damped_omega

    @property
    def pole(self) -> complex:
        """The upper pole ``-beta + j Omega``."""
        return complex(-self.decay, self.damped_omega)

    def scaled(self, ratio: float) -> Mode:
        """The same damping at ``ratio`` times the frequency (``ratio > 0``; the result must be a valid Mode)."""
        r = v.real_in_range(ratio, "ratio", OMEGA_MIN / self.omega, OMEGA_MAX / self.omega,
                            hint=" (omega * ratio must stay in [1e-100, 1e100])")
        return Mode(self.omega * r, self.zeta)
