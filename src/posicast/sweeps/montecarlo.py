"""Monte Carlo of seed 003's two-mass loop over its uncertain parameters, and the seed's 27-plant grid.

Seed 003 gives the damping ``c1``, ``c2`` and stiffness ``k2`` of its two-mass plant
with 50 % uncertainty and checks its designs on the 27 plants of a 3-level grid
(:func:`posicast.cases.two_mass_plants`).  Those are a coarse grid of a continuum:
:func:`two_mass_monte_carlo` draws the three parameters uniformly over the same
ranges (:data:`posicast.cases.TWO_MASS_UNCERTAINTY`, low to high) and evaluates at
every draw the loop the seed runs without its inner loop: closed-loop signal shaping
(seed 003 Fig. 1 without F and G: the shaper inside the loop, in front of the plant,
``architecture="control_action"``), the PI ``C = 0.396 (1 + 24 s) / s`` and a ZVD^2 shaper
designed for the *nominal* mode.  Per point: the certified closed-loop verdict and the
spectral abscissa (seed 003 Fig. 9 warns that the uncertain poles may cross to the right
half-plane), the peak sensitivity ``Ms``, the plant's actual flexible mode, the shaper's
residual vibration at that mode (seed 004 eq. 1-3) and the step response's overshoot and
2 % settling time (simulated, :func:`posicast.simulate`; NaN for an unstable loop).

>>> p = two_mass_point(50.0, 0.1, 10.0, simulate_step=False)   # the nominal plant
>>> p["stable"], round(p["vibration"], 12), round(p["mode_hz"], 4)   # the ZVD^2 cancels its mode
(True, 0.0, 0.5105)
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from scipy import stats

from .. import _validate as v
from ..analysis import residual_vibration
from ..cases import ALL as CASES
from ..cases import TWO_MASS_UNCERTAINTY, modes_of, two_mass_plant
from ..loops import ARCHITECTURES, Loop
from ..shapers import design
from ..simulation import simulate
from ..spectra import spectral_abscissa
from .engine import sweep
from .result import SweepResult

__all__ = ["two_mass_point", "two_mass_monte_carlo", "two_mass_grid", "TWO_MASS_RANGES"]

_CASE = CASES["two_mass"]
#: Seed 003's parameter ranges (the low and high levels of its 27-plant grid).
TWO_MASS_RANGES = {k: (min(lv), max(lv)) for k, lv in TWO_MASS_UNCERTAINTY.items()}
_T_END, _STEP, _T_STEP = 100.0, 0.02, 1.0  # s: a step of the reference at 1 s, 99 s to settle (PI, Ti = 24 s)
# Ms on 0.01-100 rad/s (the plant's features lie within 0.05-20 rad/s, seed 003's QFT frequencies; the peak is
# refined between grid points): the same Ms as Loop.margins' automatic grid to 1e-12, 7-60 times faster here.
_OMEGA = np.geomspace(1e-2, 1e2, 3000)


def two_mass_point(c1: float, c2: float, k2: float, shaper: str = "zvdk", architecture: str = "control_action",
                   simulate_step: bool = True) -> dict[str, Any]:
    """Seed 003's loop on the plant ``(c1, c2, k2)``, the shaper designed for the nominal plant.

    ``shaper``: a :func:`posicast.design` kind (``"zvdk"``: ZVD^2, the seed's; ``"zv"``, ...);
    ``architecture``: where the shaper sits (the seed's ``"control_action"``, or ``"feedforward"``).
    """
    P = two_mass_plant(c1, c2, k2)
    S = design(shaper, _CASE.mode, **({"k": 2} if shaper == "zvdk" else {}))
    L = Loop(v.choice(architecture, "architecture", ARCHITECTURES), G=P, C=_CASE.C, F=_CASE.F, S=S)
    st = L.stability()
    mode = modes_of(P, "plant")[0]
    out: dict[str, Any] = {"stable": bool(st.stable), "abscissa": float(spectral_abscissa(L)),
                           "ms": float(L.margins(omega=_OMEGA).ms), "mode_hz": mode.freq_hz, "zeta": mode.zeta,
                           "vibration": float(residual_vibration(S, mode))}
    if simulate_step and st.stable:
        t = np.arange(0.0, _T_END + _STEP / 2, _STEP)
        r = simulate(L, t, w=(t >= _T_STEP).astype(float))
        out.update(overshoot=r.overshoot("y"), settling_time=r.settling_time("y"))
    elif simulate_step:  # an unstable loop has no overshoot or settling time
        out.update(overshoot=math.nan, settling_time=math.nan)
    return out


def two_mass_monte_carlo(n: int, seed: int, *, shaper: str = "zvdk", architecture: str = "control_action",
                         simulate_step: bool = True, **sweep_kwargs: Any) -> SweepResult:
    """``n`` uniform draws of ``(c1, c2, k2)`` over :data:`TWO_MASS_RANGES` (seeded), swept with
    :func:`two_mass_point`; ``sweep_kwargs`` are :func:`posicast.sweep`'s options."""
    n = v.integer(n, "n", 1)
    dists = {k: stats.uniform(lo, hi - lo) for k, (lo, hi) in TWO_MASS_RANGES.items()}
    f = functools.partial(two_mass_point, shaper=shaper, architecture=architecture, simulate_step=simulate_step)
    return sweep(f, dists, n=n, seed=seed, **sweep_kwargs)


def two_mass_grid(*, shaper: str = "zvdk", architecture: str = "control_action", simulate_step: bool = True,
                  **sweep_kwargs: Any) -> SweepResult:
    """The seed's own 27 plants (3 levels of each parameter; flat index 13 is the nominal plant)."""
    f = functools.partial(two_mass_point, shaper=shaper, architecture=architecture, simulate_step=simulate_step)
    return sweep(f, {k: list(lv) for k, lv in TWO_MASS_UNCERTAINTY.items()}, **sweep_kwargs)
