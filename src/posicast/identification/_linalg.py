"""numpy.linalg's ``solve``, ``lstsq`` and ``eigvals`` for the small real problems of the mode tests and ARX,
without their wrappers.

``np.linalg.solve`` of an 8 x 8 system spends three quarters of its time in argument handling
(array wrapping, type promotion, shape checks) around one LAPACK call, and ``np.linalg.lstsq``
a quarter; the whitening filter of every coloured mode test solves eight systems (issue #15).
These functions call the same compiled numpy routines (``numpy.linalg._umath_linalg``) with the
same signature and the same floating-point error handling, so the results are numpy's to the bit;
when a numpy moves those routines, they fall back to ``np.linalg``.
"""

from __future__ import annotations

import numpy as np

try:  # the gufuncs np.linalg.solve / lstsq call (numpy >= 2.0)
    from numpy.linalg import _umath_linalg as _ul

    _SOLVE1, _LSTSQ, _EIGVALS = _ul.solve1, _ul.lstsq, _ul.eigvals
except (ImportError, AttributeError):  # pragma: no cover - another numpy
    _SOLVE1 = _LSTSQ = _EIGVALS = None


def _same_as_numpy() -> bool:
    """Do the private gufuncs, called as below, still give np.linalg's results (a private API can change its
    signature in any numpy release: then np.linalg is used)?"""
    a, b = np.array([[2.0, 1.0, 0.5], [1.0, 3.0, 0.0], [0.5, 0.0, 4.0]]), np.array([1.0, 2.0, -1.0])
    try:
        with np.errstate(all="ignore"):
            return bool(np.array_equal(_SOLVE1(a, b, signature="dd->d"), np.linalg.solve(a, b))
                        and np.array_equal(_LSTSQ(a[:, :2], b[:, None], _EPS * 3, signature="ddd->ddid")[0][:, 0],
                                           np.linalg.lstsq(a[:, :2], b, rcond=None)[0])
                        and np.array_equal(_EIGVALS(a, signature="d->D"), np.linalg.eigvals(a).astype(complex)))
    except Exception:  # noqa: BLE001 - any failure means: use np.linalg  # pragma: no cover
        return False

__all__ = ["solve", "lstsq", "eigvals"]

_EPS = float(np.finfo(float).eps)
if _SOLVE1 is not None and not _same_as_numpy():  # pragma: no cover - a numpy whose private API moved
    _SOLVE1 = _LSTSQ = _EIGVALS = None


def _singular(err: object, flag: object) -> None:
    raise np.linalg.LinAlgError("Singular matrix")


def _no_convergence(err: object, flag: object) -> None:
    raise np.linalg.LinAlgError("SVD did not converge in Linear Least Squares")


def _no_eigenvalues(err: object, flag: object) -> None:
    raise np.linalg.LinAlgError("Eigenvalues did not converge")


def solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.linalg.solve(a, b)`` for a real square ``a`` (float64) and a vector ``b`` (float64).

    >>> solve(np.array([[2.0, 0.0], [0.0, 4.0]]), np.array([1.0, 1.0])).tolist()
    [0.5, 0.25]
    """
    if _SOLVE1 is None:  # pragma: no cover
        return np.linalg.solve(a, b)
    with np.errstate(call=_singular, invalid="call", over="ignore", divide="ignore", under="ignore"):
        return _SOLVE1(a, b, signature="dd->d")


def lstsq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The solution of ``np.linalg.lstsq(a, b, rcond=None)`` for a real ``a`` (m, n), m >= 1, and a vector ``b``.

    >>> a, b = np.array([[1.0, 0.5], [1.0, 2.0], [1.0, 3.0]]), np.array([1.0, 3.0, 2.0])
    >>> lstsq(a, b).tolist() == np.linalg.lstsq(a, b, rcond=None)[0].tolist()
    True
    """
    if _LSTSQ is None:  # pragma: no cover
        return np.linalg.lstsq(a, b, rcond=None)[0]
    m, n = a.shape
    with np.errstate(call=_no_convergence, invalid="call", over="ignore", divide="ignore", under="ignore"):
        x = _LSTSQ(a, b[:, None], _EPS * max(n, m), signature="ddd->ddid")[0]
    return x[:, 0].copy()


def eigvals(a: np.ndarray) -> np.ndarray:
    """``np.linalg.eigvals(a)`` for a real square ``a`` (float64): complex eigenvalues, or real ones when every
    imaginary part is 0.

    >>> eigvals(np.array([[0.0, -1.0], [1.0, 0.0]])).tolist()
    [1j, -1j]
    """
    if _EIGVALS is None:  # pragma: no cover
        return np.linalg.eigvals(a)
    if not np.isfinite(a).all():
        raise np.linalg.LinAlgError("Array must not contain infs or NaNs")
    with np.errstate(call=_no_eigenvalues, invalid="call", over="ignore", divide="ignore", under="ignore"):
        w = _EIGVALS(a, signature="d->D")
    return w.real.copy() if (w.imag == 0).all() else w
