"""Discrete-time building blocks for simulating loops with shapers.

Rational blocks (controller, plant, load, the IIR part of a shaper) are kept
in **state-space** form: a balanced realisation of the continuous transfer
function (:func:`state_space`) discretised as a state space
(:func:`discretize_ss`).  They are never multiplied out into one high-order
``z^-1`` polynomial: at small steps all poles of such a polynomial cluster
near ``z = 1`` and its coefficients no longer determine them (measured on the
ninth-order gantry-crane plant: pole errors 3e-5 at 1 ms, 7e-3 at 0.5 ms, 3e-2
at 0.2 ms, against 1e-14 for the balanced state space), which made stable
loops diverge.

Polynomials here (:func:`poly_mul`, :func:`poly_add`) are in ascending powers
of ``z^-1`` (the ``b, a`` convention of :func:`scipy.signal.lfilter`); they
serve only low-order feedforward filters.  Shapers are discretised by
:func:`posicast.simulation.streaming.discretize`.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import fft as sp_fft
from scipy import signal
from scipy.linalg import matrix_balance

from ..core.transfer import TransferFunction

__all__ = [
    "state_space",
    "balance",
    "discretize_ss",
    "poly_add",
    "poly_mul",
    "exact_delayed_response",
    "PowerPropagator",
    "HeldFilter",
    "block_length",
    "propagate",
]


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


def balance(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(T^-1 A T, T^-1 B, C T)`` with the diagonal ``T`` that balances ``A``.

    A realisation built from polynomial coefficients, or a loop assembled from
    such blocks, can have entries spread over 15 orders of magnitude (the
    crane plant's ``C`` row holds 2e15); the matrix exponential, the
    eigenvectors and every state update then lose all digits relative to the
    largest entry.  ``T`` holds powers of two (exact), so the system is the
    same to rounding.

    Parameters
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    C : ndarray, shape (p, n)

    Returns
    -------
    A, B, C : ndarray
        The balanced system.
    """
    if A.shape[0] == 0:
        return A, B, C
    # scipy's balancing casts an intermediate to int and warns ("invalid value encountered in cast") on a
    # companion matrix whose entries span 1e-3..1e-33 (an 11th-order plant at 0.001 rad/s), yet returns
    # a good T; a T that is not finite and positive is not used
    with np.errstate(invalid="ignore", over="ignore"):
        Ab, T = matrix_balance(A, permute=False)
    scale = np.diag(T)
    if not (np.all(np.isfinite(Ab)) and np.all(np.isfinite(scale)) and np.all(scale > 0)):
        return A, B, C
    return Ab, B / scale[:, None], C * scale[None, :]


def state_space(tf: TransferFunction) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """A balanced state-space realisation ``(A, B, C, D)`` of a delay-free proper transfer function.

    Parameters
    ----------
    tf : TransferFunction
        Delay-free, proper.

    Returns
    -------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, 1)
    C : ndarray, shape (1, n)
    D : float
        ``n`` is the denominator's degree (0 for a static gain).

    Raises
    ------
    ValueError
        ``tf`` has delays or more zeros than poles.
    """
    if tf.has_delays:
        raise ValueError("a rational block with delays cannot be realised here")
    num = np.trim_zeros(tf.num.coeffs[0][::-1], "f") if not tf.num.is_zero else np.zeros(1)
    den = np.trim_zeros(tf.den.coeffs[0][::-1], "f")
    if num.size > den.size:
        raise ValueError("the transfer function is improper (more zeros than poles): it cannot be simulated")
    if den.size == 1:
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), float(num[-1] / den[0])
    with warnings.catch_warnings():
        # scipy warns about tiny leading numerator coefficients (rounding of exact zeros): harmless here
        warnings.simplefilter("ignore", signal.BadCoefficients)
        A, B, C, D = signal.tf2ss(num, den)
    A, B, C = balance(A, B, C)
    return A, B, C, float(D[0, 0])


