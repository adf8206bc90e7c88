"""Exact quasi-rational transfer functions ``H(s) = N(s) / D(s)``.

``N`` and ``D`` are :class:`~posicast.core.quasipoly.QuasiPolynomial` objects, so
``H`` may contain any number of lumped delays in numerator and denominator.
Series, parallel, feedback and inverse are carried out on ``N`` and ``D``
directly: there is no Padé or other approximation anywhere.

Evaluation handles removable singularities such as ``(1 - exp(-sT)) / (sT)`` at
``s = 0``: near ``s = 0`` and near the roots of a delay-free denominator, ``N``
and ``D`` are expanded in exact Taylor series, coefficients that cancel to zero
are removed, and the ratio of the remaining series is taken.  At a common root
elsewhere the ratio of the first nonvanishing derivatives is used (l'Hôpital).
"""

from __future__ import annotations

import warnings
from typing import Any, NamedTuple

import numpy as np

from .. import _validate as v
from .quasipoly import QuasiPolynomial, horner_rows, times_exps
from .removable import removable_points
from .verbs import SystemVerbs

__all__ = ["TransferFunction", "as_transfer", "delay", "finite_complex", "IllPosed"]


class _DcGain(float):
    """A DC gain that still answers the old call ``H.dc_gain()`` (with a FutureWarning)."""

    def __call__(self) -> float:
        warnings.warn("TransferFunction.dc_gain is a property (as on Shaper): write H.dc_gain, not H.dc_gain()",
                      FutureWarning, stacklevel=2)
        return float(self)


class IllPosed(ValueError, ZeroDivisionError):
    """An operation with no finite answer (inverting zero, an identically zero closed loop).

    A ValueError (bad input, one named message) and, for code written against earlier
    versions, a ZeroDivisionError.
    """


def finite_complex(s: Any, name: str = "s") -> np.ndarray:
    """``s`` as a complex array: TypeError for strings/objects, ValueError if any entry is NaN or infinite."""
    return v.complex_array(s, name)


def _coeff_vector(value: Any, name: str) -> np.ndarray:
    arr = np.atleast_1d(v.strict_real_array(value, name))
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D coefficient array, got shape {arr.shape}")
    return arr

_TAYLOR_ORDER = 24
_CANCEL_RTOL = 1e-11  # a Taylor coefficient below this fraction of its scale is zero
_ZERO_RTOL = 1e-13  # a value below this fraction of its term scale is zero


