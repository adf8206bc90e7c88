"""Export a shaper for a controller: discrete taps at a sample rate as JSON or a C array.

The taps come from :func:`posicast.simulation.streaming.discretize` (fractional delays
split between samples, distributed delays integrated exactly); the export also
carries the exact continuous-time design so a reader can re-discretise it.
"""

from __future__ import annotations

import json
import math
import re

import numpy as np

from ..shapers.base import Shaper
from ..simulation.streaming import DiscreteShaper, discretize

__all__ = ["export_shaper", "EXPORT_FORMATS"]

EXPORT_FORMATS = ("json", "c")
_C_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def _describe(S: Shaper) -> str:
    modes = ", ".join(f"omega = {m.omega:.9g} rad/s ({m.freq_hz:.6g} Hz), zeta = {m.zeta:.6g}" for m in S.modes)
    return f"kind {S.name}" + (f"; mode {modes}" if modes else "")


def _json(D: DiscreteShaper, name: str) -> str:
    S = D.shaper
    nz = np.flatnonzero(D.taps)
    doc = {
        "format": "posicast-shaper-taps/1",
        "name": name,
        "kind": S.name,
        "modes": [{"omega": m.omega, "zeta": m.zeta} for m in S.modes],
        "sample_rate": D.sample_rate,
        "fractional": D.fractional,
        "length": D.n_taps,
        "taps": [{"index": int(k), "weight": float(D.taps[k])} for k in nz],
        "dc_gain": D.dc_gain,
        "impulses": {"times": S.times.tolist(), "amplitudes": S.amplitudes.tolist()},
        "iir": None if D.b is None else {"b": D.b.tolist(), "a": D.a.tolist(), "form": "parallel to the taps"},
        "design": S.to_dict(),
    }
    return json.dumps(doc, indent=2)


def _c_floats(values: np.ndarray, per_line: int = 6) -> str:
    items = []
    for x in values:
        txt = f"{float(np.float32(x)):.9g}"  # 9 significant digits round-trip a float32
        if not any(c in txt for c in ".en"):
            txt += ".0"
        items.append(txt + "f")
    lines = [", ".join(items[i : i + per_line]) for i in range(0, len(items), per_line)]
    return ",\n    ".join(lines)


def _c(D: DiscreteShaper, name: str) -> str:
    S = D.shaper
    N = D.n_taps
    U = name.upper()
    times = ", ".join(f"{t:.12g}" for t in S.times)
    amps = ", ".join(f"{a:.12g}" for a in S.amplitudes)
    out = [
        f"/* posicast shaper '{name}': {_describe(S)}",
        f" * sample rate {D.sample_rate:.9g} Hz, fractional delays: {D.fractional}, {N} taps, DC gain {D.dc_gain:.12g}",
        f" * continuous-time impulses: t = [{times}] s, A = [{amps}]",
    ]
    if S.distributed:
        out.append(f" * plus {len(S.distributed)} distributed-delay part(s) integrated into the taps")
    out += [
        " *",
        f" * y[n] = sum_{{k=0}}^{{{U}_LEN-1}} {name}_taps[k] * x[n-k]"
        + (f" + IIR({name}_iir_b, {name}_iir_a) x[n]" if D.b is not None else ""),
        " *",
        " * Reference FIR (ring buffer) implementation (accumulate in double where affordable: a float",
        f" * accumulator adds up to ~{U}_LEN * 6e-8 of rounding):",
        " *",
        f" *   static float {name}_buf[{U}_LEN];",
        f" *   static unsigned {name}_pos = 0;",
        f" *   float {name}_step(float x) {{",
        " *       double y = 0.0;",
        f" *       unsigned k, i = {name}_pos;",
        f" *       {name}_buf[i] = x;                      newest sample at i",
        f" *       for (k = 0; k < {U}_LEN; ++k) {{",
        f" *           y += {name}_taps[k] * {name}_buf[i];",
        f" *           i = (i == 0) ? {U}_LEN - 1 : i - 1;   older samples backwards",
        " *       }",
        f" *       {name}_pos = ({name}_pos + 1) % {U}_LEN;",
        " *       return (float)y;",
        " *   }",
        " */",
        f"#define {U}_LEN {N}",
        f"static const float {name}_taps[{N}] = {{\n    {_c_floats(D.taps)}\n}};",
    ]
    if D.b is not None and D.a is not None:
        out += [
            "/* IIR section in parallel (Tustin, prewarped at the mode), powers of z^-1, a[0] = 1 */",
            f"#define {U}_IIR_LEN {D.b.size}",
            f"static const float {name}_iir_b[{D.b.size}] = {{ {_c_floats(D.b)} }};",
            f"static const float {name}_iir_a[{D.a.size}] = {{ {_c_floats(D.a)} }};",
        ]
    return "\n".join(out) + "\n"


def export_shaper(
    S: Shaper | DiscreteShaper,
    sample_rate: float,
    format: str = "json",
    name: str = "shaper",
    fractional: str = "linear",
) -> str:
    """Export a shaper's taps at ``sample_rate`` for a controller.

    Parameters
    ----------
    S : Shaper or DiscreteShaper
        The design (discretised here) or an already discretised one at ``sample_rate``.
    sample_rate : float
        Samples per second (see :func:`posicast.simulation.streaming.discretize` for its limits).
    format : {"json", "c"}
        ``"json"``: sample rate, nonzero taps ``{index, weight}``, the exact impulses
        (times, amplitudes), the IIR ``b``/``a`` if any and the full design.
        ``"c"``: ``#define NAME_LEN N`` and ``static const float NAME_taps[N]``, with
        the design and a reference ring-buffer FIR in a comment.
    name : str
        A C identifier naming the arrays.
    fractional : {"linear", "lagrange3", "round"}
        Realisation of fractional delays.

    Returns
    -------
    str

    Raises
    ------
    ValueError
        Unknown ``format``, ``name`` not a C identifier, ``sample_rate`` too low.

    Examples
    --------
    >>> import json, posicast as pc
    >>> doc = json.loads(export_shaper(pc.design("zv", pc.Mode(10.0, 0.0)), 100.0))
    >>> doc["sample_rate"], doc["taps"][0]
    (100.0, {'index': 0, 'weight': 0.5})
    >>> text = export_shaper(pc.design("zv", pc.Mode(10.0, 0.0)), 100.0, "c", name="zv10")
    >>> [line for line in text.splitlines() if line.startswith(("#define", "static"))]
    ['#define ZV10_LEN 33', 'static const float zv10_taps[33] = {']
    """
    if format not in EXPORT_FORMATS:
        raise ValueError(f"format must be one of {EXPORT_FORMATS}, got {format!r}")
    if not isinstance(name, str) or not _C_IDENT.match(name):
        raise ValueError(f"name must be a C identifier ([A-Za-z_][A-Za-z0-9_]*), got {name!r}")
    if isinstance(S, DiscreteShaper):
        if not math.isclose(float(sample_rate), S.sample_rate, rel_tol=1e-12):
            raise ValueError(f"sample_rate = {sample_rate!r} differs from the DiscreteShaper's {S.sample_rate:g} Hz")
        D = S
    else:
        D = discretize(S, sample_rate, fractional)
    return _json(D, name) if format == "json" else _c(D, name)
