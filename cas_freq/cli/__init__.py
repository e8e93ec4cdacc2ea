"""Command-line interface: ``cas-freq <command> ...`` (also ``python -m cas_freq``).

Each command lives in its own module with ``register(commands)`` and a handler; the heavy
imports happen inside the handlers, so ``cas-freq verify`` never loads matplotlib.

When CONFIG is omitted, a command that ran says on stderr that it used the shipped config
(one line, not with ``-q``). Exit status: 0 success, 1 a failed requirement, 2 bad input or
config (one line on stderr, no traceback), 130 interrupted (Ctrl-C: one line on stderr;
outputs are written atomically, so the previous file or report is left as it was and no
temporary file remains).
"""

import importlib
import re
import sys

from cas_freq import __version__
from cas_freq.cli.common import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_OK,
    Parser,
    set_quiet,
    shipped_config_note,
)
from cas_freq.exceptions import CasFreqError

__all__ = [
    "EXIT_BAD_INPUT", "EXIT_FAILED", "EXIT_INTERRUPTED", "EXIT_OK", "build_parser",
    "join_negative_values", "main",
]

#: Exit status after Ctrl-C (128 + SIGINT, as shells report it).
EXIT_INTERRUPTED = 130

#: Command modules of ``cas_freq.cli``, in the order ``--help`` lists them.
COMMANDS = ("analyze", "simulate", "sinedwell", "fit", "verify", "report", "compare", "sweep",
            "montecarlo", "tune", "epos4")


def build_parser():
    """The argument parser of ``cas-freq``."""
    parser = Parser(prog="cas-freq", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"cas-freq {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for name in COMMANDS:
        importlib.import_module(f"cas_freq.cli.{name}").register(commands)
    for name, sub in commands.choices.items():
        sub.set_defaults(command_name=name)  # simulate's --command shadows args.command
        sub.add_argument("-q", "--quiet", action="store_true",
                         help="no progress on stderr (by default long runs report progress: a "
                         "bar on a terminal, else a line every 10 s)")
    return parser


#: BLAS thread pools limited to one thread unless the user set them: the toolbox's linear
#: algebra is many small matrices (5 x 5 exponentials, 3 x 3 solves), where OpenBLAS's
#: threads only contend (256 exponentials: ~2 s with the default threads on a loaded 2-core
#: machine, ~2 ms with one). Only effective before numpy is first imported.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS")


def limit_blas_threads(environ=None):
    """Set each of :data:`BLAS_THREAD_VARIABLES` to 1 where it is not set."""
    import os

    environ = os.environ if environ is None else environ
    for name in BLAS_THREAD_VARIABLES:
        environ.setdefault(name, "1")


def main(argv=None):
    """Run ``cas-freq``; returns the exit status."""
    limit_blas_threads()
    command = "cas-freq"
    try:
        parser = build_parser()
        args = parser.parse_args(join_negative_values(parser, sys.argv[1:] if argv is None
                                                      else list(argv)))
        command = f"cas-freq {args.command_name}"
        set_quiet(getattr(args, "quiet", False))
        status = args.handler(args)
        shipped_config_note()
        return status
    except CasFreqError as exc:
        print(f"{command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:
        return EXIT_OK
    except KeyboardInterrupt:
        _interrupted(command)
        return EXIT_INTERRUPTED
    except Exception as exc:
        # a Ctrl-C while a C extension module initialises (matplotlib's, at import) surfaces
        # as "ImportError: initialization failed" raised from the KeyboardInterrupt
        if not _raised_by_interrupt(exc):
            raise
        _interrupted(command)
        return EXIT_INTERRUPTED
    finally:
        set_quiet(False)  # --quiet is per call (main may run more than once in a process)


#: An option argument that starts like a negative number: ``-5deg``, ``-0.1rad``, ``-1:2:3``,
#: ``-.5``. No option of cas-freq starts with a dash and a digit, so it is never an option.
NEGATIVE_VALUE = re.compile(r"-\.?[0-9]")


def join_negative_values(parser, argv):
    """``OPT -5deg`` → ``OPT=-5deg`` wherever OPT takes one value, for every command.

    argparse reads a token that starts with ``-`` as an option unless it is a plain negative
    number (``-5``), so ``--step -5deg`` fails with "expected one argument"; the joined form is
    what argparse accepts. Which options take a value is the parser's own knowledge (each
    sub-parser's actions); an abbreviated long option (``--st``) is resolved as argparse
    resolves it, and nothing after ``--`` is touched.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The ``cas-freq`` parser (:func:`build_parser`).
    argv : list of str
        The command line after the program name.

    Returns
    -------
    list of str
    """
    commands = next((action.choices for action in parser._actions
                     if isinstance(action.choices, dict)), {})
    position = next((i for i, token in enumerate(argv) if token in commands), None)
    if position is None:
        return list(argv)
    options = commands[argv[position]]._option_string_actions
    out = argv[:position + 1]
    rest = iter(argv[position + 1:])
    for token in rest:
        if token == "--":
            out += [token, *rest]
            break
        action = _option_action(options, token)
        if action is not None and action.nargs in (None, 1):
            value = next(rest, None)
            if value is not None and NEGATIVE_VALUE.match(value):
                out.append(f"{token}={value}")
                continue
            out.append(token)
            if value is not None:
                out.append(value)
            continue
        out.append(token)
    return out


def _option_action(options, token):
    """The action of option ``token`` (exact, or a unique prefix of a long option), or None."""
    if not token.startswith("-") or "=" in token:
        return None
    if token in options:
        return options[token]
    if token.startswith("--"):
        matches = {options[name] for name in options if name.startswith(token)}
        if len(matches) == 1:
            return matches.pop()
    return None


def _raised_by_interrupt(exc):
    """True where a KeyboardInterrupt is in the chain of causes and contexts of ``exc``."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _interrupted(command):
    """One line on stderr after Ctrl-C."""
    try:
        print(f"\n{command}: interrupted" if sys.stderr.isatty() else f"{command}: interrupted",
              file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass
