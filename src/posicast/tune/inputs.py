"""Argument checks of the tuners: blocks, ranges, constraints and the architecture keyword.

Each check raises with the message style of :mod:`posicast._validate`
("<name> must be ..., got <value>"); the domain refusals (an unstable block
outside the loop, coefficients or delays beyond what the frequency grid
resolves) say what to change.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from .. import _validate as v
from ..core.quasipoly import QuasiPolynomial
from ..core.transfer import TransferFunction, as_transfer
from ..loops import ARCHITECTURES, feature_frequencies, removable_points
from ..spectra import stability
from ..spectra.rootfinder import RootFindingError
from . import family as family_mod
from .constraints import Constraint, sensitivity_constraint

__all__ = ["MAX_DELAY_RATIO", "architecture_argument", "check_architecture", "check_range", "check_blocks",
           "constraint_tuple", "constraints_with_ms"]

#: the default of ``architecture`` (a ``structure=`` keyword is the old spelling only next to it)
DEFAULT_ARCHITECTURE = "control_action"


def architecture_argument(architecture: Any, structure: Any) -> tuple[Any, str]:
    """The architecture a caller asked for and the keyword it used (``structure`` is the old name).

    ``structure=`` keeps working with a FutureWarning: the loops and the
    simulation call the same three strings ``architecture``.
    """
    if structure is None:
        return architecture, "architecture"
    warnings.warn("structure= is now architecture= (the word posicast.Loop uses); structure= will be removed",
                  FutureWarning, stacklevel=4)
    if architecture != DEFAULT_ARCHITECTURE:
        raise TypeError(f"give architecture or structure (its old name), not both: got {architecture!r} "
                        f"and {structure!r}")
    return structure, "structure"


def check_architecture(architecture: Any, name: str = "architecture") -> str:
    return v.choice(architecture, name, ARCHITECTURES)


def check_range(r: Any, name: str) -> tuple[float, float] | None:
    """None, or a ``(low, high)`` pair of gains with ``low < high`` within ``+-MAX_GAIN``."""
    if r is None:
        return None
    lo, hi = v.pair(r, name)
    lo = v.real_in_range(lo, f"{name}[0]", -family_mod.MAX_GAIN, family_mod.MAX_GAIN)
    hi = v.real_in_range(hi, f"{name}[1]", -family_mod.MAX_GAIN, family_mod.MAX_GAIN)
    if not lo < hi:
        raise ValueError(f"{name} must have low < high, got ({lo:g}, {hi:g})")
    return lo, hi


# Coefficients of G, S and F, relative to the largest of their denominator, must lie within these
# magnitudes: the region computation squares and multiplies them over wide frequency grids.
_COEFF_RANGE = (1e-100, 1e100)


def _check_scale(tf: TransferFunction, name: str) -> None:
    """Refuse a block whose coefficients span beyond :data:`_COEFF_RANGE` (rescale time or gain units)."""
    scale = max(float(np.max(np.abs(tf.den.coeffs))), 1e-300)
    lo, hi = _COEFF_RANGE
    for q in (tf.num, tf.den):
        if q.is_zero:
            continue
        mags = np.abs(q.coeffs[q.coeffs != 0]) / scale
        if mags.size and (mags.min() < lo or mags.max() > hi):
            raise ValueError(
                f"{name}: its coefficients span {mags.min():.3g} to {mags.max():.3g} relative to the largest "
                f"denominator coefficient, beyond [{lo:g}, {hi:g}]; rescale the time or gain units"
            )


# Largest loop delay times the fastest pole/zero magnitude of the delay-free blocks: beyond this the
# frequency grid cannot resolve the delay's phase over the blocks' dynamics (measured for 1/(s(s+1))
# e^{-s tau}: tau = 1e3 designs in ~35 s, 1e4 ends in ~35 s with a failed independent verification,
# 1e5 runs for minutes, 1e6 and beyond return nonsense).
MAX_DELAY_RATIO = 1e4


def _check_delays(blocks: list[tuple[str, TransferFunction]]) -> None:
    tau = max(tf.max_delay for _, tf in blocks)
    if tau <= 0:
        return
    rates = []
    for _, tf in blocks:
        no_delay = TransferFunction(QuasiPolynomial(tf.num.coeffs), QuasiPolynomial(tf.den.coeffs)) \
            if tf.num.coeffs.shape[0] == 1 and tf.den.coeffs.shape[0] == 1 else None
        if no_delay is not None:
            rates += feature_frequencies([no_delay])
    if not rates:
        return
    ratio = tau * max(rates)
    if ratio > MAX_DELAY_RATIO:
        name = next(n for n, tf in blocks if tf.max_delay == tau)
        raise ValueError(
            f"{name}: its delay {tau:.4g} s is {ratio:.3g} times the fastest time constant of the loop's blocks "
            f"(1 / {max(rates):.4g} rad/s); the frequency grid cannot resolve more than {MAX_DELAY_RATIO:g}: "
            f"use a smaller delay or rescale time"
        )


def _check_shaper(S: Any, architecture: str) -> None:
    St = as_transfer(S, "S")
    _check_scale(St, "S")
    if St.num.is_zero:
        raise ValueError("S is identically zero: no signal passes the shaper")
    if St.num.degree > St.den.degree:
        raise ValueError("S must be proper (a shaper is a realisable filter)")
    if architecture == "inverse_shaper" and St.num.degree < St.den.degree:
        raise ValueError(
            "the inverse_shaper architecture needs 1/S proper: S must be biproper "
            "(every delay shaper and the notch are); this S is strictly proper"
        )
    if architecture == "feedforward":
        _check_open_loop_stable(St, "S", "in the feedforward architecture it filters w outside the loop")


def check_blocks(G: Any, S: Any, architecture: str, F: Any = None) -> tuple[TransferFunction, Any]:
    """``G`` as a proper transfer function; ``S`` and ``F`` checked (returned as given)."""
    Gt = as_transfer(G, "G")
    _check_scale(Gt, "G")
    if Gt.num.is_zero:
        raise ValueError("G is identically zero: nothing to control")
    if Gt.num.degree > Gt.den.degree:
        raise ValueError(
            f"G must be proper (a physical plant): its numerator has degree {Gt.num.degree} > "
            f"denominator degree {Gt.den.degree}"
        )
    if S is not None:
        _check_shaper(S, architecture)
    if F is not None:
        Ft = as_transfer(F, "F")
        _check_scale(Ft, "F")
        if Ft.num.degree > Ft.den.degree:
            raise ValueError("F must be proper (the flexible load is a physical system)")
        _check_open_loop_stable(Ft, "F", "it acts on the plant output outside the loop")
    _check_delays([("G", Gt)] + ([("S", as_transfer(S, "S"))] if S is not None else []))
    return Gt, S


def _check_open_loop_stable(tf: TransferFunction, name: str, why: str) -> None:
    """Raise if ``tf`` has a pole with ``Re s >= 0`` (removable singularities excepted): a block
    outside the loop that no controller can stabilise."""
    if tf.den.degree < 1 and tf.den.is_polynomial:  # a constant (times a delay): no pole
        return
    try:
        st = stability(tf.den, ignore=removable_points(tf.num, tf.den))
    except (RootFindingError, ValueError) as exc:
        raise ValueError(f"{name}: its poles could not be certified ({exc})") from None
    if not st.stable:
        raise ValueError(f"{name} is unstable ({st.reason}); {why}, so no controller can make it stable")


def constraint_tuple(constraints: Any) -> tuple[Constraint, ...]:
    """None, one Constraint or a sequence of them, as a tuple (TypeError naming ``constraints``)."""
    if constraints is None:
        return ()
    if isinstance(constraints, Constraint):
        return (constraints,)
    out = tuple(v.sequence(constraints, "constraints"))
    for c in out:
        if not isinstance(c, Constraint):
            raise TypeError(f"constraints must be posicast.tune.Constraint objects, got {type(c).__name__}")
    return out


def constraints_with_ms(ms: Any, constraints: Any) -> tuple[Constraint, ...]:
    """``||S||_inf < ms`` (unless ``ms`` is None) followed by ``constraints``."""
    extra = constraint_tuple(constraints)
    base = () if ms is None else (sensitivity_constraint(ms),)
    return base + extra
