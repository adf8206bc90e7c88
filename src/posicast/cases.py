"""The seeds' case-study plants, ready to simulate (issue #4 section 3).

Every case is a :class:`Case`: the actuator-side plant ``G`` (inside the loop), the
flexible load ``F`` (outside the loop, ``y = F z``), the controller ``C`` (or
None), the flexible :class:`~posicast.Mode` a shaper should cancel, the sample
rate the seed used (or None) and the source.  ``ALL`` maps names to cases, and
:meth:`Case.loop` builds a posicast loop around a shaper.

=========================  ====================================================
name                       source
=========================  ====================================================
``simulation_example``     seed 000 section V, eq. 25-27
``flexible_link``          seed 000 section VI, eq. 28-29 (8.98 rad/s, 0.14, 200 Hz)
``gantry_crane``           seed 001 section 4, eq. 9-11 and Table 1
``two_mass``               seed 003 "Plant, P" (m1 = 10, m2 = 1, c1 = 50, c2 = 0.1, k2 = 10)
``flexible_joint_robot``   seed 003 experiment, P1 (u -> x1) and P2 (x1 -> x2)
``sampled_28hz``           seed 002 section 3.2, eq. 16 (28 Hz, zeta 0.05, 400 Hz)
=========================  ====================================================

>>> import posicast
>>> case = ALL["simulation_example"]
>>> case.mode
Mode(omega=10.0, zeta=0.03)
>>> loop = case.loop("inverse_shaper", posicast.design("dzv", case.mode))
>>> loop.architecture
'inverse_shaper'
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from . import _validate as v
from .core.transfer import TransferFunction, as_transfer
from .loops import Loop, control_action, feedforward, inverse_shaper
from .modes import Mode

__all__ = [
    "Case",
    "ALL",
    "modes_of",
    "two_mass_plant",
    "two_mass_plants",
    "TWO_MASS_UNCERTAINTY",
    "CRANE_TABLE1",
    "simulation_example",
    "flexible_link",
    "gantry_crane",
    "two_mass",
    "flexible_joint_robot",
    "sampled_28hz",
]

_BUILDERS = {"feedforward": feedforward, "control_action": control_action, "inverse_shaper": inverse_shaper}


@dataclass(frozen=True, eq=False)
class Case:
    """A case-study plant from a seed.

    Attributes
    ----------
    name : str
        Key in :data:`ALL`.
    source : str
        Seed, section and equations.
    G : TransferFunction
        Actuator-side plant, inside the loop (``z = G u``).
    F : TransferFunction
        Flexible load outside the loop (``y = F z``).
    C : TransferFunction or None
        The seed's feedback controller, or None (open-loop input shaping).
    mode : Mode
        The flexible mode the shaper should cancel.
    sample_rate : float or None
        The seed's controller sample rate in Hz, or None (continuous).
    notes : str
        Assumptions and misprints.
    extras : Mapping
        Further blocks or numbers the seed gives (e.g. other controllers).
    """

    name: str
    source: str
    G: TransferFunction
    F: TransferFunction
    C: TransferFunction | None
    mode: Mode
    sample_rate: float | None = None
    notes: str = ""
    extras: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("name", "source", "notes"):
            if not isinstance(getattr(self, name), str):
                raise TypeError(f"{name} must be a str, got {type(getattr(self, name)).__name__}")
        for name in ("G", "F"):
            if not isinstance(getattr(self, name), TransferFunction):
                raise TypeError(f"{name} must be a posicast TransferFunction (posicast.as_transfer), got "
                                f"{type(getattr(self, name)).__name__}")
        if self.C is not None and not isinstance(self.C, TransferFunction):
            raise TypeError(f"C must be a posicast TransferFunction or None, got {type(self.C).__name__}")
        if not isinstance(self.mode, Mode):
            raise TypeError(f"mode must be a posicast Mode, got {type(self.mode).__name__}")
        if self.sample_rate is not None:
            object.__setattr__(self, "sample_rate", v.positive(self.sample_rate, "sample_rate"))
        if not isinstance(self.extras, Mapping):
            raise TypeError(f"extras must be a mapping, got {type(self.extras).__name__}")
        object.__setattr__(self, "extras", MappingProxyType(dict(self.extras)))

    def loop(self, architecture: str, S: Any = None, C: Any = None) -> Loop:
        """The case's loop with shaper ``S`` in ``architecture``.

        Parameters
        ----------
        architecture : {"feedforward", "control_action", "inverse_shaper"}
        S : Shaper, optional
            The shaper (None: the shaper-free reference loop).
        C : optional
            A controller replacing the case's ``C`` (required when the case has none).

        Returns
        -------
        Loop
        """
        return loop(self, architecture, S, C)

    def __repr__(self) -> str:
        fs = "continuous" if self.sample_rate is None else f"{self.sample_rate:g} Hz"
        return f"Case({self.name!r}, mode={self.mode}, {fs}; {self.source})"


def loop(case: Case | str, architecture: str, S: Any = None, C: Any = None) -> Loop:
    """``posicast.feedforward/control_action/inverse_shaper(G=case.G, F=case.F, C=..., S=S)``.

    Parameters
    ----------
    case : Case or str
        A case or its name in :data:`ALL`.
    architecture : {"feedforward", "control_action", "inverse_shaper"}
    S : Shaper, optional
    C : optional
        Controller overriding ``case.C``.

    Raises
    ------
    ValueError
        Unknown case name or architecture, or no controller at all.

    Examples
    --------
    >>> import posicast
    >>> L = loop("flexible_link", "feedforward", posicast.design("zv", ALL["flexible_link"].mode))
    >>> L.is_stable()
    True
    """
    if isinstance(case, str):
        if case not in ALL:
            raise ValueError(f"case must be one of {', '.join(ALL)}; got {case!r}")
        case = ALL[case]
    if not isinstance(case, Case):
        raise TypeError(f"case must be a posicast.cases.Case or a name, got {type(case).__name__}")
    if architecture not in _BUILDERS:  # seed 003's model_matching needs its inner loop: posicast.qft.model_matching
        raise ValueError(f"architecture must be one of {tuple(_BUILDERS)}, got {architecture!r}")
    ctrl = case.C if C is None else C
    if ctrl is None:
        raise ValueError(f"case {case.name!r} has no controller (open-loop shaping): pass C=")
    return _BUILDERS[architecture](G=case.G, F=case.F, C=ctrl, S=S)


def modes_of(system: Any, name: str = "system") -> tuple[Mode, ...]:
    """The underdamped modes of a delay-free rational system, least damped first.

    Each complex pole pair ``-zeta omega +/- j omega sqrt(1 - zeta^2)`` of the
    denominator gives ``Mode(omega = |p|, zeta = -Re p / |p|)``.

    Examples
    --------
    >>> modes_of(([1.0, 0.0], [1.0, 0.6, 100.0]))        # seed 000 eq. 26
    (Mode(omega=10.0, zeta=0.03),)
    """
    tf = as_transfer(system, name)
    with np.errstate(over="raise", invalid="raise"):
        try:
            r = np.roots(tf.to_scipy().den)
        except FloatingPointError:
            raise ValueError(f"{name}: its denominator's roots overflow; rescale the coefficients") from None
    pairs = r[(r.imag > 1e-12 * np.maximum(1.0, np.abs(r))) & (r.real <= 0)]  # stable complex pairs
    modes = [Mode(float(abs(p)), float(-p.real / abs(p))) for p in pairs]
    return tuple(sorted(modes, key=lambda m: (m.zeta, m.omega)))


def _tf(num: Any, den: Any) -> TransferFunction:
    return TransferFunction.from_poly(num, den)


# ---------------------------------------------------------------------- seed 000
def simulation_example() -> Case:
    """Seed 000 section V (Vyhlidal, Kucera, Hromcik: inverse shapers in the loop), eq. 25-27.

    ``G = 1 / (s^2 + s)`` (25), ``F = s / (s^2 + 0.6 s + 100)`` (26),
    ``C = (10 s + 10) / (0.01 s + 1)`` (27).  F's poles ``r_{1,2} = -0.3 +/- 9.995 j``
    (the paper prints ``9.995``; exactly ``sqrt(99.91) = 9.99550``): mode
    ``omega = 10``, ``zeta = 0.03``.  Fig. 7-8: set-point step at ``t = 5``,
    disturbance step at ``t = 20``.
    """
    F = _tf([1.0, 0.0], [1.0, 0.6, 100.0])
    return Case(
        "simulation_example",
        "seed 000 section V, eq. 25-27 (Fig. 6-8)",
        G=_tf([1.0], [1.0, 1.0, 0.0]),
        F=F,
        C=_tf([10.0, 10.0], [0.01, 1.0]),
        mode=modes_of(F)[0],
        sample_rate=None,
        notes="Fig. 7-8: set-point step at t = 5 s, disturbance d step at t = 20 s.",
        extras={"setpoint_time": 5.0, "disturbance_time": 20.0},
    )


def flexible_link() -> Case:
    """Seed 000 section VI: Quanser flexible link, eq. 28-29, sampled at 200 Hz.

    ``G = 15490 / (s^2 + 19 s)`` (28), ``C = 0.1 (s + 30) / (s + 130)`` (29); the
    beam's first bending mode ``omega = 8.98 rad/s``, ``zeta = 0.14``; the controller
    and shapers ran at 200 Hz.  The paper gives no transfer function for the beam:
    ``F = omega^2 / (s^2 + 2 zeta omega s + omega^2)`` (unit static gain: the tip follows
    the table) is an assumption of this package.  The paper's inverse DZV has
    ``B = 0.26``, ``theta = 0.57``; the exact DZV of this mode (seed 000 eq. 9-10, eq. 10
    sign-corrected) has ``B = 0.274``, ``theta = 0.571``.
    """
    m = Mode(8.98, 0.14)
    w, z = m.omega, m.zeta
    return Case(
        "flexible_link",
        "seed 000 section VI, eq. 28-29 (mode 8.98 rad/s, zeta 0.14, 200 Hz)",
        G=_tf([15490.0], [1.0, 19.0, 0.0]),
        F=_tf([w * w], [1.0, 2.0 * z * w, w * w]),
        C=_tf([0.1, 3.0], [1.0, 130.0]),
        mode=m,
        sample_rate=200.0,
        notes=(
            "F is assumed (second order with the printed mode, unit static gain); the paper prints "
            "B = 0.26, theta = 0.57 for its DZV, the exact design gives B = 0.274, theta = 0.571."
        ),
        extras={"dzv_printed": {"B": 0.26, "theta": 0.57}},
    )


# ---------------------------------------------------------------------- seed 001
# Seed 001 Table 1: tau, A of the distributed shapers (T = pi / omega) and PD gains
# (Kp, Kd) in the direct (feedforward/control-action) and inverse structures.
CRANE_TABLE1: Mapping[str, Mapping[str, float | None]] = MappingProxyType({
    "dezv": MappingProxyType({"tau": 0.286, "A": 0.395, "Kp_d": 8.841, "Kd_d": 3.142, "Kp_i": 23.3, "Kd_i": 0.465}),
    "dtzv": MappingProxyType({"tau": 0.287, "A": 0.454, "Kp_d": 10.364, "Kd_d": 3.01, "Kp_i": 30.26, "Kd_i": 0.697}),
    "dczv": MappingProxyType({"tau": 0.287, "A": 0.465, "Kp_d": 10.542, "Kd_d": 2.93, "Kp_i": 32.42, "Kd_i": 1.15}),
    "dtazv": MappingProxyType({"tau": 0.39, "A": 0.436, "Kp_d": 9.656, "Kd_d": 2.93, "Kp_i": 26.13, "Kd_i": 1.16}),
    "notch": MappingProxyType({"tau": None, "A": None, "Kp_d": 7.4, "Kd_d": 1.51, "Kp_i": 38.53, "Kd_i": 2.56}),
    "none_direct": MappingProxyType({"tau": None, "A": None, "Kp_d": 20.55, "Kd_d": 0.77, "Kp_i": None, "Kd_i": None}),
    "none_inverse": MappingProxyType({"tau": None, "A": None, "Kp_d": None, "Kd_d": None, "Kp_i": 68.86, "Kd_i": 2.16}),
})


def gantry_crane() -> Case:
    """Seed 001 section 4: hoist of a small gantry crane and the load sway, eq. 9-11.

    Actuator (closed velocity loop of the hoist drive), eq. 10 **with its typo fixed**:
    the denominator reads ``s^2 + 2 xi_j omega_i s + omega_j^2`` in print; it must be
    ``xi_j omega_j`` (``omega_i`` has only two values, the product runs over four)::

        G(s) = K (s + a) prod_{i=1}^{2} (s^2 + 2 xi_i omega_i s + omega_i^2)
               / (s prod_{j=1}^{4} (s^2 + 2 xi_j omega_j s + omega_j^2))

    with ``K = -13775``, ``a = -149.2``, ``omega_i = {154, 201}``,
    ``xi_i = {0.55, 0.059}``, ``omega_j = {38.1, 98, 155, 163}``,
    ``xi_j = {0.92, 0.57, 0.3, 0.07}``.  Load sway, eq. 11:
    ``F = -3.06 s^2 / (s^2 + 0.087 s + 30.1)``: ``omega = sqrt(30.1) = 5.486``,
    ``zeta = 0.00793`` (printed ``5.49`` and ``0.008``).  Controller, eq. 9: PD
    ``C = Kp + Kd s``; here the shaper-free direct design of Table 1
    (``Kp = 20.55``, ``Kd = 0.77``); the other rows are in :data:`CRANE_TABLE1`.
    The PD is improper, but ``C G`` is strictly proper (G has relative degree 4).
    """
    K, a = -13775.0, -149.2
    num = np.array([K, K * a])
    for w, xi in zip((154.0, 201.0), (0.55, 0.059)):
        num = np.polymul(num, [1.0, 2.0 * xi * w, w * w])
    den = np.array([1.0, 0.0])
    for w, xi in zip((38.1, 98.0, 155.0, 163.0), (0.92, 0.57, 0.3, 0.07)):
        den = np.polymul(den, [1.0, 2.0 * xi * w, w * w])  # seed 001 eq. 10: xi_j omega_j (printed xi_j omega_i)
    F = _tf([-3.06, 0.0, 0.0], [1.0, 0.087, 30.1])
    row = CRANE_TABLE1["none_direct"]
    return Case(
        "gantry_crane",
        "seed 001 section 4, eq. 9-11 and Table 1",
        G=_tf(num, den),
        F=F,
        C=_tf([row["Kd_d"], row["Kp_d"]], [1.0]),
        mode=modes_of(F)[0],
        sample_rate=None,
        notes=(
            "eq. 10 typo xi_j omega_i -> xi_j omega_j fixed; printed mode 5.49 rad/s, zeta 0.008 "
            "(exactly sqrt(30.1) = 5.4863 and 0.00793); the printed T = pi / omega = 0.574 s is "
            "pi / 5.49 = 0.5722 s.  C is the S = 1 direct PD of Table 1 (improper; C G is proper)."
        ),
        extras={"table1": CRANE_TABLE1, "printed_mode": Mode(5.49, 0.008)},
    )


# ---------------------------------------------------------------------- seed 003
# Seed 003 "Inner-loop controllers": c1, c2, k2 with 50 % uncertainty, 3 values each.
TWO_MASS_UNCERTAINTY: Mapping[str, tuple[float, float, float]] = MappingProxyType(
    {"c1": (25.0, 50.0, 75.0), "c2": (0.05, 0.1, 0.15), "k2": (5.0, 10.0, 15.0)}
)


def two_mass_plant(
    c1: float = 50.0, c2: float = 0.1, k2: float = 10.0, m1: float = 10.0, m2: float = 1.0
) -> TransferFunction:
    """Seed 003's two-mass rigid-flexible plant ``P = Y / U`` (force on m1 to position of m2).

    ``P(s) = (c2 s + k2) / (m1 m2 s^4 + (m1 c2 + c1 m2 + c2 m2) s^3
    + (m1 k2 + c1 c2 + k2 m2) s^2 + c1 k2 s)``.

    Examples
    --------
    >>> modes_of(two_mass_plant())[0]  # doctest: +ELLIPSIS
    Mode(omega=3.2073511..., zeta=0.0389019...)
    """
    for nm, val in (("c1", c1), ("c2", c2), ("k2", k2), ("m1", m1), ("m2", m2)):
        if isinstance(val, bool) or not isinstance(val, (int, float, np.integer, np.floating)):
            raise TypeError(f"{nm} must be a real number, got {type(val).__name__}")
        if not (math.isfinite(val) and val > 0):
            raise ValueError(f"{nm} must be finite and > 0, got {val!r}")
    den = [m1 * m2, m1 * c2 + c1 * m2 + c2 * m2, m1 * k2 + c1 * c2 + k2 * m2, c1 * k2, 0.0]
    return _tf([c2, k2], den)


def two_mass_plants() -> tuple[TransferFunction, ...]:
    """The 27 plants of seed 003's uncertainty set (c1, c2, k2 each at -50 %, 0, +50 %).

    Ordered as ``itertools.product(c1, c2, k2)``, so the 14th (index 13) is the
    nominal plant, as in the paper.
    """
    u = TWO_MASS_UNCERTAINTY
    return tuple(two_mass_plant(c1, c2, k2) for c1, c2, k2 in itertools.product(u["c1"], u["c2"], u["k2"]))


def two_mass() -> Case:
    """Seed 003 (Chatlatanagulchai et al., closed-loop shaping with inner-loop model matching), plant P.

    ``m1 = 10``, ``m2 = 1``, ``c1 = 50``, ``c2 = 0.1``, ``k2 = 10``: flexible mode
    ``omega_n = 3.2074 rad/s``, ``zeta = 0.0389`` (its ZV shaper is 0.9802 s long).
    The flexible mode sits inside ``P``, so here ``G = P`` and ``F = 1`` (the output
    ``y = x2`` is fed back).  ``C = 0.396 (1 + 24 s) / s`` is the PI the paper uses
    without the inner loop (with a ZVD^2 shaper); with the inner loop it uses
    ``C = 1.742 (1 + 0.19 s) / s`` (eq. 5) around ``F_m`` and the QFT controller
    ``G_qft = 87.367 (s + 17.24)(s^2 + 0.865 s + 17.85)`` (in ``extras``).  The 27
    uncertain plants: :func:`two_mass_plants`.
    """
    P = two_mass_plant()
    wn, zn = 3.2074, 0.0389
    g_qft = 87.367 * np.polymul([1.0, 17.24], [1.0, 0.865, 17.85])
    return Case(
        "two_mass",
        "seed 003 section 'Plant, P' and simulation (m1 = 10, m2 = 1, c1 = 50, c2 = 0.1, k2 = 10)",
        G=P,
        F=TransferFunction.constant(1.0),
        C=_tf([0.396 * 24.0, 0.396], [1.0, 0.0]),
        mode=modes_of(P)[0],
        sample_rate=None,
        notes="27 uncertain plants: two_mass_plants() (c1, c2, k2 at -50 %, 0, +50 %; index 13 nominal).",
        extras={
            "F_m": _tf([wn * wn], [1.0, 2.0 * zn * wn, wn * wn]),  # eq. 1
            "G_qft": _tf(g_qft, [1.0]),
            "C_inner": _tf([1.742 * 0.19, 1.742], [1.0, 0.0]),  # eq. 5
            "plants": two_mass_plants(),
        },
    )


def flexible_joint_robot() -> Case:
    """Seed 003 experiment: flexible-joint robot, ``P1 = X1 / U`` and ``P2 = X2 / X1``.

    ``P1 = (140.5 s^2 + 1.107e4 s + 1403) / (s^4 + 15.1 s^3 + 852.8 s^2 + 1068 s)``
    (motor shaft, fed back: ``G``), ``P2 = (41.09 s + 3173) / (s^2 + 16.42 s + 3161)``
    (link, outside the loop: ``F``).  Modes: ``28.90 rad/s, 0.239`` (P1) and
    ``56.22 rad/s, 0.146`` (P2, the link mode the shaper targets).  The experiment
    closes an inner loop with ``G(s) = 3`` (used as ``C`` here) and an outer PI
    ``C = 0.015 (1 + 1 / (0.01 s))`` around ``F_m = 25 / (s^2 + 7 s + 25)`` (in ``extras``).
    """
    P1 = _tf([140.5, 1.107e4, 1403.0], [1.0, 15.1, 852.8, 1068.0, 0.0])
    P2 = _tf([41.09, 3173.0], [1.0, 16.42, 3161.0])
    return Case(
        "flexible_joint_robot",
        "seed 003 experiment, P1 and P2",
        G=P1,
        F=P2,
        C=TransferFunction.constant(3.0),
        mode=modes_of(P2)[0],
        sample_rate=None,
        notes="C is the inner-loop gain G(s) = 3 on the motor position x1; the outer PI is in extras.",
        extras={
            "P1_mode": modes_of(P1)[0],
            "F_m": _tf([25.0], [1.0, 7.0, 25.0]),
            "C_outer": _tf([0.015, 1.5], [1.0, 0.0]),  # 0.015 (1 + 1 / (0.01 s))
        },
    )


# ---------------------------------------------------------------------- seed 002
def sampled_28hz() -> Case:
    """Seed 002 section 3.2: a 28 Hz, ``zeta = 0.05`` second-order system sampled at 400 Hz.

    ``F(s) = omega_n^2 / (s^2 + 2 zeta omega_n s + omega_n^2)`` (eq. 16) with
    ``omega_n = 2 pi 28``.  Open-loop input shaping: ``G = 1``, no controller.  The
    discrete ZV of eq. 11-12 (zeros of the shaper on the sampled poles, eq. 6) places
    its second impulse at ``2 T_vz = pi / Omega``, the continuous ZV's delay.
    """
    m = Mode.from_hz(28.0, 0.05)
    w, z = m.omega, m.zeta
    return Case(
        "sampled_28hz",
        "seed 002 section 3.2, eq. 16 (28 Hz, zeta 0.05, sampled at 400 Hz)",
        G=TransferFunction.constant(1.0),
        F=_tf([w * w], [1.0, 2.0 * z * w, w * w]),
        C=None,
        mode=m,
        sample_rate=400.0,
        notes="Open-loop shaping (no controller): pass C= to loop() to close a loop.",
    )


ALL: Mapping[str, Case] = MappingProxyType(
    {
        c.name: c
        for c in (
            simulation_example(),
            flexible_link(),
            gantry_crane(),
            two_mass(),
            flexible_joint_robot(),
            sampled_28hz(),
        )
    }
)
