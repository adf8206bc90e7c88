"""Quasi-polynomials from the literature with their published or independently computed roots.

Used by ``tests/test_published_qp.py``.  Every case names its source.  ``printed``
holds numbers as the source prints them (compared to the printed digits);
``reference`` holds roots computed independently of posicast: a closed form
(Lambert W, multiplicity conditions) or a 40-digit mpmath Newton polish
(``mpmath.mp.dps = 40``) of roots seeded by qpmr (Vyhlídal's QPmR in Python,
another tool), whose root count in the region is recorded in ``count``.
Coefficient rows are ascending powers of s, one row per delay (posicast's
``QuasiPolynomial(coeffs, delays)``).

Where the source's own tables could not be consulted, the case says so: the
quasi-polynomial is the published one, the reference numbers are independent
computations, not copies of the paper.
"""

from __future__ import annotations

import math

# --------------------------------------------------------------------------------------------- QPmR
# Vyhlídal & Zítek, "Mapping based algorithm for large-scale computation of quasi-polynomial zeros",
# IEEE Trans. Automatic Control 54(1):171-177, 2009, example h(s) = s + exp(-s) (the first example
# of the QPmR distribution); roots printed to 4 decimals by the MATLAB QPmR reference run
# (qpmr, examples/example01.py, `matlab_roots`), region [-10, 2] x [0, 30].  Closed form: s = W_k(-1).
VZ_EX1 = dict(
    name="vz2009_s_plus_exp",
    source="Vyhlidal & Zitek, IEEE TAC 54(1) 2009, example s + e^{-s}; MATLAB QPmR output, 4 decimals",
    coeffs=[[0.0, 1.0], [1.0, 0.0]],
    delays=[0.0, 1.0],
    region=(-10.0, 2.0, 0.0, 30.0),
    count=5,
    printed=[-0.3181 + 1.3372j, -2.0623 + 7.5886j, -2.6532 + 13.9492j, -3.0202 + 20.2725j, -3.2878 + 26.5805j],
    printed_tol=0.5e-4,
    lambert=dict(a=0.0, b=1.0, tau=1.0, branches=[0, 1, 2, 3, 4]),
)

# QPmR v.2 (T. Vyhlídal, CTU Prague), the example of the MATLAB function's help text:
# Q(s) = (1.5 s^3 + 0.2 s^2 + 20.1) + (s^3 - 2.1 s) e^{-1.3 s} + 3.2 s e^{-3.5 s} + 1.4 e^{-4.3 s},
# region [-10, 5] x [0, 300].  No roots are printed there: qpmr finds 207 roots; the rightmost are
# polished to 40 digits (relative residual < 1e-40) and shown to 16.
QPMR_HELP = dict(
    name="qpmr_v2_help_neutral",
    source="QPmR v.2 MATLAB help example (Vyhlidal); reference: qpmr count + mpmath 40-digit polish",
    coeffs=[[20.1, 0.0, 0.2, 1.5], [0.0, -2.1, 0.0, 1.0], [0.0, 3.2, 0.0, 0.0], [1.4, 0.0, 0.0, 0.0]],
    delays=[0.0, 1.3, 3.5, 4.3],
    region=(-10.0, 5.0, 0.0, 300.0),
    count=207,
    reference=[1.136275985142193515 + 2.2205803031274349776j, -0.21434427930583455484 + 7.2156366674879703369j],
    abscissa=1.136275985142193515,
    stable=False,
)

# The large-scale retarded example of Vyhlídal & Zítek (2009): degree 8, nine delays up to 24.99,
# as transcribed in qpmr (qpmr.quasipoly.examples.vyhlidal2014qpmr_02), region [-4.5, 2.5] x [0, 100].
# qpmr: 401 roots (142 s); all 401 posicast roots agree with a 40-digit polish to 2e-13.
_D2 = [24.99, 23.35, 19.9, 18.52, 13.32, 10.33, 8.52, 4.61, 0.0]
_C2 = [
    [51.7, 0, 0, 0, 0, 0, 0, 0, 0],
    [1.5, -0.1, 0.04, 0.03, 0, 0, 0, 0, 0],
    [0, 0, 0, 0.5, 0, 0, 0, 0, 0],
    [0, 25.2, 0, -0.9, 0.2, 0.15, 0, 0, 0],
    [7.2, -1.4, 0, 0, 0.1, 0, 0.8, 0, 0],
    [0, 19.3, 2.1, 0, -8.7, 0, 0, 0, 0],
    [0, 6.7, 0, 0, 0, -1.1, 0, 1, 0],
    [29.1, 0, 0, 0, 0, 0, 0, 0, 0],
    [0, -1.8, 0.001, 0, 0, -12.8, 0, 1.7, 0.2],
]
VZ_LARGE = dict(
    name="vz2009_large_retarded",
    source="Vyhlidal & Zitek, IEEE TAC 2009, large-scale retarded example (qpmr transcription); "
    "reference: qpmr count + mpmath 40-digit polish",
    coeffs=_C2,
    delays=_D2,
    region=(-4.5, 2.5, 0.0, 100.0),
    count=401,
    reference=[
        2.425236932116968 + 0j,
        0.59212802848688595 + 0j,
        0.55265941779828042 + 0.54458325764800999j,
        0.067245595539397777 + 0.78447749195335906j,
        0.062761944327768168 + 1.0034574338847895j,
        0.025392025349778988 + 1.2167823067417378j,
    ],
    abscissa=2.425236932116968,
    stable=False,
)

