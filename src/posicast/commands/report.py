"""``posicast report DATA``: the user-first HTML report for your own resonance test(s) or plant file."""

from __future__ import annotations

import argparse
import json
import sys

from ..identification import NoModeFound
from ..report import write_report
from ..report.page import output_dir
from .progress import steps
from .figures import pyplot

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    output_dir(args.out_dir, "--out")  # checked before any work
    pyplot()  # the Agg backend before any figure is drawn
    try:
        with steps(args.quiet) as say:
            summary = write_report(args.data, args.out_dir, firmware=args.firmware, axis=args.axis, progress=say)
    except NoModeFound as exc:
        print(f"posicast: {exc}", file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps(summary.to_dict(), indent=2, ensure_ascii=False))
        return 0
    print(f"wrote {summary.index} ({len(summary.figures)} figure{'s' if len(summary.figures) != 1 else ''})")
    d = summary.details
    if summary.kind == "log":
        print("\n".join(d["config"]))
    else:
        for loop in d["loops"]:
            print(f"{loop['label']}: {'stable' if loop['stable'] else 'NOT stable'} ({loop['reason']})")
    return 0
