"""Time-domain simulation of a loop of :mod:`posicast.loops` (issue #4): :func:`simulate`.

The simulator reads the loop's ring (:mod:`posicast.simulation.layout`, never its
architecture's name) and runs one of four methods, one module each:

* **exact** (:mod:`~posicast.simulation.exact`, ``sample_rate=None``, no shaper
  inside the ring): every channel exact for held inputs, fractional delays included;
* **stepped** (:mod:`~posicast.simulation.stepped`, ``sample_rate=None``, the
  shaper inside the ring): an internal step ``h = dt / substeps``, with an error
  estimate (``accuracy``);
* **sampled** (:mod:`~posicast.simulation.sampled`, ``sample_rate`` given): the
  controller and the shaper at the sample rate, the plant exact between samples;
* **nonlinear** (:mod:`~posicast.simulation.nonlinear`, ``saturation`` or
  ``rate_limit``): the ring walked sample by sample, at the internal step or at
  ``sample_rate``.

External inputs ``w``, ``d``, ``di``, ``n`` are held between the samples of
``t`` (zero-order hold), the natural reading of steps and of sampled data.
"""

from __future__ import annotations

import warnings
from typing import Any, NamedTuple, Sequence

import numpy as np

from .. import _validate as v
from ..loops.loop import Loop
from ..shapers.base import Shaper
from .checks import (
    MAX_BYTES,
    MAX_SECONDS,
    MAX_SUBSTEPS,
    as_signal,
    check_mode_nyquist,
    check_rates,
    check_saturation,
    check_time,
    controller_period,
    default_substeps,
    refuse_work,
    shaper_object,
)
from .exact import exact_channels, exact_lumped
from .layout import RingLayout, Signals, read_ring
from .nonlinear import run_nonlinear
from .response import SimulationResponse
from .sampled import plant_on_fine_grid, run_sampled
from .stepped import run_stepped

__all__ = ["simulate", "DivergenceWarning", "MAX_BYTES", "MAX_SECONDS", "MAX_SUBSTEPS"]


class DivergenceWarning(UserWarning):
    """A simulated loop diverged; the response stops where it did."""


class _Run(NamedTuple):
    """What a method returns: the signals on ``t``, the method's name and the estimated error of ``y``."""

    signals: Signals
    mode: str
    accuracy: float = 0.0


class _Options(NamedTuple):
    """The checked arguments of :func:`simulate` that choose and tune the method."""

    sample_rate: float | None
    substeps: int | None
    controller_method: str
    saturation: tuple[float, float] | None
    rate_limit: float | None
    divergence_limit: float

    @property
    def nonlinear(self) -> bool:
        return self.saturation is not None or self.rate_limit is not None