# The neutral example of the QPmR papers (Vyhlídal & Zítek; qpmr documentation, example 2):
# h(s) = s^4 + 0.2 s^3 + 5 s + 2.1 + (0.5 s^4 - 2.1 s) e^{-1.5 s} + (0.3 s^4 + 3.2 s^2) e^{-2.2 s}
#        + 1.2 s^2 e^{-4.3 s} + 3 e^{-6.3 s};  qpmr: 101 roots in [-6, 3] x [0, 100].
VZ_NEUTRAL = dict(
    name="vz_neutral_five_delays",
    source="QPmR neutral example (qpmr docs, 01_journal2026/example02); reference: qpmr count + mpmath polish",
    coeffs=[[2.1, 5, 0, 0.2, 1], [0, -2.1, 0, 0, 0.5], [0, 0, 3.2, 0, 0.3], [0, 0, 1.2, 0, 0], [3, 0, 0, 0, 0]],
    delays=[0.0, 1.5, 2.2, 4.3, 6.3],
    region=(-6.0, 3.0, 0.0, 100.0),
    count=101,
    reference=[0.91000661286668429187 + 1.5566934977882543051j, 0.03576942369924141721 + 0.37110075330021316006j],
    abscissa=0.91000661286668429187,
    stable=False,
)

# ------------------------------------------------------------------------------------ neutral, TDS-CONTROL
# Appeltans & Michiels, "Analysis and controller-design of time-delay systems using TDS-CONTROL.
# A tutorial and manual" (2023), example 2.6 (Section 2.3.2; also tdcpy's example_2_06):
# x'(t) = x(t)/4 - x(t-1)/3 + 3/4 x'(t-1) - 1/2 x'(t-tau2).  Characteristic quasi-polynomial
# s - 1/4 + (1/3 - 3 s / 4) e^{-s} + (s / 2) e^{-tau2 s}.  Difference operator 1 - 3/4 z + 1/2 z^2 (z = e^{-s})
# for tau2 = 2: |z|^2 = 2, C_D = -ln(2)/2; sum |d_k| = 5/4 >= 1, not strongly stable (the manual's point:
# stable for tau2 = 2, unstable for tau2 = 2.05).  Roots: mpmath 40-digit polish of qpmr's.
APPELTANS_26 = dict(
    name="appeltans2023_ex2_6",
    source="Appeltans & Michiels, TDS-CONTROL manual (2023), example 2.6, tau2 = 2",
    coeffs=[[-0.25, 1.0], [1.0 / 3.0, -0.75], [0.0, 0.5]],
    delays=[0.0, 1.0, 2.0],
    region=(-0.9, 0.5, 0.0, 60.0),
    count=20,
    printed=[-0.17012 + 0.82383j],  # as quoted in issue #13 (posicast.roots and qpmr agree)
    printed_tol=0.5e-5,
    reference=[-0.17011804615991857031 + 0.82382686198763387123j, -0.18327795165202481111 + 0j],
    abscissa=-0.17011804615991857031,
    difference_abscissa=-math.log(2.0) / 2.0,
    hale_abscissa=-math.log(-0.75 + math.sqrt(41.0 / 16.0)),  # sum |d_k| e^{-a theta_k} = 1
    strongly_stable=False,
)
APPELTANS_26_PERTURBED = dict(
    name="appeltans2023_ex2_6_tau2_2.05",
    source="Appeltans & Michiels, TDS-CONTROL manual (2023), example 2.6, tau2 = 2.05",
    coeffs=[[-0.25, 1.0], [1.0 / 3.0, -0.75], [0.0, 0.5]],
    delays=[0.0, 1.0, 2.05],
    # C_D: roots of 1 - 0.75 z^20 + 0.5 z^41, z = exp(-0.05 s) (mpmath.polyroots, 40 digits)
    difference_abscissa=0.15948430313888383153,
    reference=[0.1554519765866969241 + 56.631345394488070609j],  # a chain root right of the axis
    strongly_stable=False,
)

# ------------------------------------------------------------------------------------- Lambert W
# s + a + b e^{-s tau} = 0  <=>  s = -a + W_k(-b tau e^{a tau}) / tau (Asl & Ulsoy, J. Dyn. Syst. Meas.
# Control 125, 2003; Corless et al., Adv. Comput. Math. 5, 1996); the principal branch k = 0 is the
# rightmost root for real a, b, tau (Shinozaki & Mori, Automatica 42, 2006).
LAMBERT = [
    dict(a=2.0, b=-3.0, tau=0.5, branches=range(-3, 4)),
    dict(a=1.0, b=5.0, tau=0.3, branches=range(-3, 4)),
    dict(a=-0.5, b=0.2, tau=1.5, branches=range(-3, 4)),
    dict(a=0.0, b=2.0, tau=0.4, branches=range(-3, 4)),
]