def discretize_ss(tf: TransferFunction, h: float, method: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The state space ``(A, B, C, D)`` of a delay-free proper transfer function on step ``h``.

    ``method``: ``'zoh'`` (exact for a held input), ``'foh'`` (exact for a
    piecewise-linear input), ``'bilinear'`` (Tustin); applied to the balanced
    continuous realisation (:func:`state_space`), so the discrete poles are
    accurate to rounding however small ``h`` is (unlike those of the
    equivalent ``z^-1`` polynomial).

    Parameters
    ----------
    tf : TransferFunction
    h : float
        Step [s].
    method : {'zoh', 'foh', 'bilinear'}

    Returns
    -------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, 1)
    C : ndarray, shape (1, n)
    D : float
    """
    A, B, C, D = state_space(tf)
    if A.shape[0] == 0:
        return A, B, C, D
    Ad, Bd, Cd, Dd, _ = signal.cont2discrete((A, B, C, np.array([[D]])), h, method=method)
    return Ad, Bd, Cd, float(Dd[0, 0])


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
        A, B, C = balance(A, B, C)  # the companion form of a high-order channel is badly scaled
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
            y += propagate(Phi, [(G_full[:, 0], _shift(x, n))], C[0]) + float(D[0, 0]) * _shift(x, n)
        else:
            delta = f * h
            Phi_a, G_a = _zoh(A, B, h - delta)   # the last h - delta of the step: input x[k - n]
            _, G_b = _zoh(A, B, delta)           # the first delta of the step: input x[k - n - 1]
            xs = _shift(x, n + 1)
            y += propagate(Phi, [(G_a[:, 0], _shift(x, n)), ((Phi_a @ G_b)[:, 0], xs)], C[0])
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


# longest block of PowerPropagator (the powers A^j, j < BLOCK, are stored)
BLOCK = 4096


def block_length(n: int, steps: int) -> int:
    """Block length of a :class:`PowerPropagator` for an order-``n`` system over ``steps`` steps.

    At most :data:`BLOCK`, and short enough that the stored powers ``A^j``
    (``length x n x n`` numbers) stay within 4M entries (32 MB) for a high-order loop.
    """
    return max(1, min(steps, BLOCK, (1 << 22) // max(1, n * n)))


class PowerPropagator:
    """``x[k+1] = A x[k] + B u[k]``, ``y = C x``, over blocks of at most ``size`` steps from the powers of ``A``.

    Over a block the outputs are ``C A^j x0`` plus the convolution of the
    input with ``C A^(j-1) B`` (by FFT), in real arithmetic: as accurate as
    the step-by-step update (about 1e-13 relative) whatever the eigenvectors.
    Why not a modal or Schur basis, one first-order recursion per mode: near
    a double pole or a near pole-zero cancellation the eigenvectors are
    almost parallel and those recursions lost up to 1e-3 (a notch's double
    pole at 1 ms, eigenvector condition 6e7) or 1.5e-6 (the crane notch
    loop, condition 4e7) of the result.

    Parameters
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    size : int
        Longest block (>= 1).
    C : ndarray, shape (p, n), optional
        Output rows (default: the states themselves).
    """

    def __init__(self, A: np.ndarray, B: np.ndarray, size: int, C: np.ndarray | None = None) -> None:
        m = B.shape[1]
        self.A = A
        with np.errstate(over="ignore", invalid="ignore"):  # an unstable system overflows: reported as NaN
            self.powers = _powers(A, size)  # A^j, j = 0 .. size - 1
            self.free = self.powers if C is None else C @ self.powers  # C A^j
            markov = np.concatenate([np.zeros((1, self.free.shape[1], m)), self.free[:-1] @ B])  # C A^(j-1) B
            # A^(size-1-j) B as (n, size, m): the last L of them, read as an (n, L m) matrix without a copy,
            # give sum_i A^(L-1-i) B u[i] in one product
            self.state_markov = np.ascontiguousarray((self.powers @ B)[::-1].transpose(1, 0, 2))
            # the convolution with the Markov parameters by FFT, their transform once for all blocks,
            # one (frequencies, outputs) slice per input
            self.nfft = sp_fft.next_fast_len(2 * size - 1, real=True)
            self.markov_f = np.ascontiguousarray(sp_fft.rfft(markov, self.nfft, axis=0).transpose(2, 0, 1))
        self.size = size

    def block(self, x0: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Outputs at steps ``0 .. L-1`` (columns) from ``x[0] = x0`` under the inputs ``U`` (m, L), and ``x[L]``."""
        L = U.shape[1]
        with np.errstate(over="ignore", invalid="ignore"):
            U_f = sp_fft.rfft(U, self.nfft, axis=1)
            spectrum = self.markov_f[0] * U_f[0][:, None]
            for j in range(1, U_f.shape[0]):
                spectrum += self.markov_f[j] * U_f[j][:, None]
            forced = sp_fft.irfft(spectrum, self.nfft, axis=0)[:L]
            Y = (self.free[:L] @ x0 + forced).T
            # x[L] = A^L x0 + sum_i A^(L-1-i) B u[i], summed directly: no FFT rounding is carried to the next block
            n = x0.size
            drive = self.state_markov[:, self.size - L:, :].reshape(n, -1) @ np.ascontiguousarray(U.T).reshape(-1)
            x_next = self.A @ (self.powers[L - 1] @ x0) + drive
            return Y, x_next


