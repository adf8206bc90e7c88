"""The system or loop of ``posicast stability`` and ``posicast simulate`` (issue #20), from their options.

Text syntax of ``--num``, ``--den``, ``--controller-num``, ``--controller-den``: a
polynomial in descending powers (``"1 0.2 4"`` is ``s^2 + 0.2 s + 4``), or a
quasi-polynomial as terms joined by ``;``, each term a polynomial with its delay after
``@``: ``"1 0.2 4; 2 @0.5"`` is ``s^2 + 0.2 s + 4 + 2 e^{-0.5 s}`` (``posicast tune --num/--den`` reads the same).  ``--delay`` multiplies the plant by
``e^{-s delay}``.  A controller (``--kp/--ki/--kd [--derivative-filter]`` or
``--controller-num/--controller-den``) makes a loop of ``--architecture``; without one
the plant (times the shaper, if one is given) is the system.
"""

from __future__ import annotations

import argparse
from typing import NamedTuple

import numpy as np

from .. import _validate as v
from ..cases import ALL as CASES
from ..core.quasipoly import QuasiPolynomial
from ..core.transfer import TransferFunction, delay
from ..loops import Loop
from ..modes import Mode
from ..shapers import registry
from ..shapers.base import Shaper

__all__ = ["Plant", "System", "plant_of", "quasi_polynomial", "system_of"]


class System(NamedTuple):
    """What the options describe: a loop, or a transfer function when no controller was given."""

    loop: Loop | None
    transfer: TransferFunction | None
    S: Shaper | None
    description: str

    @property
    def target(self) -> Loop | TransferFunction:
        """The object whose verbs (stability, poles, ...) the subcommand calls."""
        return self.loop if self.loop is not None else self.transfer  # type: ignore[return-value]


def quasi_polynomial(text: str, name: str) -> QuasiPolynomial:
    """``text`` in the syntax of the module docstring as a quasi-polynomial (ValueError naming ``name``)."""
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"{name} must not be empty")
    total: QuasiPolynomial | None = None
    for term in text.split(";"):
        coeffs, at, tau_text = term.partition("@")
        try:
            vals = [float(x) for x in coeffs.replace(",", " ").split()]
            tau = float(tau_text) if at else 0.0
        except ValueError:
            raise ValueError(f"{name} must be numbers separated by spaces, with an optional '@delay' per "
                             f"';'-separated term, got {text!r}") from None
        if not vals:
            raise ValueError(f"{name}: a term without coefficients in {text!r}")
        v.strict_real_array(vals, name)
        v.nonnegative(tau, f"{name} delay", " [s]")
        q = QuasiPolynomial.from_poly(vals, tau)
        total = q if total is None else total + q
    assert total is not None
    return total


def _transfer(num: QuasiPolynomial, den: QuasiPolynomial, name: str) -> TransferFunction:
    try:
        return TransferFunction(num, den)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: {exc}") from None


def _controller(args: argparse.Namespace) -> TransferFunction | None:
    gains = {g: getattr(args, g) for g in ("kp", "ki", "kd")}
    given = {g: x for g, x in gains.items() if x is not None}
    if args.controller_num is not None or args.controller_den is not None:
        if given or args.derivative_filter is not None:
            raise ValueError("give the controller as --kp/--ki/--kd or as --controller-num/--controller-den, "
                             "not both")
        return _polynomial_controller(args)
    if not given:
        if args.derivative_filter is not None:
            raise ValueError("--derivative-filter needs --kd")
        return None
    return _pid_controller(args, gains)


def _polynomial_controller(args: argparse.Namespace) -> TransferFunction:
    if args.controller_num is None:
        raise ValueError("--controller-num is required with --controller-den")
    num = quasi_polynomial(args.controller_num, "--controller-num")
    den = quasi_polynomial(args.controller_den or "1", "--controller-den")
    return _transfer(num, den, "--controller-num/--controller-den")


def _pid_controller(args: argparse.Namespace, gains: dict[str, float | None]) -> TransferFunction:
    """``kp + ki / s + kd s / (tf s + 1)`` from the gain options."""
    # any finite gain: the spectral tools scale the characteristic, and refuse what floats cannot hold or
    # what would take too long up front, with the range or the estimate (kd = 4.6e16 on the crane: 0.1 s)
    kp, ki, kd = (v.finite_real(gains[g] or 0.0, f"--{g}") for g in ("kp", "ki", "kd"))
    tf = 0.0 if args.derivative_filter is None else v.nonnegative(args.derivative_filter, "--derivative-filter",
                                                                    " [s]")
    if tf and not kd:
        raise ValueError("--derivative-filter needs --kd")
    # C = kp + ki / s + kd s / (tf s + 1) over the common denominator s^i (tf s + 1)
    filt = np.array([tf, 1.0]) if kd and tf else np.array([1.0])
    num = np.polymul([kp], filt)
    den = filt
    if kd:
        num = np.polyadd(num, [kd, 0.0])
    if ki:
        num = np.polyadd(np.polymul(num, [1.0, 0.0]), np.polymul([ki], filt))
        den = np.polymul(den, [1.0, 0.0])
    return TransferFunction.from_poly(np.trim_zeros(num, "f") if np.any(num) else [0.0], den)


class Plant(NamedTuple):
    """The plant the options describe: ``G`` (with ``--delay``), the load ``F`` and the mode (a case's, or
    ``--omega/--zeta``), and a description."""

    G: TransferFunction
    F: TransferFunction | None
    mode: Mode | None
    description: str


def plant_of(args: argparse.Namespace) -> Plant:
    """``--case`` or ``--num/--den`` with ``--delay``; ``--omega/--zeta`` override the case's mode (``tune``,
    ``stability`` and ``simulate`` read their plant here)."""
    v.nonnegative(args.delay, "--delay", " [s]")
    if (args.omega is None) != (args.zeta is None):
        raise ValueError("--omega and --zeta go together")
    F = None
    mode = None
    if args.case is not None:
        v.choice(args.case, "--case", CASES)
        if args.den is not None:
            raise ValueError("--den goes with --num, not with --case")
        case = CASES[args.case]
        G, F, mode = case.G, case.F, case.mode
        what = f"case {args.case}"
    else:
        if args.den is None:
            raise ValueError("--den is required with --num")
        G = _transfer(quasi_polynomial(args.num, "--num"), quasi_polynomial(args.den, "--den"), "--num/--den")
        what = "G = (" + args.num + ") / (" + args.den + ")"
    if args.delay:
        G = G * delay(args.delay)
        what += f" e^(-{args.delay:g} s)"
    if args.omega is not None:
        mode = Mode(args.omega, args.zeta)
    return Plant(G, F, mode, what)


def system_of(args: argparse.Namespace) -> System:
    """The loop (or plant) the options describe; every option is checked before any design work."""
    G, F, mode, what = plant_of(args)
    C = _controller(args)
    S = None
    if args.shaper is not None:
        if mode is None:
            raise ValueError("--shaper needs the mode: --omega and --zeta (or --case)")
        S = registry.design(args.shaper.lower(), mode)
        what += f", shaper {S.name}"
    if C is None:
        if args.architecture is not None:
            raise ValueError("--architecture needs a controller (--kp/--ki/--kd or --controller-num)")
        return System(None, G * S.transfer if S is not None else G, S, what)
    arch = args.architecture or "control_action"
    return System(Loop(arch, G=G, C=C, F=F, S=S), None, S, f"{what}, {arch} loop")
