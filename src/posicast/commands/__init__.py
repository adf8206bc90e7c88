"""The command line's subcommands, one module each, imported only when their subcommand runs.

:mod:`posicast.cli` builds the argument parser and dispatches; it imports none of
these at start-up, so ``posicast --help`` costs no more than argparse (issue #15).
Each module here has ``run(args) -> exit status`` and imports what it computes with
at module level.  To add a subcommand: its parser lines in ``posicast.cli._build_parser``,
a module here with ``run(args)``, and one line in ``posicast.cli._COMMANDS``.
"""