# ---------------------------------------------------------------- multiplicity-induced dominancy
# Mazanti, Boussaada & Niculescu, "Multiplicity-induced-dominancy for delay-differential equations of
# retarded type", J. Differential Equations 286 (2021) 84-118: for
# Q(s) = s^n + sum_{k<n} a_k s^k + e^{-s tau} sum_{k<n} alpha_k s^k a root of the maximal multiplicity 2n
# is real, s0 = -n/tau - a_{n-1}/n, and strictly dominant.  The coefficients below solve
# Q^{(j)}(s0) = 0, j < 2n (derived with sympy; each case re-checked with mpmath at 50 digits:
# Q^{(j)}(s0) < 1e-47, Q^{(2n)}(s0) != 0).
# n = 1 (Boussaada et al.): s + a + b e^{-s tau}, double root s0 = -a - 1/tau for b = e^{-1 - a tau} / tau.
# (Issue #13 writes b = -e^{-1 - a tau} / tau: with the + sign convention of b e^{-s tau} the sign is +.)
MID_1 = dict(a=1.0, tau=0.5, s0=-3.0, multiplicity=2)
# n = 3, tau = 1, s0 = -3 (a_2 = 0): Q = s^3 + 9 s - 6 + e^{-3} (3 s^2 + 42 s + 159) e^{-s}, sixfold at -3
MID_3 = dict(
    coeffs=[[-6.0, 9.0, 0.0, 1.0], [159.0 * math.exp(-3.0), 42.0 * math.exp(-3.0), 3.0 * math.exp(-3.0), 0.0]],
    delays=[0.0, 1.0],
    s0=-3.0,
    multiplicity=6,
)
# n = 2, tau = 1/2, s0 = -4 (a_1 = 0): Q = s^2 + 8 - e^{-2} (4 s + 40) e^{-s/2}, fourfold at -4
MID_2 = dict(
    coeffs=[[8.0, 0.0, 1.0], [-40.0 * math.exp(-2.0), -4.0 * math.exp(-2.0), 0.0]],
    delays=[0.0, 0.5],
    s0=-4.0,
    multiplicity=4,
)


def mazanti2021_prop61(kappa: float = 1.964, k: float = -0.67036, tau: float = 0.66) -> dict:
    """Mazanti, Boussaada & Niculescu (2021), Proposition 6.1, eq. (6.10a)-(6.10f): the third-order
    model with a sixfold dominant root s0 = r0 / tau - 1 / kappa, r0 = -3 - 9^(1/3) + 3^(1/3)
    (kappa = 1.964 s, k = -0.67036, tau = tau0 + tau1 = 0.66 s: s0 = -6.021, printed so in qpmr's
    examples).  Re-checked with mpmath: Q^{(j)}(s0) < 1e-47 for j <= 5, Q^{(6)}(s0) = 1.725."""
    r0 = -3.0 - 9.0 ** (1.0 / 3.0) + 3.0 ** (1.0 / 3.0)
    s0 = r0 / tau - 1.0 / kappa  # (6.10a)
    om = math.sqrt(-kappa * (s0**3 + 9.0 / tau * s0**2 + 36.0 / tau**2 * s0 + 60.0 / tau**3))  # (6.10b)
    xi = -3.0 * s0 / (2.0 * om) - 9.0 / (2.0 * om * tau) - 1.0 / (2.0 * om * kappa)  # (6.10c)
    e = math.exp(s0 * tau)
    b0 = -(3.0 * kappa * (s0**2 * tau**2 - 8.0 * s0 * tau + 20.0) * e) / (k * om**2 * tau**3)  # (6.10d)
    b1 = (6.0 * kappa * (s0 * tau - 4.0) * e) / (k * om**2 * tau**2)  # (6.10e)
    b2 = (-3.0 * kappa * e) / (k * om**2 * tau)  # (6.10f)
    coeffs = [
        [om**2 / kappa, om**2 + 2.0 * om * xi / kappa, 2.0 * om * xi + 1.0 / kappa, 1.0],
        [-b0 * k * om**2 / kappa, -b1 * k * om**2 / kappa, -b2 * k * om**2 / kappa, 0.0],
    ]
    return dict(coeffs=coeffs, delays=[0.0, tau], s0=s0, printed_s0=-6.021, multiplicity=6,
                s0_mp=-6.0210350493660044576)


# ------------------------------------------------------------------------------ critical delays
# s + a e^{-s tau} is stable iff a tau < pi / 2 (Hayes 1950; e.g. Michiels & Niculescu, "Stability and
# stabilization of time-delay systems", SIAM 2007, Sec. 1.2): at tau = pi / (2 a) the roots +-j a lie
# exactly on the imaginary axis (j a + a e^{-j pi / 2} = 0) and every other root is left of it.
CRITICAL = [dict(a=1.0), dict(a=3.0), dict(a=0.25)]