def simulate(
    loop: Loop,
    t: Any,
    w: Any = None,
    d: Any = None,
    n: Any = None,
    sample_rate: float | None = None,
    *,
    di: Any = None,
    substeps: int | None = None,
    controller_method: str = "bilinear",
    saturation: float | tuple[float, float] | None = None,
    rate_limit: float | None = None,
    divergence_limit: float = 1e6,
    outputs: Sequence[str] | None = None,
) -> SimulationResponse:
    """Simulate a loop of :mod:`posicast.loops` for reference, disturbance and noise signals.

    Parameters
    ----------
    loop : Loop
        From :func:`posicast.feedforward`, :func:`~posicast.control_action` or
        :func:`~posicast.inverse_shaper`; its shaper must be a posicast Shaper.
    t : array_like
        Uniform, increasing time grid [s].
    w, d, n : array_like or None
        Reference, output disturbance (added to ``z``) and measurement noise on
        ``t``, held between samples.  ``di`` is an input disturbance (added to
        the plant input).
    sample_rate : float or None
        Controller/shaper rate [Hz] for the sampled mode; ``1 / sample_rate``
        must be an integer multiple of the step of ``t``.  None: continuous mode.
    substeps : int, optional
        Continuous mode with the shaper in the loop: internal steps per step of
        ``t`` (default: enough for ``h <= 1 ms`` and at least 1).
    controller_method : {'bilinear', 'zoh', 'foh'}
        Sampled mode: the controller's discretisation.
    saturation : float or (float, float), optional
        Actuator limits on ``u``: ``(u_min, u_max)``, or ``u_max`` for ``±u_max``.
    rate_limit : float, optional
        Largest ``|du/dt|`` of the actuator command [units/s].  With either
        limit the loop is run sample by sample (sampled mode at
        ``sample_rate``; continuous mode at the internal step, ZOH plant and
        Tustin controller).
    divergence_limit : float
        A signal whose magnitude exceeds ``divergence_limit`` times the largest
        input magnitude (or 1) has diverged: the response stops at that time
        and :attr:`SimulationResponse.diverged` says when and which signal.
    outputs : sequence of str, optional
        The loop signals to return (e.g. ``("y", "u")``); default all.  The
        response then holds these and the inputs given; with the shaper inside
        the loop (continuous mode) the run keeps only these, so a long run's
        memory is that of the signals asked for (an hour at 1 kHz: about 30 MB
        per signal).  A divergence is detected on the signals returned.

    Returns
    -------
    SimulationResponse

    Raises
    ------
    ValueError, TypeError
        A bad argument (named in the message), or work estimated up front beyond
        :data:`MAX_BYTES` of memory or :data:`MAX_SECONDS` of computation: the
        message gives the estimate and what to change (fewer samples, fewer
        ``substeps``, a ``sample_rate``), before anything large is allocated.

    Examples
    --------
    Feedforward ZV shaping of a unit step: the load ``y`` settles without
    residual vibration.

    >>> import numpy as np, posicast
    >>> S = posicast.design("zv", posicast.Mode(10.0, 0.03))
    >>> loop = posicast.feedforward(G=(1, [1, 1, 0]), F=([1, 0], [1, 0.6, 100]),
    ...                             C=([10, 10], [0.01, 1]), S=S)     # seed 000 eq. 25-27
    >>> t = np.arange(0, 30, 1e-3)
    >>> r = posicast.simulate(loop, t, w=np.ones_like(t))
    >>> bool(r.residual_vibration(after=15.0) < 1e-10)
    True

    The inverse-shaper loop (the shaper inside), keeping only the load:

    >>> loop = posicast.inverse_shaper(G=(1, [1, 1, 0]), F=([1, 0], [1, 0.6, 100]),
    ...                                C=([10, 10], [0.01, 1]), S=posicast.design("dzv", posicast.Mode(10.0, 0.03)))
    >>> r = posicast.simulate(loop, t, w=np.ones_like(t), outputs=("y",))
    >>> sorted(r.signals), bool(r.accuracy < 1e-5)
    (['w', 'y'], True)
    """
    if not isinstance(loop, Loop):
        raise TypeError(f"loop must be a posicast Loop (feedforward/control_action/inverse_shaper), got {type(loop).__name__}")
    t, dt = check_time(t)
    N = t.size
    # every argument is checked, and the work estimated, before anything large is allocated or run
    opts = _check_options(sample_rate, dt, N, substeps, controller_method, saturation, rate_limit, divergence_limit)
    S = shaper_object(loop)
    layout = read_ring(loop)
    keep = _check_outputs(outputs, layout)
    refuse_work(layout, S, N, dt, opts.sample_rate, opts.substeps, opts.nonlinear)
    given = {"w": w, "d": d, "di": di, "n": n}
    sig = {name: as_signal(x, name, N) for name, x in given.items()}
    if keep is not None:
        keep = keep | {name for name, x in given.items() if x is not None or name in keep}
        # an input not given and not kept is never returned: a read-only zero view, no memory of its length
        sig = {name: x if name in keep else np.broadcast_to(np.zeros(1), (N,)) for name, x in sig.items()}
    if opts.nonlinear:
        run = _nonlinear(loop, layout, S, sig, dt, opts)
    elif opts.sample_rate is not None:
        run = _sampled(loop, layout, S, sig, dt, opts)
    elif S is None or layout.shaper is None:
        run = _exact(loop, layout, S, sig, dt)
    else:
        run = _stepped(loop, layout, S, sig, dt, opts, keep)
    return _finish(loop, t, sig, run, opts.sample_rate, opts.divergence_limit, keep)


def _check_outputs(outputs: Any, layout: RingLayout) -> frozenset[str] | None:
    """The names in ``outputs`` (each a signal of this loop), or None for all."""
    if outputs is None:
        return None
    names = [outputs] if isinstance(outputs, str) else v.sequence(outputs, "outputs", min_len=1)
    ring = layout.ring
    valid = tuple(dict.fromkeys([*layout.nodes, *ring.outputs, *ring.external, "w", "d", "di", "n"]))
    valid = tuple(name for name in valid if name != "zn")
    return frozenset(v.choice(name, "outputs", valid) for name in names)


def _check_options(sample_rate: Any, dt: float, N: int, substeps: Any, controller_method: Any, saturation: Any,
                   rate_limit: Any, divergence_limit: Any) -> _Options:
    if isinstance(divergence_limit, (bool, np.bool_)) or not isinstance(divergence_limit, (int, float, np.integer,
                                                                                           np.floating)):
        raise TypeError(f"divergence_limit must be a number > 1, got {type(divergence_limit).__name__}")
    if not (divergence_limit > 1):
        raise ValueError(f"divergence_limit must be a number > 1, got {divergence_limit!r}")
    v.choice(controller_method, "controller_method", ("bilinear", "zoh", "foh"))
    sat = check_saturation(saturation)
    if rate_limit is not None:
        if isinstance(rate_limit, bool) or not isinstance(rate_limit, (int, float, np.integer, np.floating)) \
                or not rate_limit > 0:
            raise ValueError(f"rate_limit must be a positive number of units per second, got {rate_limit!r}")
        rate_limit = float(rate_limit)
    if substeps is not None:
        substeps = v.integer_in_range(substeps, "substeps", 1, MAX_SUBSTEPS)
    if sample_rate is not None:
        controller_period(sample_rate, dt, N)
    return _Options(sample_rate, substeps, controller_method, sat, rate_limit, divergence_limit)


