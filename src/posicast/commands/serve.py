"""``posicast serve``: the interactive designer in the browser (:mod:`posicast.serve`)."""

from __future__ import annotations

import argparse
import sys

from .. import _validate as v
from ..serve import missing_requirements, serve

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    missing = missing_requirements()
    if missing:
        print(f"posicast: error: the designer needs {', '.join(missing)}: pip install 'posicast[serve]'",
              file=sys.stderr)
        return 2
    port = v.integer_in_range(args.port, "--port", 0, 65535)
    if not args.host.strip():
        raise ValueError("--host must not be empty")
    serve(args.host, port, open_browser=not args.no_browser, json_line=args.json)
    return 0
