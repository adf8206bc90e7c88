"""Quasi-polynomials ``h(s) = sum_i p_i(s) exp(-s tau_i)`` with real coefficients.

A quasi-polynomial is stored as a coefficient matrix and a delay vector:
``coeffs[i, k]`` multiplies ``s**k * exp(-s * delays[i])`` (ascending powers, one
row per distinct delay, delays sorted increasingly).  This is the form the
spectral tools (root finding, stability) consume, and every operation here is
exact: products add delays and multiply polynomials, nothing is approximated.
"""

from __future__ import annotations

from math import factorial
from typing import Iterable, NamedTuple, Sequence

import numpy as np
from numpy.polynomial import polynomial as P

from .. import _validate as v
from .verbs import QuasiPolynomialVerbs

__all__ = ["QuasiPolynomial", "horner", "horner_rows", "times_exps"]


def horner(x: object, c: object) -> np.ndarray:
    """``numpy.polynomial.polynomial.polyval(x, c)`` (ascending coefficients; a 2-D ``c`` gives one
    polynomial per column), by Horner's rule in place.

    The same operations in the same order as numpy's, so the same numbers bit for bit, without
    its two temporaries per coefficient: 1.1-7x faster on the arrays the root finder and the
    tuner evaluate (issue #15).

    >>> horner(np.array([1.0, 2.0]), [1.0, 0.0, 3.0])      # 1 + 3 x^2
    array([ 4., 13.])
    """
    x = np.asarray(x)
    c = np.asarray(c)
    if c.dtype.kind in "biu":
        c = c + 0.0
    c = c.reshape(c.shape + (1,) * x.ndim)
    out = c[-1] + x * 0
    for i in range(2, c.shape[0] + 1):
        out *= x
        out += c[-i]
    return out

def horner_rows(z: np.ndarray, cols: Sequence[np.ndarray]) -> np.ndarray:
    """``horner(z, c.T)`` for a 1-D ``z``, with the columns of ``c`` given as ``(m, 1)`` arrays
    (ascending powers): the ``m`` polynomials at ``z``, shape ``(m, z.size)``.

    The same operations in the same order as :func:`horner` (equal to rounding: numpy's complex
    product may round differently by memory layout, as between one point and many), with fewer
    numpy calls: the evaluators that call it many times on small arrays keep the columns.

    >>> horner_rows(np.array([1.0, 2.0]), [np.array([[1.0]]), np.array([[0.0]]), np.array([[3.0]])])
    array([[ 4., 13.]])
    """
    if len(cols) == 1:
        return cols[0] + z * 0
    out = cols[-1] * z
    out += cols[-2]
    for col in cols[-3::-1]:
        out *= z
        out += col
    return out


def times_exps(polys: np.ndarray, neg_tau: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``polys * exp(neg_tau * z)`` (rows of ``polys`` times ``exp(-tau_k z)``, ``neg_tau`` a column),
    in place; an undelayed first row is left as it is (``exp(-0 z)`` is exactly 1: the exponentials
    of one row saved).

    >>> times_exps(np.ones((2, 1), dtype=complex), np.array([[0.0], [-np.pi]]), np.array([1j]))
    array([[ 1.+0.0000000e+00j],
           [-1.-1.2246468e-16j]])
    """
    if neg_tau[0, 0] == 0.0:
        if neg_tau.shape[0] > 1:
            polys[1:] *= np.exp(neg_tau[1:] * z)
        return polys
    polys *= np.exp(neg_tau * z)
    return polys


class _Plan(NamedTuple):
    """Per-quasi-polynomial constants of evaluation: coefficient columns ``(m, 1)`` and ``-delays``."""

    cols: tuple
    neg_tau: np.ndarray


# Two delays closer than this (relative to the largest) are the same delay.
_DELAY_RTOL = 1e-12
# Largest derivative / Taylor order accepted (1/k! underflows the float range past 170).
_MAX_DERIVATIVE = 1000
_MAX_TAYLOR = 170


def _as_real_matrix(coeffs: object, name: str) -> np.ndarray:
    arr = v.strict_real_array(coeffs, name)  # TypeError: strings, complex, ragged; ValueError: NaN, inf, empty
    if arr.ndim == 0:
        arr = arr.reshape(1, 1)
    elif arr.ndim == 1:
        arr = arr[np.newaxis, :]
    if arr.ndim != 2:
        raise ValueError(f"{name} must be a 2-D array (one row per delay), got {arr.ndim}-D")
    if arr.shape[1] == 0:
        raise ValueError(f"{name} must have at least one column (the s**0 coefficients)")
    return np.array(arr, dtype=float)


def _finite_result(arr: np.ndarray, what: str) -> np.ndarray:
    """``arr`` if finite, else a ValueError: an operation's result left the float range."""
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} overflows the float range (coefficients or delays too large)")
    return arr


