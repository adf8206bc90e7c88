"""``posicast sweep ...`` (issue #19): runs :func:`posicast.sweeps.command.run_sweep` with the CLI's atomic figure writer."""

from __future__ import annotations

import argparse

from ..sweeps.command import run_sweep
from .figures import save_atomic

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    """Run the sweep named on the command line (chart, montecarlo, calibrate or function)."""
    return run_sweep(args, lambda fig, out: save_atomic(fig, out, "--plot"))
