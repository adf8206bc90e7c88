"""What the root finder and the stability tools accept, and the errors they raise.

Argument checks for :func:`posicast.roots` and :mod:`posicast.spectra.verdict`: the
quasi-polynomial (:func:`as_quasipolynomial`, :func:`prepared`), the rectangle
(:func:`check_region`, and :func:`check_range` for one whose polynomial terms leave the
float range), the budget (:func:`check_budget`) and the known spurious roots
(:func:`check_ignore`).  Scalar and array checks go through :mod:`posicast._validate`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import _validate as v
from ..core.quasipoly import QuasiPolynomial
from ..core.transfer import TransferFunction

__all__ = [
    "RootFindingError",
    "BudgetExceeded",
    "as_quasipolynomial",
    "prepared",
    "check_region",
    "check_budget",
    "check_ignore",
    "check_range",
    "normalised",
    "usable_radius",
]


class RootFindingError(RuntimeError):
    """The roots could not be certified (count and roots found disagree, or no clean boundary)."""


class BudgetExceeded(RootFindingError):
    """The region needs more evaluations or time than the budget allows."""


def as_quasipolynomial(h: Any, name: str = "h") -> QuasiPolynomial:
    """Return ``h`` as a nonzero :class:`QuasiPolynomial` or raise a clear error."""
    if isinstance(h, QuasiPolynomial):
        q = h
    elif isinstance(h, TransferFunction) or hasattr(h, "transfer"):
        raise TypeError(
            f"{name} must be a QuasiPolynomial; for a transfer function pass its .num (zeros) "
            "or .den (poles), or use posicast.spectra.zeros / poles"
        )
    elif isinstance(h, tuple) and len(h) == 2:
        q = QuasiPolynomial(h[0], h[1])
    else:
        raise TypeError(f"{name} must be a QuasiPolynomial or a (coeffs, delays) pair, got {type(h).__name__}")
    if q.is_zero:
        raise ValueError(f"{name} is identically zero: every s is a root")
    return q


def prepared(h: Any) -> QuasiPolynomial:
    """``h`` as a quasi-polynomial with its smallest delay factored out; an advanced one is refused
    (it has roots of arbitrarily large real part: no stability analysis applies)."""
    q = normalised(as_quasipolynomial(h).factor_min_delay()[0])
    kind = q.kind
    if kind == "advanced":
        raise ValueError(
            "h is of advanced type (a delayed term has a higher power of s than the undelayed one): "
            "it has roots of arbitrarily large real part; no stability analysis applies"
        )
    return q


def normalised(q: QuasiPolynomial) -> QuasiPolynomial:
    """``q`` times a power of two that brings its largest coefficient to ``[0.5, 1)``: the same roots.

    The power of two is exact, so no coefficient is rounded; gains of 1e-300 or 1e300 in a loop
    then cost nothing in range.  Coefficients spanning more than the float range (a nonzero one
    would come within a thousand of the smallest normal float, ~1e-308, relative to the largest) are refused.
    """
    nz = np.abs(q.coeffs[q.coeffs != 0])
    if nz.size == 0:
        return q
    e = math.frexp(float(nz.max()))[1]
    if math.ldexp(float(nz.min()), -e) < 1e-305:  # <= the largest, scaled below 1: no overflow
        raise ValueError(
            f"h's coefficients span {float(nz.max()):.3g} / {float(nz.min()):.3g} = more than 1e305: "
            "they cannot be held in one float scale (rescale the gains or the time unit)"
        )
    if e == 0:
        return q
    return QuasiPolynomial(np.ldexp(q.coeffs, -e), q.delays)


def usable_radius(q: QuasiPolynomial) -> float:
    """The largest ``|s|`` where every ``|c_j| |s|^(j+1)`` stays below 1e250 (see :func:`check_range`)."""
    nz = np.abs(q.coeffs) > 0
    j = np.nonzero(nz)[1]
    logc = np.log10(np.abs(q.coeffs[nz]))
    return float(np.min(10.0 ** np.minimum((250.0 - logc) / (j + 1), 300.0)))


def check_region(region: Any) -> tuple[float, float, float, float]:
    """Validate ``(re_min, re_max, im_min, im_max)``: four finite reals, nonempty."""
    if isinstance(region, (str, bytes)) or not hasattr(region, "__len__"):
        raise TypeError("region must be four real numbers (re_min, re_max, im_min, im_max), "
                        f"got {type(region).__name__}")
    items = list(region)
    if len(items) != 4:
        raise ValueError(f"region must have 4 entries (re_min, re_max, im_min, im_max), got {len(items)}")
    names = ("re_min", "re_max", "im_min", "im_max")
    vals = [v.finite_real(x, f"region {n}") for x, n in zip(items, names)]
    a, b, c, d = vals
    if not a < b:
        raise ValueError(f"region: re_min must be < re_max, got re_min={a:g}, re_max={b:g}")
    if not c < d:
        raise ValueError(f"region: im_min must be < im_max, got im_min={c:g}, im_max={d:g}")
    return a, b, c, d


def check_budget(max_evaluations: Any, timeout: Any = 1.0) -> tuple[float, float]:
    """``max_evaluations`` and ``timeout`` as finite positive floats (TypeError/ValueError otherwise)."""
    m = v.positive(max_evaluations, "max_evaluations")
    if m < 1:
        raise ValueError(f"max_evaluations must be >= 1, got {m:g}")
    return m, v.positive(timeout, "timeout")


def check_ignore(ignore: Any) -> np.ndarray:
    """``ignore`` as a flat array of finite complex points (TypeError/ValueError naming ``ignore``)."""
    try:
        arr = v.complex_array(ignore, "ignore")
    except ValueError:
        raise ValueError("ignore must contain finite points (no NaN or inf)") from None
    return np.atleast_1d(arr).ravel()


def check_range(q: QuasiPolynomial, rect: tuple[float, float, float, float]) -> None:
    """Refuse a region where the polynomial terms leave the float range (with the size they reach).

    The exponentials are scaled to modulus <= 1 everywhere, but ``|c_j| |s|^j`` (and the
    derivative bounds, one power more) must stay far below 1e308.
    """
    a, b, c, d = rect
    R = max(abs(complex(x, y)) for x in (a, b) for y in (c, d))
    if R <= 1.0:
        return
    nz = np.abs(q.coeffs) > 0
    j = np.nonzero(nz)[1]
    logmag = float(np.max(np.log10(np.abs(q.coeffs[nz])) + (j + 1) * math.log10(R)))
    if logmag > 250.0:
        deg = int(j.max())
        lim = usable_radius(q)
        raise ValueError(
            f"region {rect} reaches |s| = {R:.3g}, where the degree-{deg} terms of h grow to about 1e{logmag:.0f} "
            f"and leave the float range; keep the region within |s| < {lim:.3g}"
        )