def _nonnegative_delay(delay: object, name: str) -> float:
    d = v.finite_real(delay, name)
    if d < 0:
        raise ValueError(f"{name} must be >= 0 [s], got {d:g}")
    return d


class QuasiPolynomial(QuasiPolynomialVerbs):
    """An exact quasi-polynomial ``h(s) = sum_i p_i(s) exp(-s tau_i)``.

    Parameters
    ----------
    coeffs : array_like, shape (m, d + 1)
        ``coeffs[i, k]`` is the coefficient of ``s**k exp(-s delays[i])``
        (ascending powers).  A 1-D array is one row.  posicast's one rule: a
        coefficient matrix given with its delays is ascending; a polynomial given
        alone (:meth:`from_poly`, ``(num, den)`` tuples) is numpy's descending.
    delays : array_like, shape (m,), optional
        Nonnegative finite delays, default ``[0]``.  Equal delays are merged.

    Examples
    --------
    The ZV shaper numerator ``0.5 + 0.5 exp(-s pi)`` is neutral:

    >>> h = QuasiPolynomial([[0.5], [0.5]], [0.0, np.pi])
    >>> h.kind
    'neutral'
    >>> abs(h(1j)) < 1e-15
    True
    """

    __slots__ = ("coeffs", "delays", "_plan")

    coeffs: np.ndarray
    delays: np.ndarray

    def __init__(self, coeffs: object, delays: object | None = None) -> None:
        c = _as_real_matrix(coeffs, "coeffs")
        if delays is None:
            d = np.zeros(c.shape[0])
        else:
            d = np.array(v.strict_real_array(delays, "delays", allow_empty=True), dtype=float).reshape(-1)
        if d.shape[0] != c.shape[0]:
            raise ValueError(
                f"delays has {d.shape[0]} entries but coeffs has {c.shape[0]} rows"
            )
        if not np.all(np.isfinite(d)):
            raise ValueError("delays must be finite")
        if np.any(d < 0):
            raise ValueError(f"delays must be >= 0, got min {d.min():g}")
        c, d = _canonical(c, d)
        self.coeffs = c
        self.delays = d
        self._plan: _Plan | None = None
        self.coeffs.flags.writeable = False
        self.delays.flags.writeable = False

    def __getstate__(self) -> tuple[None, dict]:
        # pickled without the evaluation constants (rebuilt on first use; readable by older posicast)
        return None, {"coeffs": self.coeffs, "delays": self.delays}

    def __setstate__(self, state: tuple[None, dict]) -> None:
        for name, value in state[1].items():
            setattr(self, name, value)
        self._plan = None

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_poly(cls, poly_desc: Sequence[float] | np.ndarray, delay: float = 0.0) -> QuasiPolynomial:
        """One polynomial (numpy's descending-power convention) times ``exp(-s delay)``.

        >>> QuasiPolynomial.from_poly([1.0, 2.0], 0.5)      # (s + 2) exp(-0.5 s)
        QuasiPolynomial((1*s + 2)*exp(-0.5*s))
        """
        arr = np.atleast_1d(v.strict_real_array(poly_desc, "poly_desc"))
        if arr.ndim != 1:
            raise ValueError(f"poly_desc must be a 1-D coefficient array, got shape {arr.shape}")
        return cls(arr[::-1][np.newaxis, :], [_nonnegative_delay(delay, "delay")])

    @classmethod
    def from_terms(cls, terms: Iterable[tuple[Sequence[float] | float, float]]) -> QuasiPolynomial:
        """Build from ``[(poly_desc, delay), ...]`` pairs (descending powers)."""
        rows, delays = [], []
        for i, term in enumerate(v.sequence(terms, "terms")):
            if isinstance(term, (str, bytes)) or not hasattr(term, "__len__") or len(term) != 2:
                raise TypeError(f"terms[{i}] must be a (poly_desc, delay) pair, got {type(term).__name__}")
            poly, delay = term
            arr = np.atleast_1d(v.strict_real_array(poly, f"terms[{i}] polynomial"))
            if arr.ndim != 1:
                raise ValueError(f"terms[{i}] polynomial must be 1-D, got shape {arr.shape}")
            rows.append(arr[::-1])
            delays.append(_nonnegative_delay(delay, f"terms[{i}] delay"))
        if not rows:
            return cls.zero()
        width = max(len(r) for r in rows)
        mat = np.zeros((len(rows), width))
        for i, r in enumerate(rows):
            mat[i, : len(r)] = r
        return cls(mat, delays)

    @classmethod
    def zero(cls) -> QuasiPolynomial:
        """The identically zero quasi-polynomial."""
        return cls(np.zeros((1, 1)), [0.0])

    @classmethod
    def constant(cls, value: float) -> QuasiPolynomial:
        """The constant ``value`` (finite).

        >>> QuasiPolynomial.constant(2.0)(1j)
        (2+0j)
        """
        return cls([[v.finite_real(value, "value")]], [0.0])

    # ------------------------------------------------------------------ properties
    @property
    def is_zero(self) -> bool:
        """True if the quasi-polynomial is identically zero."""
        return self.coeffs.shape[0] == 0

    @property
    def degree(self) -> int:
        """Highest power of ``s`` (``-1`` for the zero quasi-polynomial)."""
        return self.coeffs.shape[1] - 1 if not self.is_zero else -1

    @property
    def has_delays(self) -> bool:
        """True if some term carries a nonzero delay (after factoring nothing out)."""
        return bool(np.any(self.delays > 0))

    @property
    def is_polynomial(self) -> bool:
        """True if there is a single term: a polynomial times at most one delay."""
        return self.coeffs.shape[0] <= 1

    def row_degrees(self) -> np.ndarray:
        """Degree of each row's polynomial."""
        out = np.empty(self.coeffs.shape[0], dtype=int)
        for i, row in enumerate(self.coeffs):
            nz = np.flatnonzero(row)
            out[i] = nz[-1] if nz.size else -1
        return out

    @property
    def kind(self) -> str:
        """``'polynomial'``, ``'retarded'``, ``'neutral'`` or ``'advanced'``.

        After factoring out the smallest delay, the quasi-polynomial is retarded
        when only the undelayed term reaches the highest power of ``s``, neutral
        when a delayed term reaches the same power, advanced when a delayed term
        has a higher power than the undelayed one.
        """
        if self.is_zero:
            raise ValueError("the zero quasi-polynomial has no kind")
        if self.coeffs.shape[0] == 1:
            return "polynomial"
        deg = self.row_degrees()
        d0 = deg[0]
        rest = deg[1:].max()
        if d0 > rest:
            return "retarded"
        if d0 == rest:
            return "neutral"
        return "advanced"

    def difference_operator(self) -> QuasiPolynomial:
        """The associated difference operator of a neutral quasi-polynomial.

        The coefficients of the highest power of ``s`` in each row, normalised by
        the undelayed one: ``D(s) = 1 + sum_i (c_i / c_0) exp(-s (tau_i - tau_0))``.
        Its spectrum bounds the high-frequency roots (strong stability).
        """
        if self.kind != "neutral":
            raise ValueError(f"only a neutral quasi-polynomial has a difference operator, this one is {self.kind}")
        n = self.degree
        lead = self.coeffs[:, n]
        keep = lead != 0
        return QuasiPolynomial((lead[keep] / lead[0])[:, np.newaxis], self.delays[keep] - self.delays[0])

    # ------------------------------------------------------------------ evaluation
    def __call__(self, s: object) -> np.ndarray | complex:
        """Evaluate at complex ``s`` (scalar or array, vectorised).

        ``s`` must be finite; a value outside the float range (``|s|`` or ``-Re s``
        too large for the powers and delays) is a ValueError naming ``s``.
        """
        s_arr = v.complex_array(s, "s")
        out = self._eval(s_arr)
        if not np.isfinite(out).all():
            bad = complex(s_arr.reshape(-1)[int(np.flatnonzero(~np.isfinite(np.reshape(out, -1)))[0])])
            raise ValueError(f"s = {bad:.6g}: the value overflows the float range (|s| or -Re s too large "
                             f"for the powers and delays of {self})")
        return out if s_arr.ndim else complex(out)

    def _eval(self, s_arr: np.ndarray) -> np.ndarray:
        """Raw evaluation at a complex array (no checks; overflow gives inf/NaN, without warnings)."""
        if self.is_zero:
            return np.zeros_like(s_arr)
        z = s_arr.reshape(-1)
        plan = self.plan()
        with np.errstate(all="ignore"):
            polys = horner_rows(z, plan.cols)  # (m, z.size)
            return np.add.reduce(times_exps(polys, plan.neg_tau, z), axis=0).reshape(s_arr.shape)

    def plan(self) -> _Plan:
        """The constant arrays of :meth:`_eval` (built once: a quasi-polynomial is immutable)."""
        if getattr(self, "_plan", None) is None:  # (None also for an instance unpickled from an older posicast)
            self._plan = _Plan(tuple(np.ascontiguousarray(col[:, None]) for col in self.coeffs.T),
                               np.ascontiguousarray(-self.delays[:, None]))
        return self._plan

    def magnitude_scale(self, s: object) -> np.ndarray:
        """``sum_i |p_i(s)| |exp(-s tau_i)|`` summed term by term (absolute values).

        Used as the scale against which a computed value is judged to be zero.
        """
        s_arr = np.asarray(s, dtype=complex)
        if self.is_zero:
            return np.zeros(s_arr.shape)
        absc = np.abs(self.coeffs)
        with np.errstate(all="ignore"):  # a scale beyond the float range is inf
            polys = horner(np.abs(s_arr), absc.T)
            exps = np.abs(np.exp(-np.multiply.outer(self.delays, s_arr)))
            return np.sum(polys * exps, axis=0)

    def derivative(self, order: int = 1) -> QuasiPolynomial:
        """Exact derivative: ``d/ds [p(s) e^{-s tau}] = (p'(s) - tau p(s)) e^{-s tau}``.

        ``order`` is an integer in ``[0, 1000]``.

        >>> QuasiPolynomial.from_poly([1.0, 0.0, 0.0]).derivative()     # d/ds s^2
        QuasiPolynomial(2*s)
        """
        order = v.integer_in_range(order, "order", 0, _MAX_DERIVATIVE)
        q = self
        for _ in range(order):
            if q.is_zero:
                return q
            c = q.coeffs
            deriv = np.zeros_like(c)
            if c.shape[1] > 1:
                deriv[:, :-1] = c[:, 1:] * np.arange(1, c.shape[1])
            deriv -= q.delays[:, np.newaxis] * c
            q = QuasiPolynomial(_finite_result(deriv, f"the derivative of order {order}"), q.delays)
        return q

    def taylor(self, s0: complex, order: int) -> tuple[np.ndarray, np.ndarray]:
        """Taylor coefficients about ``s0`` up to ``order`` and their magnitude scales.

        Returns ``(c, scale)`` with ``h(s0 + h) = sum_k c[k] h**k`` and ``scale[k]``
        the sum of the absolute values of the contributions to ``c[k]`` (a
        coefficient far below its scale is a cancellation to zero).
        """
        order = v.integer_in_range(order, "order", 0, _MAX_TAYLOR)
        arr = v.complex_array(s0, "s0")
        if arr.ndim:
            raise TypeError(f"s0 must be a complex number, got an array of shape {arr.shape}")
        s0 = complex(arr)
        K = order + 1
        c = np.zeros(K, dtype=complex)
        scale = np.zeros(K)
        if self.is_zero:
            return c, scale
        inv_fact = np.array([1.0 / factorial(k) for k in range(K)])
        for row, tau in zip(self.coeffs, self.delays):
            # Taylor coefficients of the polynomial about s0: p^{(l)}(s0) / l!
            pt = np.zeros(K, dtype=complex)
            pabs = np.zeros(K)  # the same with absolute values: the rounding scale
            prow = row.astype(float)
            for l in range(min(K, len(row))):
                pt[l] = horner(s0, prow) * inv_fact[l]
                pabs[l] = horner(abs(s0), np.abs(prow)) * inv_fact[l]
                prow = P.polyder(prow) if len(prow) > 1 else np.zeros(1)
            with np.errstate(all="ignore"):
                et = ((-tau) ** np.arange(K)) * inv_fact  # Taylor of exp(-tau h)
                e0 = np.exp(-s0 * tau)
                c += e0 * np.convolve(pt, et)[:K]
                scale += abs(e0) * np.convolve(pabs, np.abs(et))[:K]
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(scale))):
            raise ValueError(f"s0 = {s0:.6g}: the Taylor coefficients overflow the float range (|s0| or -Re s0 "
                             f"too large for the powers and delays)")
        return c, scale

    # ------------------------------------------------------------------ algebra
    def _coerce(self, other: object) -> QuasiPolynomial | None:
        if isinstance(other, QuasiPolynomial):
            return other
        if isinstance(other, (int, float, np.integer, np.floating)) and not isinstance(other, (bool, np.bool_)):
            return QuasiPolynomial.constant(v.finite_real(other, "operand"))
        return None

    def __add__(self, other: object) -> QuasiPolynomial:
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        if self.is_zero:
            return o
        if o.is_zero:
            return self
        width = max(self.coeffs.shape[1], o.coeffs.shape[1])
        a = np.zeros((self.coeffs.shape[0], width))
        a[:, : self.coeffs.shape[1]] = self.coeffs
        b = np.zeros((o.coeffs.shape[0], width))
        b[:, : o.coeffs.shape[1]] = o.coeffs
        with np.errstate(all="ignore"):
            return _merge(np.vstack([a, b]), np.concatenate([self.delays, o.delays]), "the sum")

    __radd__ = __add__

    def __neg__(self) -> QuasiPolynomial:
        return QuasiPolynomial(-self.coeffs, self.delays) if not self.is_zero else self

    def __sub__(self, other: object) -> QuasiPolynomial:
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        return self + (-o)

    def __rsub__(self, other: object) -> QuasiPolynomial:
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        return o + (-self)

    def __mul__(self, other: object) -> QuasiPolynomial:
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        if self.is_zero or o.is_zero:
            return QuasiPolynomial.zero()
        rows, delays = [], []
        with np.errstate(all="ignore"):
            for ra, ta in zip(self.coeffs, self.delays):
                for rb, tb in zip(o.coeffs, o.delays):
                    rows.append(P.polymul(ra, rb))
                    delays.append(ta + tb)
            width = max(len(r) for r in rows)
            mat = np.zeros((len(rows), width))
            for i, r in enumerate(rows):
                mat[i, : len(r)] = r
            return _merge(mat, np.array(delays), "the product")

    __rmul__ = __mul__

    def shift(self, delay: float) -> QuasiPolynomial:
        """Multiply by ``exp(-s delay)`` (``delay >= 0``, finite).

        >>> QuasiPolynomial.constant(1.0).shift(0.5).delays
        array([0.5])
        """
        delay = _nonnegative_delay(delay, "delay")
        if self.is_zero:
            return self
        return QuasiPolynomial(self.coeffs, _finite_result(self.delays + delay, f"shifting by delay = {delay:g}"))

    def factor_min_delay(self) -> tuple[QuasiPolynomial, float]:
        """Return ``(q, tau_min)`` with ``self = q * exp(-s tau_min)`` and ``q`` undelayed in its first row."""
        if self.is_zero or self.delays[0] == 0:
            return self, 0.0
        tau0 = float(self.delays[0])
        return QuasiPolynomial(self.coeffs, self.delays - tau0), tau0

    def scaled(self, factor: float) -> QuasiPolynomial:
        """``factor * h`` (``factor`` a finite real).

        >>> QuasiPolynomial.constant(2.0).scaled(-1.5)(0.0)
        (-3+0j)
        """
        factor = v.finite_real(factor, "factor")
        if self.is_zero:
            return self
        with np.errstate(all="ignore"):
            c = self.coeffs * factor
        return QuasiPolynomial(_finite_result(c, f"scaling by factor = {factor:g}"), self.delays)

    def equals(self, other: QuasiPolynomial, rtol: float = 1e-12) -> bool:
        """Structural equality up to a relative tolerance on coefficients and delays.

        >>> QuasiPolynomial.constant(1.0).equals(QuasiPolynomial([[1.0 + 1e-15]]))
        True
        """
        v.instance_of(other, QuasiPolynomial, "other", "a QuasiPolynomial")
        rtol = v.nonnegative(rtol, "rtol")
        if self.coeffs.shape != other.coeffs.shape:
            return False
        if self.is_zero:
            return True
        scale = max(np.abs(self.coeffs).max(), np.abs(other.coeffs).max())
        return bool(
            np.allclose(self.delays, other.delays, rtol=rtol, atol=rtol * max(1.0, self.delays.max()))
            and np.allclose(self.coeffs, other.coeffs, rtol=0, atol=rtol * scale)
        )

    # ------------------------------------------------------------------ display
    def __repr__(self) -> str:
        return f"QuasiPolynomial({self})"

    def __str__(self) -> str:
        if self.is_zero:
            return "0"
        parts = []
        for row, tau in zip(self.coeffs, self.delays):
            poly = _poly_str(row)
            if tau == 0:
                parts.append(poly)
            else:
                parts.append(f"({poly})*exp(-{tau:.6g}*s)")
        return " + ".join(parts)


