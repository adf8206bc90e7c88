"""H-infinity loop-shaping constraints ``||W X||_inf < gamma`` (seed 001 eq. 6-7, 14-15).

``X`` is one closed-loop channel of the loop the controller sits in.  The
named ones are the four sensitivities seed 001 lists, each a channel of the
posicast :class:`~posicast.loops.Loop` so that it means the same thing in
every architecture:

==============  ============  =============================================================
kind            channel       transfer function
==============  ============  =============================================================
``"S"``         ``d -> z``    sensitivity ``1 / (1 + L)`` (seed 001 eq. 15, ``S_fk``)
``"T"``         ``n -> z``    complementary sensitivity ``L / (1 + L)`` (up to sign)
``"input"``     ``di -> z``   input (load-disturbance) sensitivity ``G / (1 + L)``
``"controller"````n -> u``    controller (noise) sensitivity: noise to actuator command,
                              ``C / (1 + L)`` times ``S`` (control action) or ``1 / S`` (inverse)
==============  ============  =============================================================

Any other channel can be given as a ``(src, dst)`` pair.  ``L = C P`` with
``P = G``, ``S G`` or ``G / S`` (seed 001 eq. 5).

Seed 001 states "input" and "controller" sensitivity on the modified plant
``P_i`` (``P / (1 + L)`` and ``C / (1 + L)``); posicast takes the physical
channels instead, which differ from those by the shaper factor.  Use the
``(src, dst)`` form, or a weight, for other conventions.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .. import _validate as v
from ..core.transfer import TransferFunction, as_transfer

__all__ = ["Constraint", "NAMED_CHANNELS", "sensitivity_constraint"]

NAMED_CHANNELS = {"S": ("d", "z"), "T": ("n", "z"), "input": ("di", "z"), "controller": ("n", "u")}

# gamma is squared against |W X|^2 on the frequency grid: beyond these bounds the squares leave the
# float range (1e+-300) for any weight a physical model produces.
GAMMA_RANGE = (1e-12, 1e12)
# Peak sensitivity bounds accepted by ms=: Ms = 100 is a stability margin of 0.01; beyond it the bound
# hardly constrains the design while the region's boundary approaches the stability boundary, where each
# design takes ten times longer (gantry crane PD: 0.5 s at Ms = 100, 6 s at Ms = 1000).
MS_RANGE = (1e-3, 100.0)


@dataclass(frozen=True)
class Constraint:
    """One loop-shaping inequality ``||W X||_inf < gamma``.

    Parameters
    ----------
    kind : {'S', 'T', 'input', 'controller'} or (src, dst)
        The closed-loop channel ``X`` (see the module table).
    gamma : float
        Bound, > 0.  For ``kind='S'`` with no weight this is ``Ms``.
    weight : plant-like, optional
        Frequency weight ``W(s)`` (anything :func:`posicast.as_transfer` accepts),
        default 1.

    Examples
    --------
    >>> c = Constraint("S", 2.0)
    >>> c.channel, c.label
    (('d', 'z'), '||S||inf < 2')
    >>> Constraint("S", 0.0)
    Traceback (most recent call last):
    ...
    ValueError: gamma must be > 0, got 0
    """

    kind: Any
    gamma: float
    weight: Any = None

    def __post_init__(self) -> None:
        kind = self.kind
        if isinstance(kind, str):
            if kind not in NAMED_CHANNELS:
                raise ValueError(f"kind must be one of {tuple(NAMED_CHANNELS)} or a (src, dst) pair, got {kind!r}")
        elif not (isinstance(kind, tuple) and len(kind) == 2 and all(isinstance(k, str) for k in kind)):
            raise TypeError(f"kind must be a name {tuple(NAMED_CHANNELS)} or a (src, dst) pair of strings, got {kind!r}")
        gamma = _bound(self.gamma, "gamma")
        object.__setattr__(self, "gamma", gamma)
        if self.weight is not None:
            W = as_transfer(self.weight, "weight")
            if W.num.is_zero:
                raise ValueError("weight is identically zero: the constraint would be empty")
            if W.num.degree > W.den.degree:
                raise ValueError("weight must be proper (an improper weight makes ||W X||inf infinite)")
            object.__setattr__(self, "weight", W)

    @property
    def channel(self) -> tuple[str, str]:
        """``(src, dst)`` of the loop channel ``X``."""
        return NAMED_CHANNELS[self.kind] if isinstance(self.kind, str) else self.kind

    @property
    def weight_tf(self) -> TransferFunction:
        return TransferFunction.constant(1.0) if self.weight is None else self.weight

    @property
    def label(self) -> str:
        name = self.kind if isinstance(self.kind, str) else f"{self.kind[0]}->{self.kind[1]}"
        w = "" if self.weight is None else "W "
        return f"||{w}{name}||inf < {self.gamma:g}"

    def __repr__(self) -> str:
        return f"Constraint({self.label})"


def sensitivity_constraint(ms: Any) -> Constraint:
    """``||S||_inf < Ms`` (seed 001 eq. 14), checking ``Ms`` is in :data:`MS_RANGE`.

    >>> sensitivity_constraint(1.6).label
    '||S||inf < 1.6'
    """
    return Constraint("S", _bound(ms, "ms", MS_RANGE, " (a peak sensitivity; 1.2 to 2 is usual)"))


def _bound(value: Any, name: str, bounds: tuple[float, float] = GAMMA_RANGE, hint: str = "") -> float:
    """``value > 0`` within ``bounds`` (a ValueError naming ``name`` otherwise)."""
    val = v.positive(value, name)
    lo, hi = bounds
    if not lo <= val <= hi:
        raise ValueError(f"{name} must be in [{lo:g}, {hi:g}]{hint}, got {val:g}")
    return val