class TransferFunction(SystemVerbs):
    """An exact quasi-rational transfer function ``H(s) = N(s) / D(s)``.

    Parameters
    ----------
    num, den : QuasiPolynomial
        Numerator and denominator.  ``den`` must not be identically zero.

    Examples
    --------
    A PD controller in series with a pure delay, closed in unit feedback:

    >>> C = TransferFunction.from_poly([10.0, 10.0], [1.0])
    >>> G = TransferFunction.from_poly([1.0], [1.0, 1.0, 0.0]) * delay(0.1)
    >>> T = (C * G).feedback()
    >>> abs(T(0) - 1.0) < 1e-12            # integrator in the loop: unit DC gain
    True
    >>> T.den.kind
    'retarded'

    Removable singularities evaluate to their limit:

    >>> S = TransferFunction(QuasiPolynomial([[1.0], [-1.0]], [0.0, 2.0]),
    ...                      QuasiPolynomial([[0.0, 2.0]]))
    >>> S(0.0)
    (1+0j)
    """

    __slots__ = ("num", "den", "_expansion_points", "_taylor_cache", "_nd_plan")

    num: QuasiPolynomial
    den: QuasiPolynomial

    def __init__(self, num: QuasiPolynomial, den: QuasiPolynomial) -> None:
        v.instance_of(num, QuasiPolynomial, "num", "a QuasiPolynomial")
        v.instance_of(den, QuasiPolynomial, "den", "a QuasiPolynomial")
        if den.is_zero:
            raise ValueError("den must not be identically zero")
        self.num = num
        self.den = den
        self._expansion_points: np.ndarray | None = None
        self._taylor_cache: dict[complex, tuple] = {}
        self._nd_plan: _NDPlan | None = None

    def __getstate__(self) -> tuple[None, dict]:
        # pickled without the caches (rebuilt on first use; readable by older posicast)
        return None, {"num": self.num, "den": self.den}

    def __setstate__(self, state: tuple[None, dict]) -> None:
        for name, value in state[1].items():
            setattr(self, name, value)
        self._expansion_points = None
        self._taylor_cache = {}
        self._nd_plan = None

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_poly(cls, num_desc: Any, den_desc: Any, delay: float = 0.0) -> TransferFunction:
        """Rational ``num/den`` (numpy descending-power coefficients) times ``exp(-s delay)``.

        ``num`` and ``den`` are non-empty 1-D arrays of finite reals (``den`` not all
        zero), ``delay`` a finite number >= 0.

        >>> TransferFunction.from_poly([1.0], [1.0, 1.0])(0.0)
        (1+0j)
        """
        num = _coeff_vector(num_desc, "num")
        den = _coeff_vector(den_desc, "den")
        if not np.any(den != 0):
            raise ValueError("den must not be identically zero")
        d = v.finite_real(delay, "delay")
        if d < 0:
            raise ValueError(f"delay must be finite and >= 0, got {d:g}")
        return cls(QuasiPolynomial.from_poly(num, d), QuasiPolynomial.from_poly(den))

    @classmethod
    def constant(cls, value: float) -> TransferFunction:
        """The static gain ``value`` (finite).

        >>> TransferFunction.constant(2.0)(1j)
        (2+0j)
        """
        return cls(QuasiPolynomial.constant(value), QuasiPolynomial.constant(1.0))

    # ------------------------------------------------------------------ inspection
    @property
    def has_delays(self) -> bool:
        """True if numerator or denominator contains a delay."""
        return self.num.has_delays or self.den.has_delays

    @property
    def max_delay(self) -> float:
        d = [q.delays.max() for q in (self.num, self.den) if not q.is_zero]
        return float(max(d)) if d else 0.0

    def is_rational(self) -> bool:
        """True if ``H`` is a rational function (after cancelling a common delay, at most a pure delay on top)."""
        return self.num.is_polynomial and self.den.is_polynomial

    def __repr__(self) -> str:
        return f"TransferFunction(num={self.num}, den={self.den})"

    # ------------------------------------------------------------------ evaluation
    def _points(self) -> np.ndarray:
        """Points about which evaluation uses Taylor series: 0 and delay-free denominator roots."""
        if self._expansion_points is None:
            pts = [0.0 + 0.0j]
            den = self.den
            if den.is_polynomial and den.degree >= 1:
                poly = den.coeffs[0][::-1]
                roots = np.roots(poly)
                for r in roots:
                    if abs(r) == 0:
                        continue
                    # far left, the delays' exponentials overflow: such a root is no removable point
                    with np.errstate(over="ignore", invalid="ignore"):
                        nv = abs(complex(self.num._eval(np.asarray(r, dtype=complex))))
                        scale = float(self.num.magnitude_scale(r))
                    if np.isfinite(nv) and np.isfinite(scale) and nv <= 1e-8 * max(1.0, scale):
                        pts.append(complex(r))
            self._expansion_points = np.array(pts, dtype=complex)
        return self._expansion_points

    def _plan(self) -> _NDPlan:
        """Constants of :meth:`__call__`, built once (num and den are immutable)."""
        plan = getattr(self, "_nd_plan", None)  # (None also for an instance unpickled from an older posicast)
        if plan is None:
            n, d = self.num, self.den
            # one Horner pass over num's and den's rows stacked, and one exponential per delay, where
            # they share their delays and degree (a loop's sensitivities): the same operations on the
            # operations as evaluating each (equal to rounding), with half the numpy calls
            shared = (not n.is_zero and n.coeffs.shape == d.coeffs.shape and np.array_equal(n.delays, d.delays))
            cols = tuple(np.concatenate([a, b]) for a, b in zip(n.plan().cols, d.plan().cols)) if shared else ()
            tau = self.max_delay
            # the 24-term series is exact to rounding for |h| tau <= 0.5 (see __call__)
            near = tuple((complex(s0), 0.5 / max(tau, 1.0 / (1.0 + abs(s0)))) for s0 in self._points())
            plan = self._nd_plan = _NDPlan(shared, cols, d.plan().neg_tau, n.coeffs.shape[0], near)
        return plan

    def _num_den(self, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``N(s)`` and ``D(s)`` at a 1-D complex ``flat`` (ValueError naming ``s`` past the float range)."""
        plan = self._plan()
        if plan.shared:
            with np.errstate(all="ignore"):
                polys = horner_rows(flat, plan.cols)
                m = plan.m
                if plan.neg_tau.shape[0] > 1 or plan.neg_tau[0, 0] != 0.0:  # (else exp(-0 s) = 1)
                    polys = polys.reshape(2, m, flat.size)
                    times_exps(polys.transpose(1, 0, 2), plan.neg_tau[:, :, None], flat)
                    polys = polys.reshape(2 * m, flat.size)
                N = np.add.reduce(polys[:m], axis=0)
                D = np.add.reduce(polys[m:], axis=0)
            if np.isfinite(N).all() and np.isfinite(D).all():
                return N, D
        return np.atleast_1d(self.num(flat)), np.atleast_1d(self.den(flat))

    def __call__(self, s: Any) -> Any:
        """Evaluate ``H(s)`` at complex ``s`` (scalar or array).  Poles give ``inf``.

        ``s`` must be finite; where ``N(s)`` or ``D(s)`` leaves the float range the
        evaluation is a ValueError naming ``s``.
        """
        s_arr = finite_complex(s)
        flat = s_arr.reshape(-1)
        N, D = self._num_den(flat)
        with np.errstate(divide="ignore", invalid="ignore"):
            out = N / D
        # Taylor expansion near 0 and near removable roots of a polynomial denominator.
        # The 24-term series is exact to rounding for |h| tau <= 0.5; direct evaluation
        # of a cancelling N/D loses ~eps/|h tau|^k there, so the series is used.
        for s0, radius in self._plan().near:
            near = np.abs(flat - s0) <= radius
            if near.any():
                out[near] = self._taylor_ratio(s0, flat[near] - s0)
        # Remaining 0/0 points: l'Hopital with exact derivatives.
        bad = ~np.isfinite(out)
        if bad.any():
            for idx in np.flatnonzero(bad):
                out[idx] = self._limit_at(flat[idx])
        out = out.reshape(s_arr.shape)
        if np.isnan(out).any():  # no finite limit found where N and D both overflowed
            bad = complex(s_arr.reshape(-1)[int(np.flatnonzero(np.isnan(out.reshape(-1)))[0])])
            raise ValueError(f"s = {bad:.6g}: H(s) is outside the float range there")
        return out if s_arr.ndim else complex(out)

    def _taylor_ratio(self, s0: complex, h: np.ndarray) -> np.ndarray:
        key = complex(s0)
        if key not in self._taylor_cache:  # the coefficients depend on s0 only
            self._taylor_cache[key] = _ratio_series(self.num.taylor(s0, _TAYLOR_ORDER)
                                                    + self.den.taylor(s0, _TAYLOR_ORDER))
        cols = self._taylor_cache[key]
        if cols is None:  # denominator vanishes to high order: treat as a pole
            return np.full(h.shape, complex(np.inf))
        nd = horner_rows(h, cols)  # the two series, num's and den's, in one pass
        with np.errstate(divide="ignore", invalid="ignore"):
            out = nd[0] / nd[1]
        out[~np.isfinite(out)] = complex(np.inf)
        return out

    def _limit_at(self, s0: complex) -> complex:
        n, d = self.num, self.den
        for _ in range(_TAYLOR_ORDER):
            dv = d(s0)
            nv = n(s0)
            d_small = abs(dv) <= _ZERO_RTOL * float(d.magnitude_scale(s0)) or dv == 0
            n_small = abs(nv) <= _ZERO_RTOL * float(n.magnitude_scale(s0)) or nv == 0
            if not d_small:
                return complex(nv / dv)
            if not n_small:
                return complex(np.inf)
            n, d = n.derivative(), d.derivative()
        return complex(np.inf)

    def freqresp(self, omega: Any) -> np.ndarray:
        """Frequency response ``H(j omega)`` for real ``omega`` (rad/s).

        >>> complex(TransferFunction.from_poly([1.0], [1.0, 1.0]).freqresp([1.0])[0])
        (0.5-0.5j)
        """
        w = v.strict_real_array(omega, "omega", allow_empty=True)
        try:
            return np.asarray(self(1j * w))
        except ValueError as exc:  # H(j omega) outside the float range: name the argument given
            raise ValueError(f"omega: {exc}") from None

    @property
    def dc_gain(self) -> float:
        """``H(0)`` as a real number (``inf`` for a pole at 0); a property, as on every posicast system."""
        value = self(0.0)
        return _DcGain(float(value.real) if np.isfinite(value) else float("inf"))

    def removable_points(self) -> np.ndarray:
        """Common roots of numerator and denominator (not poles, not zeros), one entry per multiplicity.

        >>> S = TransferFunction(QuasiPolynomial([[1.0], [-1.0]], [0.0, 2.0]), QuasiPolynomial([[0.0, 2.0]]))
        >>> S.removable_points()                          # (1 - e^{-2 s}) / (2 s) at s = 0
        array([0.+0.j])
        """
        return removable_points(self.num, self.den)

    # ------------------------------------------------------------------ algebra
    @staticmethod
    def _coerce(other: Any) -> TransferFunction | None:
        if isinstance(other, TransferFunction):
            return other
        if isinstance(other, (int, float, np.integer, np.floating)):
            return TransferFunction.constant(float(other))
        if hasattr(other, "transfer") and isinstance(getattr(other, "transfer"), TransferFunction):
            return other.transfer  # a Shaper
        return None

    def __mul__(self, other: Any) -> TransferFunction:
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        return TransferFunction(self.num * o.num, self.den * o.den)

    def __rmul__(self, other: Any) -> TransferFunction:
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        return o * self

    def series(self, *others: Any) -> TransferFunction:
        """Series connection ``self * others[0] * ...``."""
        out = self
        for i, o in enumerate(others):
            out = out * as_transfer(o, f"others[{i}]")
        return out

    def __add__(self, other: Any) -> TransferFunction:
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        if self.den.equals(o.den):
            return TransferFunction(self.num + o.num, self.den)
        return TransferFunction(self.num * o.den + o.num * self.den, self.den * o.den)

    __radd__ = __add__

    def parallel(self, *others: Any) -> TransferFunction:
        """Parallel connection ``self + others[0] + ...``."""
        out = self
        for i, o in enumerate(others):
            out = out + as_transfer(o, f"others[{i}]")
        return out

    def __neg__(self) -> TransferFunction:
        return TransferFunction(-self.num, self.den)

    def __sub__(self, other: Any) -> TransferFunction:
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        return self + (-o)

    def __rsub__(self, other: Any) -> TransferFunction:
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        return o + (-self)

    def inverse(self) -> TransferFunction:
        """``1 / H`` (exact: numerator and denominator swap)."""
        if self.num.is_zero:
            raise IllPosed("cannot invert a zero transfer function")
        return TransferFunction(self.den, self.num)

    def __truediv__(self, other: Any) -> TransferFunction:
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        return self * o.inverse()

    def __rtruediv__(self, other: Any) -> TransferFunction:
        o = self._coerce(other)
        if o is None:
            return NotImplemented
        return o * self.inverse()

    def feedback(self, other: Any = 1.0, sign: int = -1) -> TransferFunction:
        """Closed loop ``H / (1 - sign * H * K)`` with ``K = other`` in the feedback path.

        ``sign=-1`` (default) is negative feedback.  Exact:
        ``N_H D_K / (D_H D_K - sign N_H N_K)``.
        """
        if isinstance(sign, (bool, np.bool_)) or not isinstance(sign, (int, float, np.integer, np.floating)):
            raise TypeError(f"sign must be -1 or +1, got {type(sign).__name__}")
        if sign not in (-1, 1):
            raise ValueError(f"sign must be -1 or +1, got {sign!r}")
        k = as_transfer(other, "other")
        num = self.num * k.den
        den = self.den * k.den - (self.num * k.num).scaled(float(sign))
        if den.is_zero:
            raise IllPosed("the closed loop has an identically zero characteristic function")
        return TransferFunction(num, den)

    # ------------------------------------------------------------------ conversion
    def to_scipy(self) -> Any:
        """Return a ``scipy.signal.TransferFunction`` (only for delay-free ``H``)."""
        from scipy import signal

        num, den = self._rational_desc()
        return signal.TransferFunction(num, den)

    def to_control(self) -> Any:
        """Return a python-control ``TransferFunction`` (only for delay-free ``H``).

        python-control is imported here, and only here.
        """
        try:
            import control  # noqa: PLC0415 - optional dependency
        except ImportError as exc:  # pragma: no cover - depends on environment
            raise ImportError("to_control() needs python-control: pip install control") from exc
        num, den = self._rational_desc()
        return control.TransferFunction(num, den)

    def _rational_desc(self) -> tuple[np.ndarray, np.ndarray]:
        num, tn = self.num.factor_min_delay()
        den, td = self.den.factor_min_delay()
        if not (num.is_polynomial and den.is_polynomial) or (tn - td) != 0:
            raise ValueError(
                "this transfer function contains delays; only a delay-free one converts to a rational "
                "model (posicast never approximates a delay)"
            )
        n = num.coeffs[0][::-1] if not num.is_zero else np.zeros(1)
        return n, den.coeffs[0][::-1]


class _NDPlan(NamedTuple):
    """:meth:`TransferFunction.__call__`'s constants: whether num and den share delays and degree
    (then ``cols``, their stacked coefficient columns, ``neg_tau`` and num's row count ``m``), and
    the Taylor expansion points with their radii."""

    shared: bool
    cols: tuple
    neg_tau: np.ndarray
    m: int
    near: tuple


def _ratio_series(taylor: tuple) -> tuple | None:
    """The series of num and den about a point as (2, 1) coefficient columns, both from the lowest
    power where either is nonzero (a coefficient below ``_CANCEL_RTOL`` of its scale is zero);
    None when den's series vanishes (a pole)."""
    cn, sn, cd, sd = taylor
    cn = np.where(np.abs(cn) <= _CANCEL_RTOL * sn, 0.0, cn)
    cd = np.where(np.abs(cd) <= _CANCEL_RTOL * sd, 0.0, cd)
    kn = np.flatnonzero(cn)
    kd = np.flatnonzero(cd)
    if kd.size == 0:
        return None
    k0 = min(kd[0], kn[0]) if kn.size else kd[0]
    return tuple(np.array([[a], [b]]) for a, b in zip(cn[k0:], cd[k0:]))


def delay(tau: float) -> TransferFunction:
    """The pure delay ``exp(-s tau)``.

    >>> bool(abs(delay(0.5)(1j * np.pi) - np.exp(-0.5j * np.pi)) < 1e-15)
    True
    """
    t = v.nonnegative(tau, "tau", " [s]")
    return TransferFunction(QuasiPolynomial([[1.0]], [t]), QuasiPolynomial.constant(1.0))


def as_transfer(obj: Any, name: str = "system") -> TransferFunction:
    """Convert what a user may pass as a plant or controller into a :class:`TransferFunction`.

    Accepted: a :class:`TransferFunction`; a posicast ``Shaper``; a number;
    ``(num, den)`` with numpy descending-power coefficient sequences; a
    ``scipy.signal.lti`` / ``dlti``-free continuous system (``TransferFunction``,
    ``ZerosPolesGain``, ``StateSpace``); a SISO python-control ``TransferFunction``
    or ``StateSpace`` (python-control is not imported for this: the object is
    read through its attributes).

    Raises
    ------
    TypeError
        For anything else, naming ``name``.
    """
    if not isinstance(name, str):
        raise TypeError(f"name must be a string (the argument's name in messages), got {type(name).__name__}")
    if isinstance(obj, TransferFunction):
        return obj
    if obj is None:
        raise TypeError(f"{name} must be a system (TransferFunction, (num, den), number, scipy/python-control "
                        f"system), got None")
    try:
        return _converted(obj, name)
    except (TypeError, ValueError) as exc:  # every message names the argument
        msg = str(exc)
        raise type(exc)(msg if msg.startswith(name) else f"{name}: {msg}") from None


def _converted(obj: Any, name: str) -> TransferFunction:
    """:func:`as_transfer` for anything but a TransferFunction or None."""
    tf = getattr(obj, "transfer", None)
    if isinstance(tf, TransferFunction):
        return tf
    if isinstance(obj, (bool, np.bool_)):
        raise TypeError(f"{name} must be a transfer function, (num, den) or a number, got a bool")
    if isinstance(obj, (int, float, np.integer, np.floating)):
        return TransferFunction.constant(v.finite_real(obj, name))
    if isinstance(obj, tuple) and len(obj) == 2:
        try:
            return TransferFunction.from_poly(obj[0], obj[1])
        except (TypeError, ValueError) as exc:
            raise type(exc)(f"{name} = (num, den): {exc}") from None
    mod = type(obj).__module__ or ""
    if mod.startswith("scipy.signal"):
        if getattr(obj, "dt", None) not in (None, 0):
            raise TypeError(f"{name}: a discrete-time scipy system is not a continuous plant")
        with warnings.catch_warnings():  # ss -> tf leaves rounding-level leading coefficients
            warnings.simplefilter("ignore")
            tf_obj = obj.to_tf()
        return TransferFunction.from_poly(np.atleast_1d(tf_obj.num).ravel(), tf_obj.den)
    if mod.startswith("control"):
        return _from_control(obj, name)
    raise TypeError(
        f"{name} must be a posicast TransferFunction, a (num, den) tuple, a number, a scipy.signal lti "
        f"or a python-control TransferFunction/StateSpace; got {type(obj).__name__}"
    )


def _from_control(obj: Any, name: str) -> TransferFunction:
    if getattr(obj, "ninputs", 1) != 1 or getattr(obj, "noutputs", 1) != 1:
        raise ValueError(f"{name} must be SISO, got {obj.noutputs}x{obj.ninputs}")
    dt = getattr(obj, "dt", 0)
    if dt not in (0, None):
        raise TypeError(f"{name}: a discrete-time python-control system is not a continuous plant")
    if hasattr(obj, "A") and hasattr(obj, "B"):  # StateSpace
        from scipy import signal

        A, B, C, D = (np.asarray(x, dtype=float) for x in (obj.A, obj.B, obj.C, obj.D))
        if A.size == 0:
            return TransferFunction.constant(float(D.ravel()[0]))
        num, den = signal.ss2tf(A, B, C, D)
        return TransferFunction.from_poly(np.atleast_1d(num[0]), den)
    num = getattr(obj, "num_array", None)
    den = getattr(obj, "den_array", None)
    if num is None:
        num, den = obj.num, obj.den
    return TransferFunction.from_poly(np.asarray(num[0][0], dtype=float), np.asarray(den[0][0], dtype=float))