def _merge(mat: np.ndarray, delays: np.ndarray, what: str) -> QuasiPolynomial:
    """A QuasiPolynomial from an algebra result, or a ValueError if it left the float range."""
    _finite_result(mat, what)
    _finite_result(delays, what)
    return QuasiPolynomial(mat, delays)


def _poly_str(row: np.ndarray) -> str:
    terms = []
    for k in range(len(row) - 1, -1, -1):
        c = row[k]
        if c == 0:
            continue
        if k == 0:
            terms.append(f"{c:.6g}")
        elif k == 1:
            terms.append(f"{c:.6g}*s")
        else:
            terms.append(f"{c:.6g}*s^{k}")
    return " + ".join(terms) if terms else "0"


def _canonical(c: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sort by delay, merge equal delays, drop zero rows, trim high zero powers."""
    if c.shape[0] == 0:
        return np.zeros((0, 1)), np.zeros(0)
    order = np.argsort(d, kind="stable")
    c = c[order]
    d = d[order]
    tol = _DELAY_RTOL * max(1.0, float(d[-1]))
    merged_c = [c[0].copy()]
    merged_d = [d[0]]
    for row, tau in zip(c[1:], d[1:]):
        if tau - merged_d[-1] <= tol:
            merged_c[-1] += row
        else:
            merged_c.append(row.copy())
            merged_d.append(tau)
    mc = np.array(merged_c)
    md = np.array(merged_d)
    keep = np.any(mc != 0, axis=1)
    mc = mc[keep]
    md = md[keep]
    if mc.shape[0] == 0:
        return np.zeros((0, 1)), np.zeros(0)
    nz_cols = np.flatnonzero(np.any(mc != 0, axis=0))
    mc = mc[:, : nz_cols[-1] + 1]
    return mc, md
