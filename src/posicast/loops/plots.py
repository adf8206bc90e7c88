"""Matplotlib views of loops: Bode, Nyquist with the Ms circle, and closed-loop spectra.

Each function draws and returns ``(fig, ax)``; matplotlib is imported only here.
The data come from :class:`~posicast.loops.Loop` methods (``frequency_response``,
``nyquist``, ``margins``, ``poles``), which can be used without plotting.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from .. import _validate as v
from ..core.removable import removable_points
from ..core.transfer import TransferFunction
from ..spectra import roots
from ..spectra.rootfinder import check_region
from .loop import Loop

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["bode_plot", "complex_plane", "nyquist_plot", "spectrum_plot", "unwrapped_phase"]

_COLORS = ("tab:blue", "tab:red", "tab:green", "tab:orange", "tab:purple", "tab:brown")


def _as_list(items: Any, name: str, types: tuple[type, ...]) -> list[Any]:
    seq = list(items) if isinstance(items, (list, tuple)) else [items]
    if len(seq) > 50:
        raise ValueError(f"{name}: at most 50 curves per plot, got {len(seq)}")
    if not seq:
        raise ValueError(f"{name} must not be empty")
    for it in seq:
        if not isinstance(it, types):
            allowed = " or ".join(t.__name__ for t in types)
            raise TypeError(f"{name} must be a {allowed} or a sequence of them, got {type(it).__name__}")
    return seq


def _loops_with_labels(loop: Any, labels: Sequence[str] | None) -> list[Loop]:
    loops = _as_list(loop, "loop", (Loop,))
    v.labels(labels, "labels", len(loops))
    return loops


def _omega(omega: Any, positive: bool = False) -> np.ndarray:
    w = v.strict_real_array(omega, "omega", allow_empty=True).reshape(-1)
    if w.size < 2:
        raise ValueError("omega must contain at least 2 frequencies")
    if positive and np.any(w <= 0):
        raise ValueError("omega must be > 0 rad/s on a Bode plot's logarithmic axis")
    return w


#: Largest phase step [rad] between neighbouring frequencies that :func:`unwrapped_phase` unwraps.
_PHASE_STEP = np.pi / 4
#: Most frequencies :func:`unwrapped_phase` evaluates (the refinement stops there).
_PHASE_POINTS = 2_000_000


def unwrapped_phase(H: TransferFunction, omega: Any) -> np.ndarray:
    """Continuous phase [rad] of ``H(j omega)`` on increasing ``omega``: no 2 pi jumps, whatever the grid.

    ``np.unwrap`` on a coarse grid cannot tell a delay's phase ``-omega tau`` (which
    turns by ``tau`` times the grid step between two points: more than pi at 10 krad/s
    for ``tau = 0.1 s`` on a 2000-point log grid) from a jump.  Here the net delay of
    ``H``, ``tau = min delay of its numerator - min delay of its denominator``, is
    taken out analytically (``-omega tau``), and the phase of the rest is followed on
    a grid refined until no step exceeds pi/4 (midpoints inserted where one does), so
    each step is the true increment.  The phase at the first frequency is its
    principal value.

    Examples
    --------
    >>> import numpy as np, posicast
    >>> from posicast.core.transfer import delay
    >>> H = posicast.as_transfer(([1.0], [1.0, 1.0])) * delay(0.1)
    >>> w = np.array([1.0, 1e4])
    >>> bool(abs(unwrapped_phase(H, w)[1] - (-0.1e4 - np.arctan(1e4))) < 1e-9)
    True
    """
    v.instance_of(H, TransferFunction, "H", "a posicast TransferFunction")
    w = v.strict_real_array(omega, "omega").reshape(-1)
    if w.size and np.any(np.diff(w) <= 0):
        raise ValueError("omega must be increasing")
    tau = float(np.min(H.num.delays)) - float(np.min(H.den.delays)) if not H.num.is_zero else 0.0

    def rest(x: np.ndarray) -> np.ndarray:
        return H.freqresp(x) * np.exp(1j * x * tau)

    grid, val = w, rest(w)
    while grid.size < _PHASE_POINTS:
        steps = np.abs(np.angle(val[1:] / val[:-1]))
        wide = np.flatnonzero(~(steps <= _PHASE_STEP) & np.isfinite(steps) & (np.diff(grid) > 1e-12 * np.abs(grid[1:])))
        if wide.size == 0:
            break
        mid = 0.5 * (grid[wide] + grid[wide + 1])
        grid = np.insert(grid, wide + 1, mid)
        val = np.insert(val, wide + 1, rest(mid))
    with np.errstate(invalid="ignore", divide="ignore"):
        ph = np.concatenate([[np.angle(val[0])], np.angle(val[0]) + np.cumsum(np.angle(val[1:] / val[:-1]))])
    ph = ph[np.searchsorted(grid, w)]
    return ph - w * tau


def bode_plot(
    items: Loop | TransferFunction | Sequence[Loop | TransferFunction],
    src: str = "w",
    dst: str = "y",
    omega: Any = None,
    ax: Any = None,
    labels: Sequence[str] | None = None,
) -> tuple[Figure, Axes]:
    """Magnitude [dB] and phase [deg] of channel ``src -> dst`` of one or several loops.

    Parameters
    ----------
    items : Loop, TransferFunction, or a sequence of them
        For a Loop, its channel ``src -> dst`` is drawn; a TransferFunction is
        drawn as is (e.g. ``loop.sensitivity``).
    src, dst : str
        The channel (see :meth:`Loop.transfer`).
    omega : array_like
        Frequencies [rad/s] (default: the first loop's :meth:`Loop.default_omega`,
        or ``logspace(-2, 3)`` for transfer functions).
    ax : matplotlib Axes or a pair of Axes, optional
        A pair ``(magnitude, phase)``; a single Axes draws the magnitude only.
    labels : sequence of str, optional
        Legend entries (default: the loops' labels).

    Returns
    -------
    fig, (ax_mag, ax_phase)
        ``ax_phase`` is None when a single Axes was given.  The phase is
        :func:`unwrapped_phase`: continuous, with each delay's ``-omega tau`` exact.
    """
    seq = _as_list(items, "items", (Loop, TransferFunction))
    v.labels(labels, "labels", len(seq))
    if isinstance(ax, (list, tuple, np.ndarray)):
        if len(ax) != 2:
            raise ValueError(f"ax must be one Axes or a pair (magnitude, phase), got {len(ax)}")
        for a in ax:
            v.axes(a, "ax")
    else:
        v.axes(ax, "ax")
    for it in seq:
        if isinstance(it, Loop):
            it._check_pair(src, dst)
    if omega is None:
        first = next((it for it in seq if isinstance(it, Loop)), None)
        w = first.default_omega() if first is not None else np.logspace(-2, 3, 2000)
    else:
        w = _omega(omega, positive=True)
    import matplotlib.pyplot as plt

    if ax is None:
        fig, (ax_mag, ax_ph) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    elif isinstance(ax, (list, tuple, np.ndarray)):
        ax_mag, ax_ph = ax
        fig = ax_mag.figure
    else:
        ax_mag, ax_ph = ax, None
        fig = ax.figure
    for i, it in enumerate(seq):
        tf = it.transfer(src, dst) if isinstance(it, Loop) else it
        H = tf.freqresp(w)
        lab = it.label if isinstance(it, Loop) else f"H{i}"
        if labels is not None:
            lab = labels[i]
        with np.errstate(divide="ignore"):
            mag = 20.0 * np.log10(np.abs(H))
        ax_mag.semilogx(w, mag, color=_COLORS[i % len(_COLORS)], label=lab)
        if ax_ph is not None:
            ph = np.degrees(unwrapped_phase(tf, w))  # the delays' phase exactly, no unwrapping jumps
            ax_ph.semilogx(w, ph, color=_COLORS[i % len(_COLORS)], label=lab)
    ax_mag.set_ylabel(f"|T_{src}{dst}| [dB]" if any(isinstance(it, Loop) for it in seq) else "magnitude [dB]")
    ax_mag.grid(True, which="both", alpha=0.3)
    ax_mag.legend(fontsize=8)
    if ax_ph is not None:
        ax_ph.set_ylabel("phase [deg]")
        ax_ph.set_xlabel(r"$\omega$ [rad/s]")
        ax_ph.grid(True, which="both", alpha=0.3)
    else:
        ax_mag.set_xlabel(r"$\omega$ [rad/s]")
    return fig, (ax_mag, ax_ph)


def nyquist_plot(
    loop: Loop | Sequence[Loop],
    omega: Any = None,
    ms: float | None | bool = None,
    ax: Any = None,
    labels: Sequence[str] | None = None,
    zoom: float | bool | None = None,
) -> tuple[Figure, Axes]:
    """Nyquist curve of the loop gain ``L(j omega)`` with the ``Ms`` circle (seed 001 Fig. 7).

    Parameters
    ----------
    loop : Loop or sequence of Loop
    omega : array_like, optional
        Frequencies [rad/s], default each loop's :meth:`Loop.default_omega`.
        The mirror image (``omega < 0``) is drawn dashed.
    ms : float, None or False
        Draw the circle of center -1 and radius ``1 / ms``: a float is a
        design constraint (e.g. ``Ms = 2``); None draws each loop's own peak
        sensitivity circle (tangent to its curve); False draws no circle.
    ax : matplotlib Axes, optional
    labels : sequence of str, optional
    zoom : float, bool or None
        Half-width of the square window about the critical point ``-1`` (the axes
        limits).  None (default): :data:`NYQUIST_ZOOM` when a curve leaves a box
        twice that size (an integrator or a resonance sends ``|L|`` to thousands,
        and autoscaling would shrink the circle to a dot), else the curves' own
        extent; False: autoscale.  A text in the corner says how far the curve goes.

    Returns
    -------
    fig, ax

    Examples
    --------
    >>> import posicast
    >>> loop = posicast.control_action(G=([1], [1, 1, 0]), C=([10, 10], [0.01, 1]))   # |L| -> inf at 0
    >>> fig, ax = nyquist_plot(loop, ms=2.0)
    >>> [float(x) for x in ax.get_xlim() + ax.get_ylim()]       # zoomed on -1
    [-3.5, 1.5, -2.5, 2.5]
    """
    loops = _loops_with_labels(loop, labels)
    if ms is not None and ms is not False:
        ms = v.positive(ms, "ms")
        if not 1.0 <= ms <= 1e12:
            raise ValueError(f"ms must be in [1, 1e12] (a peak sensitivity), got {ms:g}")
    if zoom is not None and zoom is not False:
        if zoom is True:
            zoom = NYQUIST_ZOOM
        zoom = v.real_in_range(zoom, "zoom", 0.0, 1e12, lo_open=True)
    v.axes(ax, "ax")
    w = None if omega is None else _omega(omega)
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(6, 6))
    else:
        fig = ax.figure
    reach = 0.0  # how far from -1 the curves go
    for i, lp in enumerate(loops):
        col = _COLORS[i % len(_COLORS)]
        data = lp.nyquist(w)
        L = data.response
        finite = np.isfinite(L)
        reach = max(reach, float(np.max(np.abs(L[finite] + 1.0))) if finite.any() else 0.0)
        lab = lp.label if labels is None else labels[i]
        ax.plot(L.real, L.imag, color=col, label=lab)
        ax.plot(L.real, -L.imag, color=col, ls="--", lw=0.8)
        if ms is None:
            m = lp.margins(data.omega)
            _ms_circle(ax, m.ms, col, ":", f"Ms = {m.ms:.3g}")
    if ms is not None and ms is not False:
        _ms_circle(ax, ms, "k", "-", f"Ms = {ms:g}")
    ax.plot([-1.0], [0.0], "k+", ms=10)
    ax.set_xlabel("Re L(j$\\omega$)")
    ax.set_ylabel("Im L(j$\\omega$)")
    half = zoom if zoom is not None else (NYQUIST_ZOOM if reach > 2.0 * NYQUIST_ZOOM else None)
    if half is not None and half is not False:
        ax.set_xlim(-1.0 - half, -1.0 + half)
        ax.set_ylim(-half, half)
        ax.set_aspect("equal", adjustable="box")
        if reach > half:
            ax.text(0.02, 0.02, f"zoomed on -1; the curve reaches |1 + L| = {reach:.3g}", transform=ax.transAxes,
                    fontsize=7, color="0.3")
    else:
        ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    return fig, ax


#: Default half-width of the Nyquist plot's window about -1 when the curve goes far (see :func:`nyquist_plot`).
NYQUIST_ZOOM = 2.5


def _ms_circle(ax: Any, ms: float, color: str, ls: str, label: str) -> None:
    """The circle of centre -1 and radius 1/ms, labelled in the legend and beside its top."""
    theta = np.linspace(0.0, 2.0 * np.pi, 400)
    r = 1.0 / ms
    ax.plot(-1 + r * np.cos(theta), r * np.sin(theta), color=color, lw=1.0, ls=ls, label=label)
    ax.annotate(label, xy=(-1.0, r), xytext=(0, 3), textcoords="offset points", ha="center", va="bottom",
                fontsize=8, color=color)


def spectrum_plot(
    loop: Loop | Sequence[Loop],
    region: Sequence[float],
    ax: Any = None,
    labels: Sequence[str] | None = None,
) -> tuple[Figure, Axes]:
    """Plant poles, shaper zeros and closed-loop poles in the complex plane (seed 000 Fig. 6).

    Black diamonds: poles of ``F`` (roots of its denominator); crosses: zeros
    of the shaper (roots of ``S.num`` less its removable points); squares, then
    circles, ...: closed-loop poles (:meth:`Loop.poles`).  Several loops share
    one axes (seed 000 Fig. 6 overlays the inverse ZV and inverse DZV loops).

    Parameters
    ----------
    loop : Loop or sequence of Loop
    region : (re_min, re_max, im_min, im_max)
        Rectangle searched for roots (:func:`posicast.spectra.roots`).
    ax : matplotlib Axes, optional
    labels : sequence of str, optional

    Returns
    -------
    fig, ax
    """
    loops = _loops_with_labels(loop, labels)
    region = check_region(region)
    v.axes(ax, "ax")
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 6))
    else:
        fig = ax.figure
    markers = ("s", "o", "^", "v", "D", "p")
    shaper_markers = ("x", "+", "1", "2", "3", "4")
    plotted_plant = False
    for i, lp in enumerate(loops):
        col = _COLORS[i % len(_COLORS)]
        lab = lp.label if labels is None else labels[i]
        if not plotted_plant and not lp.F.den.is_zero and lp.F.den.degree >= 1:
            fp = roots(lp.F.den, region).roots
            if fp.size:
                ax.plot(fp.real, fp.imag, "kd", ms=8, mfc="none", mew=1.5, label="poles of F")
            plotted_plant = True
        if lp.S is not None:
            if not (lp.S.num.is_polynomial and lp.S.num.degree < 1):
                sz = roots(lp.S.num, region, ignore=removable_points(lp.S.num, lp.S.den)).roots
                if sz.size:
                    ax.plot(sz.real, sz.imag, shaper_markers[i % len(shaper_markers)], color=col, ms=8,
                            label=f"zeros of S ({lab})")
        pol = lp.poles(region).roots
        ax.plot(pol.real, pol.imag, markers[i % len(markers)], color=col, mfc="none", ms=7,
                label=f"closed-loop poles ({lab})")
    complex_plane(ax, region)
    return fig, ax


def complex_plane(ax: Axes, region: Sequence[float]) -> None:
    """The s-plane frame of :func:`spectrum_plot`: the imaginary axis, the ``region``
    ``(re_min, re_max, im_min, im_max)`` as limits, axis labels, grid and legend."""
    ax.axvline(0.0, color="k", lw=0.6)
    ax.set_xlim(region[0], region[1])
    ax.set_ylim(region[2], region[3])
    ax.set_xlabel("Re s")
    ax.set_ylabel("Im s")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