class HeldFilter:
    """A delay-free proper transfer function on step ``h`` for a held (ZOH) input, run chunk after chunk.

    Exact at the samples (the balanced realisation discretised by one matrix
    exponential, run by :class:`PowerPropagator`); the state is carried from
    one call of :meth:`run` to the next, so a long input can be fed in pieces.

    Parameters
    ----------
    tf : TransferFunction
        Delay-free, proper.
    h : float
        Step [s].
    size : int, optional
        Longest block of the propagator (default: the first input's length; at most :data:`BLOCK`).
    """

    def __init__(self, tf: TransferFunction, h: float, size: int | None = None) -> None:
        A, B, C, D = state_space(tf)
        self.d = D
        self.n = A.shape[0]
        self.x = np.zeros(self.n)
        self.size = size
        if self.n:
            self.Phi, self.Gam = _zoh(A, B, h)
            self.C = C

    def reset(self) -> None:
        """Back to rest (zero state)."""
        self.x = np.zeros(self.n)

    def run(self, u: np.ndarray) -> np.ndarray:
        """The outputs at the samples of the held input ``u``, continuing from the previous call."""
        if self.n == 0:
            return self.d * u
        if not hasattr(self, "prop"):  # blocks as long as the first chunk (or ``size``), at most BLOCK
            self.size = block_length(self.n, max(1, self.size or u.size))
            self.prop = PowerPropagator(self.Phi, self.Gam, self.size, self.C)
        y = np.empty(u.size)
        x = self.x
        for k in range(0, u.size, self.size):
            Y, x = self.prop.block(x, u[None, k: k + self.size])
            y[k: k + self.size] = Y[0]
        self.x = x
        return y + self.d * u if self.d else y


def _powers(A: np.ndarray, size: int) -> np.ndarray:
    """``A^j`` for ``j = 0 .. size - 1``, by doubling (``log2(size)`` batched products)."""
    n = A.shape[0]
    P = np.empty((size, n, n))
    P[0] = np.eye(n)
    filled = 1
    while filled < size:
        take = min(filled, size - filled)
        P[filled: filled + take] = P[:take] @ (P[filled - 1] @ A)  # A^j A^filled
        filled += take
    return P


def propagate(Phi: np.ndarray, inputs: list[tuple[np.ndarray, np.ndarray]], c: np.ndarray) -> np.ndarray:
    """Outputs ``y[k] = c x[k]`` of ``x[k+1] = Phi x[k] + sum_j g_j u_j[k]``, ``x[0] = 0``.

    ``c`` is one output row or a 2-D array of rows (then one output per row).
    Run by :class:`PowerPropagator` in blocks of up to :data:`BLOCK` steps:
    unlike a high-order transfer function (whose coefficients lose the poles
    when a small step clusters them near ``z = 1``) or a modal basis (which
    loses accuracy near repeated poles; a mode-by-mode run measured no faster
    on the seed 000 benchmark, and 40x less accurate) this is accurate to rounding.
    """
    rows = np.atleast_2d(np.asarray(c, dtype=float))
    n = Phi.shape[0]
    N = inputs[0][1].size
    if n == 0 or N == 0:
        return np.zeros((rows.shape[0], N)) if np.ndim(c) == 2 else np.zeros(N)
    G = np.column_stack([g for g, _ in inputs])
    U = np.vstack([u for _, u in inputs])
    size = block_length(n, N)
    prop = PowerPropagator(Phi, G, size, rows)
    y = np.empty((rows.shape[0], N))
    x = np.zeros(n)
    for k in range(0, N, size):
        y[:, k: k + size], x = prop.block(x, U[:, k: k + size])
    return y if np.ndim(c) == 2 else y[0]

