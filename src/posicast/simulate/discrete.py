"""Discrete-time building blocks for simulating loops with shapers.

Polynomials here are in ascending powers of ``z^-1`` (the ``b, a`` convention
of :func:`scipy.signal.lfilter`).  Shapers are discretised by
:func:`posicast.simulate.streaming.discretize`.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import signal

from ..core.transfer import TransferFunction

__all__ = ["discretize_rational", "poly_add", "poly_mul", "exact_delayed_response", "schur_propagate"]


def poly_mul(*polys: np.ndarray) -> np.ndarray:
    out = np.ones(1)
    for p in polys:
        out = np.convolve(out, p)
    return out


def poly_add(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    n = max(a.size, b.size)
    out = np.zeros(n)
    out[: a.size] += a
    out[: b.size] += b
    return out


def discretize_rational(tf: TransferFunction, h: float, method: str) -> tuple[np.ndarray, np.ndarray]:
    """``(b, a)`` in powers of ``z^-1`` of a delay-free proper transfer function.

    ``method``: ``'zoh'`` (exact for a held input), ``'foh'`` (exact for a
    piecewise-linear input), ``'bilinear'`` (Tustin).
    """
    if tf.has_delays:
        raise ValueError("a rational block with delays cannot be discretized here")
    num, den = tf.to_scipy().num, tf.to_scipy().den
    num = np.atleast_1d(np.asarray(num, float))
    den = np.atleast_1d(np.asarray(den, float))
    if num.size > den.size:
        raise ValueError("the transfer function is improper (more zeros than poles): it cannot be simulated")
    if den.size == 1:
        return np.array([num[-1] / den[0]]), np.ones(1)
    with warnings.catch_warnings():
        # scipy warns about tiny leading numerator coefficients (rounding of exact zeros): harmless here
        warnings.simplefilter("ignore", signal.BadCoefficients)
        b, a, _ = signal.cont2discrete((num, den), h, method=method)
    b = np.atleast_1d(np.squeeze(b))
    a = np.atleast_1d(np.asarray(a, float))
    b = np.concatenate([np.zeros(a.size - b.size), b]) if b.size < a.size else b
    return b / a[0], a / a[0]


def exact_delayed_response(tf: TransferFunction, x: np.ndarray, h: float) -> np.ndarray:
    """Exact sampled response of ``tf`` to the held (ZOH) input ``x`` on step ``h``.

    ``tf`` has a polynomial (delay-free) denominator and a numerator
    ``sum_i p_i(s) exp(-s t_i)``: each term is a rational system with an input
    delay ``t_i = (n + f) h``.  Its exact discretisation splits the held
    input at the fractional instant ``f h`` inside a step (the modified
    z-transform), so delays that are not multiples of the step are exact.
    """
    den = tf.den
    if den.has_delays:
        raise ValueError("exact_delayed_response needs a delay-free denominator")
    dtau = float(den.delays[0])
    den_desc = den.coeffs[0, ::-1]
    den_desc = np.trim_zeros(den_desc, "f")
    y = np.zeros(x.size)
    for row, tau in zip(tf.num.coeffs, tf.num.delays):
        t = float(tau) - dtau
        if t < -1e-12:
            raise ValueError("the transfer function is not causal (negative net delay)")
        num_desc = np.trim_zeros(row[::-1], "f")
        if num_desc.size == 0:
            continue
        if num_desc.size > den_desc.size:
            raise ValueError("improper channel: cannot be simulated")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", signal.BadCoefficients)
            A, B, C, D = signal.tf2ss(num_desc, den_desc)
        n = int(math.floor(t / h + 1e-12))
        f = max(0.0, t / h - n)
        if f < 1e-12:
            f = 0.0
        nx = A.shape[0]
        if nx == 0:  # a static gain sees x(t_k - t)
            y += float(D[0, 0]) * _shift(x, n if f == 0 else n + 1)
            continue
        Phi, G_full = _zoh(A, B, h)
        if f == 0.0:
            y += schur_propagate(Phi, [(G_full[:, 0], _shift(x, n))], C[0]) + float(D[0, 0]) * _shift(x, n)
        else:
            delta = f * h
            Phi_a, G_a = _zoh(A, B, h - delta)   # the last h - delta of the step: input x[k - n]
            _, G_b = _zoh(A, B, delta)           # the first delta of the step: input x[k - n - 1]
            xs = _shift(x, n + 1)
            y += schur_propagate(Phi, [(G_a[:, 0], _shift(x, n)), ((Phi_a @ G_b)[:, 0], xs)], C[0])
            y += float(D[0, 0]) * xs  # the direct term sees x(t_k - t) = x[k - n - 1]
    return y


def _shift(x: np.ndarray, n: int) -> np.ndarray:
    if n <= 0:
        return x
    out = np.zeros_like(x)
    if n < x.size:
        out[n:] = x[:-n]
    return out


def _zoh(A: np.ndarray, B: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    from scipy.linalg import expm

    n, m = A.shape[0], B.shape[1]
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A * T
    M[:n, n:] = B * T
    E = expm(M)
    return E[:n, :n], E[:n, n:]


def schur_propagate(
    Phi: np.ndarray, inputs: list[tuple[np.ndarray, np.ndarray]], c: np.ndarray
) -> np.ndarray:
    """Outputs ``y[k] = c x[k]`` of ``x[k+1] = Phi x[k] + sum_j g_j u_j[k]``, ``x[0] = 0``.

    ``c`` is one output row or a 2-D array of rows (then one output per row).
    When ``Phi`` has a well-conditioned eigenbasis the recursion runs mode by
    mode (one first-order complex recursion per conjugate pair); otherwise in
    the complex Schur basis ``Phi = Q T Q^H``, the triangular system solved
    from the last state up.  Either way every recursion is first order:
    unlike a high-order transfer function (whose coefficients lose accuracy
    when a small step clusters the poles near ``z = 1``) this is accurate to
    rounding, and the Schur path handles repeated poles (integrators).
    """
    from scipy.linalg import schur

    rows = np.atleast_2d(np.asarray(c, dtype=float))
    n = Phi.shape[0]
    N = inputs[0][1].size
    if n == 0:
        return np.zeros((rows.shape[0], N)) if np.ndim(c) == 2 else np.zeros(N)
    lam, V = np.linalg.eig(Phi)
    if np.linalg.cond(V) < 1e8:
        Vinv = np.linalg.inv(V)
        # y = sum_i Re(coef_i z_i): the modal signals go into one matrix, then one product
        Z = np.empty((2 * n, N))
        W = np.empty((rows.shape[0], 2 * n))
        used = 0
        done = np.zeros(n, dtype=bool)
        for i in range(n):
            if done[i]:
                continue
            done[i] = True
            weight = 1.0
            if abs(lam[i].imag) > 1e-14 * max(1.0, abs(lam[i])):
                j = [k for k in range(n) if not done[k] and abs(lam[k] - lam[i].conjugate()) <= 1e-9 * max(1.0, abs(lam[i]))]
                if j:
                    done[j[0]] = True
                    weight = 2.0  # the conjugate mode contributes the conjugate
            coef = weight * (rows @ V[:, i])
            if lam[i].imag == 0.0 and not np.any(V[:, i].imag) and not np.any(Vinv[i].imag):
                drive_r = sum(float((Vinv[i] @ g).real) * u for g, u in inputs)
                Z[used] = signal.lfilter([0.0, 1.0], [1.0, -lam[i].real], drive_r)
                W[:, used] = coef.real
                used += 1
                continue
            drive = sum(complex(Vinv[i] @ g) * u for g, u in inputs)
            zi = signal.lfilter([0.0, 1.0], [1.0, -lam[i]], drive)
            Z[used], Z[used + 1] = zi.real, zi.imag  # Re(c z) = Re c Re z - Im c Im z
            W[:, used], W[:, used + 1] = coef.real, -coef.imag
            used += 2
        out = W[:, :used] @ Z[:used]
        return out if np.ndim(c) == 2 else out[0]
    T, Q = schur(Phi.astype(complex), output="complex")
    QH = Q.conj().T
    drive = np.zeros((n, N), dtype=complex)
    for g, u in inputs:
        drive += np.outer(QH @ g, u)
    z = np.zeros((n, N), dtype=complex)
    for i in range(n - 1, -1, -1):
        rhs = drive[i]
        if i + 1 < n:
            rhs = rhs + T[i, i + 1 :] @ z[i + 1 :]
        z[i] = signal.lfilter([0.0, 1.0], [1.0, -T[i, i]], rhs)
    y = ((rows @ Q) @ z).real
    return y if np.ndim(c) == 2 else y[0]


def _ss_to_filter(Phi: np.ndarray, Gam: np.ndarray, C: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    b, a = signal.ss2tf(Phi, Gam, C, D)
    b = np.atleast_1d(np.squeeze(b))
    return b / a[0], a / a[0]