def _check_sampled(loop: Loop, S: Shaper | None, dt: float, N: int, sample_rate: Any) -> tuple[float, int]:
    """The controller period ``Ts`` and steps of ``t`` per period, with the rate checks of the sampled runs."""
    Ts, m = controller_period(sample_rate, dt, N)
    check_rates(S, Ts, "sample_rate", float(sample_rate))
    for lp in (loop.F, loop.G):
        check_mode_nyquist(lp, float(sample_rate))
    return Ts, m


def _nonlinear(loop: Loop, layout: RingLayout, S: Shaper | None, sig: Signals, dt: float, opts: _Options) -> _Run:
    if opts.sample_rate is None:
        substeps = opts.substeps if opts.substeps is not None else default_substeps(dt)
        h = dt / substeps
        check_rates(S, h, "the internal rate (1/t step x substeps)", 1.0 / h)
        fine = {k: np.repeat(x, substeps) for k, x in sig.items()}
        res = run_nonlinear(loop, layout, S, fine, h, "bilinear", opts.saturation, opts.rate_limit)
        return _Run({k: x[::substeps] for k, x in res.items()}, "continuous (nonlinear, fine step)")
    Ts, m = _check_sampled(loop, S, dt, sig["w"].size, opts.sample_rate)
    coarse = {k: x[::m] for k, x in sig.items()} if m > 1 else sig
    res = run_nonlinear(loop, layout, S, coarse, Ts, opts.controller_method, opts.saturation, opts.rate_limit)
    return _Run(plant_on_fine_grid(loop, layout, res, sig, Ts, m) if m > 1 else res, "sampled")


def _sampled(loop: Loop, layout: RingLayout, S: Shaper | None, sig: Signals, dt: float, opts: _Options) -> _Run:
    Ts, m = _check_sampled(loop, S, dt, sig["w"].size, opts.sample_rate)
    return _Run(run_sampled(loop, layout, S, sig, Ts, m, opts.controller_method), "sampled")


def _exact(loop: Loop, layout: RingLayout, S: Shaper | None, sig: Signals, dt: float) -> _Run:
    if S is None or (not S.distributed and S.continuous is None):
        return _Run(exact_lumped(loop, layout, S, sig, dt), "continuous (exact)")
    return _Run(exact_channels(loop, layout, sig, dt), "continuous (exact)")


def _stepped(loop: Loop, layout: RingLayout, S: Shaper, sig: Signals, dt: float, opts: _Options,
             keep: frozenset[str] | None) -> _Run:
    substeps = opts.substeps if opts.substeps is not None else default_substeps(dt)
    h = dt / substeps
    check_rates(S, 2 * h, "the internal rate (1/t step x substeps)", 1.0 / (2 * h))
    run = run_stepped(loop, layout, S, sig, h, substeps, keep)
    return _Run(run.signals, "continuous", run.accuracy)


def _first_beyond(x: np.ndarray, bound: float, stop: int) -> int:
    """The first index below ``stop`` where ``x`` is not finite or beyond ``bound`` in magnitude (else ``stop``),
    scanned in pieces of 2^20 samples."""
    for k in range(0, min(stop, x.size), 1 << 20):
        part = x[k: min(stop, k + (1 << 20))]
        bad = np.flatnonzero(~(np.abs(part) <= bound))  # NaN compares False
        if bad.size:
            return k + int(bad[0])
    return stop


def _finish(loop: Loop, t: np.ndarray, sig: Signals, run: _Run, sample_rate: float | None,
            limit: float, keep: frozenset[str] | None = None) -> SimulationResponse:
    signals = dict(sig)
    signals.update({name: values for name, values in run.signals.items() if name != "zn"})
    if keep is not None:
        signals = {name: values for name, values in signals.items() if name in keep}
    # largest input magnitude (no temporary of the signal's size: an hour at 1 kHz is 29 MB per signal)
    scale = max(1.0, max(max(float(np.max(x)), -float(np.min(x))) if x.size else 0.0 for x in sig.values()))
    diverged = None
    which = None
    first = t.size
    for k in ("y", "z", "u", "v", "e", "m", "r"):
        if k not in signals:
            continue
        bad = _first_beyond(signals[k], limit * scale, first)
        if bad < first:
            first, which = bad, k
    if which is not None:
        diverged = float(t[first])
        warnings.warn(
            f"the {loop.architecture} loop diverged: |{which}| exceeded {limit:g} x the input scale at "
            f"t = {diverged:.4g} s; the response stops there",
            DivergenceWarning,
            stacklevel=3,
        )
        t = t[:first]
        signals = {k: v[:first] for k, v in signals.items()}
    return SimulationResponse(
        time=t, signals=signals, mode=run.mode, sample_rate=sample_rate, accuracy=run.accuracy,
        diverged=diverged, diverged_signal=which, architecture=loop.architecture,
    )
