"""One set of spectral verbs for every posicast object.

``roots``, ``poles``, ``zeros``, ``stability``, ``spectral_abscissa``, ``rightmost``
and ``unstable_count`` accept a :class:`~posicast.core.quasipoly.QuasiPolynomial`, a
:class:`~posicast.core.transfer.TransferFunction`, a :class:`~posicast.shapers.base.Shaper`
or a :class:`~posicast.loops.loop.Loop` (and anything
:func:`~posicast.core.transfer.as_transfer` takes: scipy and python-control systems,
numbers).  Every object answers the same verbs as methods (python-control's rule:
``posicast.poles(G, region)`` and ``G.poles(region)`` are one computation).

What each verb reads:

=====================  =====================================  ===============================
object                 poles, stability, spectral abscissa    zeros
=====================  =====================================  ===============================
quasi-polynomial ``h``  none (``h`` is entire); ``roots``,     the roots of ``h``
                       ``stability`` etc. read ``h`` itself
transfer function,     roots of the denominator less the       roots of the numerator less the
shaper ``N / D``       removable points (common roots)         removable points
loop                   roots of ``characteristic`` less        of one channel:
                       ``cancelled`` (closed-loop poles)       ``channel=(src, dst)``
=====================  =====================================  ===============================

``roots(x, region)`` is the quasi-polynomial word: for a system it means its poles.
A bare 2-tuple is read as a quasi-polynomial ``(coeffs, delays)`` by ``roots``,
``stability``, ``spectral_abscissa``, ``rightmost`` and ``unstable_count`` (as
before), and as a system ``(num, den)`` (numpy descending powers) by ``poles``
and ``zeros``.

Return types: ``roots``/``poles``/``zeros`` a :class:`~posicast.spectra.rootfinder.Roots`;
``stability`` a :class:`~posicast.spectra.verdict.Stability`; ``spectral_abscissa`` a
:class:`~posicast.spectra.verdict.SpectralAbscissa` (a ``float``); ``rightmost`` an
array; ``unstable_count`` an ``int``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .. import _validate as v
from ..core.quasipoly import QuasiPolynomial
from ..core.removable import removable_points
from ..core.transfer import TransferFunction, as_transfer
from . import rootfinder as _rf
from . import verdict as _st
from .rootfinder import Roots
from .verdict import SpectralAbscissa, Stability

__all__ = ["roots", "poles", "zeros", "stability", "spectral_abscissa", "rightmost", "unstable_count", "Characteristic",
           "characteristic_of"]


@dataclass(frozen=True)
class Characteristic:
    """The quasi-polynomial whose roots are an object's poles, and the points that are not poles.

    Attributes
    ----------
    quasi : QuasiPolynomial
        A transfer function's denominator, a loop's characteristic quasi-polynomial,
        or a quasi-polynomial itself.
    removable : ndarray of complex
        Roots of ``quasi`` that are not poles (common roots with the numerator, a
        loop's ``cancelled`` points), one entry per multiplicity.
    """

    quasi: QuasiPolynomial
    removable: np.ndarray


def _is_quasi(obj: Any) -> bool:
    return isinstance(obj, QuasiPolynomial) or (isinstance(obj, tuple) and len(obj) == 2)


def _is_loop(obj: Any) -> bool:
    # loops sit above spectra: a loop is recognised by what it carries, not by its class
    return isinstance(getattr(obj, "characteristic", None), QuasiPolynomial) and hasattr(obj, "cancelled")


def _transfer(system: Any, name: str) -> TransferFunction:
    try:
        return as_transfer(system, name)
    except TypeError:
        if isinstance(system, tuple):  # a (num, den) pair: as_transfer's message says what is wrong in it
            raise
        raise TypeError(
            f"{name} must be a QuasiPolynomial, TransferFunction, Shaper, Loop, (num, den), number, "
            f"scipy or python-control system; got {type(system).__name__}"
        ) from None


def characteristic_of(system: Any) -> Characteristic:
    """The quasi-polynomial whose roots are ``system``'s poles (see the module table).

    A 2-tuple is a system ``(num, den)`` here, as for :func:`poles`.

    >>> import posicast
    >>> c = characteristic_of(posicast.design("dzv", posicast.Mode(10.0, 0.03)))
    >>> c.quasi.degree, c.removable          # D(s) = s T, its root s = 0 is removable
    (1, array([0.+0.j]))
    """
    if isinstance(system, tuple):
        system = _transfer(system, "system")
    return _characteristic(system, "system")


def _characteristic(h: Any, name: str) -> Characteristic:
    """:func:`characteristic_of`, reading a 2-tuple as a quasi-polynomial ``(coeffs, delays)``."""
    if _is_quasi(h):
        try:
            q = _rf.as_quasipolynomial(h, name)
        except (TypeError, ValueError) as exc:
            if not isinstance(h, tuple):
                raise
            raise type(exc)(f"{name}: a 2-tuple is read here as a quasi-polynomial (coeffs, delays) ({exc}); "
                            "for a system (num, den) pass TransferFunction.from_poly(num, den) or use poles()") from None
        return Characteristic(q, np.zeros(0, dtype=complex))
    if _is_loop(h):
        return Characteristic(h.characteristic, np.asarray(h.cancelled, dtype=complex))
    tf = _transfer(h, name)
    return Characteristic(tf.den, removable_points(tf.num, tf.den))


def _roots_naming(c: Characteristic, region: Any, name: str, max_evaluations: Any, timeout: Any) -> Roots:
    """The roots of ``c``; a ValueError that is about the system (not the region or budget) names it."""
    _rf.check_region(region)
    _rf.check_budget(max_evaluations, timeout)
    try:
        return _rf.roots(c.quasi, region, ignore=c.removable if c.removable.size else None,
                         max_evaluations=max_evaluations, timeout=timeout)
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from None


def _numerator_of(system: Any, channel: Sequence[str] | None, name: str) -> Characteristic:
    if _is_quasi(system):
        if isinstance(system, tuple):
            return _numerator_of(_transfer(system, name), channel, name)
        if channel is not None:
            raise ValueError("channel applies to a loop only")
        return Characteristic(_rf.as_quasipolynomial(system, name), np.zeros(0, dtype=complex))
    if _is_loop(system):
        src, dst = _channel(system, channel)
        tf = system.transfer(src, dst)
        if tf.num.is_zero:
            raise ValueError(f"channel {src} -> {dst} is identically zero: it has no zeros to compute")
        return Characteristic(tf.num, system.channel_cancelled(src, dst))
    if channel is not None:
        raise ValueError("channel applies to a loop only")
    tf = _transfer(system, name)
    if tf.num.is_zero:
        raise ValueError(f"{name} is identically zero: every s is a zero")
    return Characteristic(tf.num, removable_points(tf.num, tf.den))


def _channel(loop: Any, channel: Any) -> tuple[str, str]:
    """``channel`` as a pair of the loop's signal names ``(src, dst)``."""
    allowed = f"src in {tuple(loop.inputs)}, dst in {tuple(loop.outputs)}"
    if channel is None:
        raise ValueError(f"the zeros of a loop are those of one channel: pass channel=(src, dst), {allowed}")
    if not isinstance(channel, (tuple, list)) or len(channel) != 2 or not all(isinstance(c, str) for c in channel):
        raise TypeError(f"channel must be a pair of signal names (src, dst), {allowed}; got {channel!r}")
    src, dst = channel
    if src not in loop.inputs or dst not in loop.outputs:
        raise ValueError(f"channel must be (src, dst) with {allowed}; got {channel!r}")
    return src, dst


def _ignored(own: np.ndarray, ignore: Any) -> Any:
    """The object's own removable points plus the caller's ``ignore`` (None when both are empty)."""
    if ignore is None:
        return own if own.size else None
    if not own.size:
        return ignore  # checked where it is used
    return np.concatenate([own, np.atleast_1d(v.complex_array(ignore, "ignore"))])


def roots(h: Any, region: Sequence[float], *, ignore: Any = None, max_evaluations: float = 5e7,
          timeout: float = 120.0) -> Roots:
    """All roots of a quasi-polynomial in a rectangle, with a certified count; for a system, its poles.

    ``h`` is a :class:`QuasiPolynomial` (or a ``(coeffs, delays)`` pair), or any
    system (transfer function, shaper, loop: :func:`poles`).  See
    :func:`posicast.spectra.rootfinder.roots` for the method, ``region``,
    ``ignore``, ``max_evaluations`` and ``timeout``.

    >>> import posicast
    >>> r = posicast.roots(posicast.QuasiPolynomial.from_poly([1.0, 3.0, 2.0]), (-5, 5, -5, 5))
    >>> np.round(r.roots.real, 12)
    array([-1., -2.])
    """
    c = _characteristic(h, "h")
    return _rf.roots(c.quasi, region, ignore=_ignored(c.removable, ignore), max_evaluations=max_evaluations,
                     timeout=timeout)


def poles(system: Any, region: Sequence[float], *, max_evaluations: float = 5e7, timeout: float = 120.0) -> Roots:
    """Poles of a transfer function, shaper or loop in ``region`` (certified count).

    The roots of the denominator (a loop: its characteristic quasi-polynomial)
    less the removable points.  A quasi-polynomial has no poles.  The removable
    points of a transfer function are found when its denominator is a polynomial
    (every shaper's is); a denominator with delays (e.g. ``(C * G).feedback()``
    with a delay in the loop) keeps any root it shares with the numerator: build a
    :class:`~posicast.loops.loop.Loop` for a loop's exact closed-loop poles.

    Examples
    --------
    >>> import posicast
    >>> G = posicast.TransferFunction.from_poly([1.0], [1.0, 3.0, 2.0])     # 1 / ((s + 1)(s + 2))
    >>> np.round(posicast.poles(G, (-5, 5, -5, 5)).roots.real, 12)
    array([-1., -2.])
    >>> posicast.design("dzv", posicast.Mode(10.0, 0.03)).poles((-50, 50, -50, 50)).count   # s = 0 removable
    0
    """
    if isinstance(system, QuasiPolynomial):
        raise TypeError("a QuasiPolynomial has no poles (it is entire): roots(h, region) gives its zeros")
    return _roots_naming(characteristic_of(system), region, "system", max_evaluations, timeout)


def zeros(system: Any, region: Sequence[float], *, channel: Sequence[str] | None = None,
          max_evaluations: float = 5e7, timeout: float = 120.0) -> Roots:
    """Zeros in ``region`` (certified count): the numerator's roots less the removable points.

    For a loop, the zeros of one channel ``channel=(src, dst)``; for a
    quasi-polynomial, its roots.

    Examples
    --------
    >>> import posicast
    >>> S = posicast.design("zv", posicast.Mode(10.0, 0.0))           # zeros at +-10j, +-30j, ...
    >>> z = posicast.zeros(S, (-1, 1, 0, 25))
    >>> np.round(z.roots, 9)
    array([0.+10.j])
    """
    return _roots_naming(_numerator_of(system, channel, "system"), region, "system", max_evaluations, timeout)


def stability(h: Any, *, ignore: Any = None, max_evaluations: float = 5e7, timeout: float = 120.0) -> Stability:
    """Exponential stability of ``h`` (a quasi-polynomial) or of a system's poles.

    See :func:`posicast.spectra.verdict.stability`.

    >>> import posicast
    >>> posicast.stability(posicast.TransferFunction.from_poly([1.0], [1.0, -1.0])).reason
    '1 root with Re s >= 0, the rightmost at 1'
    """
    c = _characteristic(h, "h")
    return _st.stability(c.quasi, ignore=_ignored(c.removable, ignore), max_evaluations=max_evaluations,
                         timeout=timeout)


def spectral_abscissa(h: Any, *, ignore: Any = None, max_radius: float = 2e4) -> SpectralAbscissa:
    """Largest real part of the roots of ``h`` (a system: of its poles), with a certified error.

    See :func:`posicast.spectra.verdict.spectral_abscissa`.

    >>> import posicast
    >>> round(posicast.spectral_abscissa(posicast.TransferFunction.from_poly([1.0], [1.0, 3.0, 2.0])), 12)
    -1.0
    """
    c = _characteristic(h, "h")
    return _st.spectral_abscissa(c.quasi, ignore=_ignored(c.removable, ignore), max_radius=max_radius)


def rightmost(h: Any, n: int = 1, *, ignore: Any = None, max_alpha_steps: int = 12,
              max_radius: float = 2e4) -> np.ndarray:
    """The ``n`` rightmost roots of ``h`` (a system: poles), see :func:`posicast.spectra.verdict.rightmost`."""
    c = _characteristic(h, "h")
    return _st.rightmost(c.quasi, n, ignore=_ignored(c.removable, ignore), max_alpha_steps=max_alpha_steps,
                         max_radius=max_radius)


def unstable_count(h: Any, *, ignore: Any = None, max_evaluations: float = 2e6) -> int:
    """Certified number of roots (a system: poles) with ``Re s >= 0``; see
    :func:`posicast.spectra.verdict.unstable_count`."""
    c = _characteristic(h, "h")
    return _st.unstable_count(c.quasi, ignore=_ignored(c.removable, ignore), max_evaluations=max_evaluations)
