"""``posicast export``: a shaper (or its inverse) as C or JSON for a controller at a sample rate (issue #16)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from .. import _validate as v
from ..io.export import export_shaper
from ..shapers import registry  # registry.design at call time: the suite patches it to test status 70
from .figures import write_atomic
from .shaping import mode_of, shaper_params

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    """Design the shaper (continuous, or in the z plane with ``--zplane``) and write its export."""
    out = None if args.output is None else v.path_for_output(args.output, "--output", (".h", ".c", ".json", ".txt"))
    kind = args.kind.lower()
    params = shaper_params(args, kind)
    fs = v.positive(args.sample_rate, "--sample-rate")
    if args.zplane:
        stride: Any = args.stride
        if stride not in (None, "positive"):
            if not stride.isdigit():
                raise ValueError(f"--stride must be an integer >= 1 or 'positive', got {stride!r}")
            stride = v.integer(int(stride), "--stride", 1)
        params.update(sample_period=1.0 / fs, **({} if stride is None else {"stride": stride}))
    elif args.stride is not None:
        raise ValueError("--stride applies only with --zplane")
    S = registry.design(kind, mode_of(args), **params)
    text = export_shaper(S, fs, args.format, name=args.name, form=args.form, inverse=args.inverse,
                         precision=args.precision)
    if out is not None:  # atomically, as the figures: an error leaves no file
        write_atomic(out, args.output, "--output", lambda fh: fh.write(text.encode()))
    if args.json:  # one document: the shaper, and the export itself unless it went to --output
        content: Any = None if out is not None else (json.loads(text) if args.format == "json" else text)
        print(json.dumps({"shaper": S.to_dict(), "sample_rate": fs, "format": args.format, "form": args.form,
                          "inverse": args.inverse, "output": args.output, "export": content}, indent=2))
    elif out is None:
        sys.stdout.write(text)
    else:
        print(f"wrote {out}")
    return 0
