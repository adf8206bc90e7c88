"""Fixed controller structures for automatic loop shaping: a gain times a product of named sections.

Each section is in the normalised (unit DC gain) form, so the gain ``K`` is the controller's DC gain
and the frequencies are where the sections act:

==================  =============================================  ===========================
section             factor                                          parameters
==================  =============================================  ===========================
``real_zero``       ``s / z + 1``                                   ``z``
``real_pole``       ``1 / (s / p + 1)``                             ``p``
``lead``            ``(s / z + 1) / (s / p + 1)``                   ``z, p``
``complex_zero``    ``s^2 / w^2 + 2 zeta s / w + 1``                ``w, zeta``
``complex_pole``    ``1 / (s^2 / w^2 + 2 zeta s / w + 1)``          ``w, zeta``
``second_order``    ``(s^2/wz^2 + 2 zz s/wz + 1) / (s^2/wp^2 + 2 zp s/wp + 1)``  ``wz, zz, wp, zp``
``notch``           ``(s^2/w^2 + 2 zz s/w + 1) / (s^2/w^2 + 2 zp s/w + 1)``      ``w, zz, zp``
``integrator``      ``1 / s`` (``K`` is then the velocity gain)     none
==================  =============================================  ===========================

All parameters are positive and optimised on a log scale; dampings are kept in ``[0.05, 2]``.

>>> st = Structure(("lead", "real_pole"))
>>> st.n_params, st.names
(4, ('K', 'lead.z', 'lead.p', 'real_pole.p'))
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import _validate as v
from ..core.transfer import TransferFunction

__all__ = ["SECTIONS", "Structure"]

# section -> (parameter names, which are dampings)
SECTIONS: dict[str, tuple[str, ...]] = {
    "real_zero": ("z",),
    "real_pole": ("p",),
    "lead": ("z", "p"),
    "complex_zero": ("w", "zeta"),
    "complex_pole": ("w", "zeta"),
    "second_order": ("wz", "zz", "wp", "zp"),
    "notch": ("w", "zz", "zp"),
    "integrator": (),
}
_DAMPINGS = {"zeta", "zz", "zp"}
ZETA_RANGE = (0.05, 2.0)


def _first(w: float) -> np.ndarray:
    return np.array([1.0 / w, 1.0])


def _second(w: float, z: float) -> np.ndarray:
    return np.array([1.0 / (w * w), 2.0 * z / w, 1.0])


@dataclass(frozen=True)
class Structure:
    """A controller ``K * prod(sections)`` with named, positive parameters.

    Parameters
    ----------
    sections : tuple of str
        Section names from :data:`SECTIONS` (repeat a name for several sections).
    """

    sections: tuple[str, ...]

    def __post_init__(self) -> None:
        secs = tuple(v.sequence(self.sections, "sections"))
        for s in secs:
            v.choice(s, "sections[]", tuple(SECTIONS))
        object.__setattr__(self, "sections", secs)

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names, ``K`` first."""
        out, seen = ["K"], {}
        for s in self.sections:
            seen[s] = seen.get(s, 0) + 1
            tag = s if self.sections.count(s) == 1 else f"{s}{seen[s]}"
            out += [f"{tag}.{p}" for p in SECTIONS[s]]
        return tuple(out)

    @property
    def n_params(self) -> int:
        return len(self.names)

    @property
    def relative_degree(self) -> int:
        """Denominator degree minus numerator degree (negative: improper)."""
        d = 0
        for s in self.sections:
            d += {"real_zero": -1, "real_pole": 1, "complex_zero": -2, "complex_pole": 2, "integrator": 1}.get(s, 0)
        return d

    def bounds(self, w_lo: float, w_hi: float) -> list[tuple[float, float]]:
        """Log-parameter bounds: frequencies in ``[w_lo, w_hi]``, dampings in :data:`ZETA_RANGE`."""
        out = [(-30.0, 30.0)]
        for name in self.names[1:]:
            if name.split(".")[1] in _DAMPINGS:
                out.append((float(np.log(ZETA_RANGE[0])), float(np.log(ZETA_RANGE[1]))))
            else:
                out.append((float(np.log(w_lo)), float(np.log(w_hi))))
        return out

    def is_damping(self) -> np.ndarray:
        return np.array([n.split(".")[-1] in _DAMPINGS for n in self.names])

    def polynomials(self, x: Any) -> tuple[np.ndarray, np.ndarray]:
        """``(num, den)`` in descending powers for log-parameters ``x``."""
        p = np.exp(np.asarray(x, float))
        num, den = np.array([p[0]]), np.array([1.0])
        i = 1
        for s in self.sections:
            q = p[i:i + len(SECTIONS[s])]
            i += len(q)
            if s == "real_zero":
                num = np.convolve(num, _first(q[0]))
            elif s == "real_pole":
                den = np.convolve(den, _first(q[0]))
            elif s == "lead":
                num, den = np.convolve(num, _first(q[0])), np.convolve(den, _first(q[1]))
            elif s == "complex_zero":
                num = np.convolve(num, _second(q[0], q[1]))
            elif s == "complex_pole":
                den = np.convolve(den, _second(q[0], q[1]))
            elif s == "second_order":
                num, den = np.convolve(num, _second(q[0], q[1])), np.convolve(den, _second(q[2], q[3]))
            elif s == "notch":
                num, den = np.convolve(num, _second(q[0], q[1])), np.convolve(den, _second(q[0], q[2]))
            else:  # integrator
                den = np.convolve(den, [1.0, 0.0])
        return num, den

    def transfer(self, x: Any) -> TransferFunction:
        """The controller for log-parameters ``x`` as an exact transfer function."""
        num, den = self.polynomials(x)
        return TransferFunction.from_poly(num, den)

    def high_frequency_gain(self, x: Any) -> float:
        """QFT's cost: ``lim |G(s) s^r|`` as ``s -> inf`` (``r`` the relative degree): the leading-coefficient ratio."""
        num, den = self.polynomials(x)
        return float(abs(num[0] / den[0]))

    def parameters(self, x: Any) -> dict[str, float]:
        """Parameter name -> value (not logarithms)."""
        return dict(zip(self.names, map(float, np.exp(np.asarray(x, float)))))
