"""Command-line interface: ``cas-freq <command> ...`` (also ``python -m cas_freq``).

Each command lives in its own module with ``register(commands)`` and a handler; the heavy
imports happen inside the handlers, so ``cas-freq verify`` never loads matplotlib.

Exit status: 0 success, 1 a failed requirement, 2 bad input or config (one line on stderr, no
traceback).
"""

import importlib
import sys

from cas_freq import __version__
from cas_freq.cli.common import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK, Parser
from cas_freq.exceptions import CasFreqError

__all__ = ["EXIT_BAD_INPUT", "EXIT_FAILED", "EXIT_OK", "build_parser", "main"]

#: Command modules of ``cas_freq.cli``, in the order ``--help`` lists them.
COMMANDS = ("analyze", "simulate", "sinedwell", "fit", "verify", "report", "compare", "sweep",
            "montecarlo")


def build_parser():
    """The argument parser of ``cas-freq``."""
    parser = Parser(prog="cas-freq", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"cas-freq {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for name in COMMANDS:
        importlib.import_module(f"cas_freq.cli.{name}").register(commands)
    return parser


def main(argv=None):
    """Run ``cas-freq``; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.handler(args)
    except CasFreqError as exc:
        print(f"cas-freq {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:
        return EXIT_OK
