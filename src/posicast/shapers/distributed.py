"""Distributed-delay shapers (seed 000 DZV, seed 001 DeZV/DtZV/DcZV/DtaZV) and the IIR notch.

All of them place the dominant zero exactly on the mode's pole; the zero is
checked numerically in the test suite.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from .. import _validate as v
from ..core.transfer import TransferFunction
from ..modes import Mode
from .base import DECAY_MAX, DistributedPart, Kernel, check_decay, check_mode

__all__ = ["dzv_parameters", "distributed_zv_parameters", "notch_continuous"]


def dzv_parameters(mode: Mode) -> tuple[float, float]:
    """``(B, theta)`` of the DZV shaper ``S = B + (1 - B) (1 - e^{-s theta}) / (s theta)``.

    Seed 000 eq. 9: ``theta`` is the smallest positive root of
    ``Omega e^{-beta theta} + beta sin(Omega theta) - Omega cos(Omega theta) = 0``,
    which lies in ``(pi / Omega, 2 pi / Omega]``.

    **Seed 000 eq. 10 is misprinted.**  It reads
    ``B = sin(Omega theta) / (sin(Omega theta) - theta Omega e^{beta theta})``, which
    leaves ``|S(p)|`` of order 1-10 (e.g. 8.5 at some modes; B = 0.082 instead of
    0.274 at the experiment's mode omega = 8.98, zeta = 0.14).  Solving
    ``S(p) = 0`` for B gives ``B = (1 - e^{-p theta}) / (1 - e^{-p theta} - p theta)``,
    real exactly when eq. 9 holds, and its real form is
    ``B = sin(Omega theta) / (sin(Omega theta) - theta Omega e^{-beta theta})``
    (the exponent's sign is flipped in print).  This corrected form is used; the
    test suite checks ``|S(p)| <= 1e-10`` on random modes.  For ``zeta = 0`` the root
    is the double root ``theta = 2 pi / Omega`` and ``B = 0`` (the pure uniform kernel).

    Note: seed 000 eq. 8 writes the zero spectrum with ``1 / tau``; it must be
    ``1 / theta`` (the DZV has no ``tau``): ``s_k = (W_k(a e^a) - a) / theta`` with
    ``a = (1 - B) / B``.
    """
    B, _, theta = _dzv(mode)
    return B, theta


def _dzv(mode: Mode) -> tuple[float, float, float]:
    """``(B, 1 - B, theta)``, with ``1 - B`` computed without cancellation (it is tiny as zeta -> 1)."""
    check_mode(mode)
    check_decay(mode, 1.0, "a DZV shaper")  # theta <= one damped period
    W = mode.damped_omega
    b = mode.decay
    if b == 0.0:
        return 0.0, 1.0, 2.0 * math.pi / W

    def f(theta: float) -> float:
        return W * math.exp(-b * theta) + b * math.sin(W * theta) - W * math.cos(W * theta)

    lo = math.pi / W
    hi = 2.0 * math.pi / W
    # f(lo) = W (e^{-b pi / W} + 1) > 0 and f(hi) = W (e^{-2 pi b / W} - 1) < 0.
    theta = brentq(f, lo, hi, xtol=1e-15 * hi, rtol=4 * np.finfo(float).eps, maxiter=200)
    s = math.sin(W * theta)
    x = theta * W * math.exp(-b * theta)
    B = s / (s - x)  # seed 000 eq. 10, sign corrected
    return B, -x / (s - x), theta


def distributed_zv_parameters(mode: Mode, kernel: Kernel) -> tuple[float, float]:
    """``(A, tau)`` of ``S = A + (1 - A) G(s) e^{-tau s}`` (seed 001 eq. 12) with ``S(p) = 0``.

    With ``G(p) = |G| e^{j phi}`` at the pole ``p = -beta + j Omega``:
    the phase condition gives ``tau = ((phi + pi) mod 2 pi) / Omega`` (the shortest
    nonnegative delay) and the magnitude condition
    ``A = |G| e^{beta tau} / (1 + |G| e^{beta tau})``.
    """
    A, _, tau = _zv_parameters(mode, kernel)
    return A, tau


def _zv_parameters(mode: Mode, kernel: Kernel) -> tuple[float, float, float]:
    """``(A, 1 - A, tau)``; ``1 - A = 1 / (1 + m)`` directly (it is tiny as zeta -> 1)."""
    check_mode(mode)
    v.instance_of(kernel, Kernel, "kernel", "a posicast Kernel")
    if mode.decay * kernel.T > DECAY_MAX:
        T_max = DECAY_MAX / mode.decay
        raise ValueError(f"T={kernel.T:g} s is too long for a mode with decay rate zeta*omega = {mode.decay:g} 1/s: "
                         f"the kernel would span a decay of e^-{mode.decay * kernel.T:.4g}, beyond double precision; "
                         f"T must be <= {T_max:.6g} s")
    p = mode.pole
    g = complex(kernel.transfer()(p))
    if not (math.isfinite(g.real) and math.isfinite(g.imag)):  # pragma: no cover - guarded by the decay check
        raise ValueError(f"the kernel's transfer function cannot be evaluated at the pole {p:.6g} (T={kernel.T:g})")
    phi = math.atan2(g.imag, g.real)
    tau = math.fmod(phi + math.pi, 2.0 * math.pi)
    if tau < 0:
        tau += 2.0 * math.pi
    tau /= mode.damped_omega
    check_decay(mode, (tau + kernel.T) / mode.damped_period,
                f"a distributed ZV shaper with a {kernel.shape} kernel of T={kernel.T:g} s")
    m = abs(g) * math.exp(mode.decay * tau)  # <= |g| e^600: finite after check_decay
    return m / (1.0 + m), 1.0 / (1.0 + m), tau


def distributed_zv_part(mode: Mode, shape: str, T: float) -> tuple[float, DistributedPart, float]:
    """``(A, part, tau)`` for one of the four kernels of seed 001."""
    check_mode(mode)
    kernel = Kernel(shape, v.positive(v.finite_real(T, "T"), "T"))
    A, w, tau = _zv_parameters(mode, kernel)
    return A, DistributedPart(w, tau, (kernel,)), tau


def notch_continuous(mode: Mode) -> TransferFunction:
    """The IIR part of seed 001 eq. 13: ``S5 - 1``.

    ``S5 = (s^2 + 2 zeta omega s + omega^2) / (s^2 + 2 omega s + omega^2)``
    ``= 1 + 2 (zeta - 1) omega s / (s + omega)^2``: a unit impulse plus this
    strictly proper remainder (impulse response ``2 (zeta - 1) omega (1 - omega t) e^{-omega t}``).
    """
    check_mode(mode)
    w, z = mode.omega, mode.zeta
    return TransferFunction.from_poly([2.0 * (z - 1.0) * w, 0.0], [1.0, 2.0 * w, w * w])
