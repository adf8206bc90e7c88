"""``posicast qft``: QFT inner-loop model matching over seed 003's uncertain two-mass plants (issue #18).

Exit status 1 when the specification is infeasible (the result names the violated bound).
"""

from __future__ import annotations

import argparse
import json

from .. import _validate as v
from ..cases import ALL as CASES
from ..qft import PlantSet, qft_design
from .figures import pyplot, save_atomic
from .progress import working

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    """Design G for the two-mass plant set; print it (or JSON) and write the Nichols chart if asked."""
    plants = PlantSet.two_mass(v.real_in_range(args.uncertainty, "--uncertainty", 0.0, 100.0, hi_open=True))
    sections = tuple(x.strip() for x in args.structure.split(",") if x.strip())
    with working(f"QFT design over {len(plants)} plants", args.quiet):
        r = qft_design(plants, CASES["two_mass"].extras["F_m"], stability=args.stability, matching=args.matching,
                       structure=sections)
    sc = r.controller.to_scipy()
    if args.json:
        print(json.dumps({"feasible": r.feasible, "violated": list(r.violated), "margins": dict(r.margins),
                          "high_frequency_gain": r.high_frequency_gain, "parameters": dict(r.parameters),
                          "num": [float(x) for x in sc.num], "den": [float(x) for x in sc.den]}, indent=2))
    else:
        print(r.summary())
        print("G num: " + " ".join(f"{x:.10g}" for x in sc.num))
        print("G den: " + " ".join(f"{x:.10g}" for x in sc.den))
    if args.plot:
        pyplot()
        fig, _ = r.plot()
        save_atomic(fig, args.plot, "--plot")
    return 0 if r.feasible else 1
