"""Command-line interface: ``cas-freq <command> ...`` (also ``python -m cas_freq``).

Each command lives in its own module with ``register(commands)`` and a handler; the heavy
imports happen inside the handlers, so ``cas-freq verify`` never loads matplotlib. This module
itself imports nothing at its top but ``sys`` and two small modules of the package, so that a
Ctrl-C at any later point of the start, the imports included, is handled by :func:`main`.

When CONFIG is omitted, a command that ran says on stderr that it used the shipped config
(one line, not with ``-q``). Exit status: 0 success, 1 a failed requirement, 2 bad input or
config (one line on stderr, no traceback), 130 interrupted (Ctrl-C: one line on stderr;
outputs are written atomically, so the previous file or report is left as it was and no
temporary file remains; also where the Ctrl-C landed in code Python cannot interrupt, such as
numba's compiler calling back from C: it is raised again once that code returns), 143
terminated (SIGTERM; 129 for SIGHUP: handled as Ctrl-C, :mod:`cas_freq.cli.signals`).
"""

import sys

from cas_freq import __version__
from cas_freq.core.exceptions import CasFreqError

__all__ = [
    "EXIT_BAD_INPUT", "EXIT_FAILED", "EXIT_INTERRUPTED", "EXIT_OK", "build_parser",
    "join_negative_values", "main",
]

#: Exit status after Ctrl-C (128 + SIGINT, as shells report it); after SIGTERM or SIGHUP it is
#: likewise 128 + the signal's number.
EXIT_INTERRUPTED = 130

#: The commands, in the order ``--help`` lists them; each lives in the module of its name
#: (``-`` spelt ``_``: ``export-model`` in ``cas_freq.cli.export_model``).
COMMANDS = ("analyze", "simulate", "sinedwell", "fit", "verify", "report", "compare", "sweep",
            "montecarlo", "worstcase", "tune", "epos4", "export-model", "design")


def __getattr__(name):
    # the exit codes of cas_freq.cli.common, imported on first use (not at this module's top)
    if name in ("EXIT_BAD_INPUT", "EXIT_FAILED", "EXIT_OK"):
        from cas_freq.cli import common

        return getattr(common, name)
    raise AttributeError(f"module 'cas_freq.cli' has no attribute {name!r}")


def build_parser():
    """The argument parser of ``cas-freq``."""
    import importlib

    from cas_freq.cli.common import Parser

    parser = Parser(prog="cas-freq", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"cas-freq {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for name in COMMANDS:
        importlib.import_module(f"cas_freq.cli.{name.replace('-', '_')}").register(commands)
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

#: numpy's transparent huge pages off unless the user set them: numpy asks the kernel for huge
#: pages on every large array, and where the kernel defragments on request (``defrag`` set to
#: ``madvise``, this project's machine) the first write into a fresh recording buffer stalls
#: on compaction (1-3 s for an 81 MB sine-dwell batch). ``cas-freq report`` of the shipped
#: config, alternated: 29.0 / 34.9 s wall, 17.4 / 19.3 s system CPU with them; 25.8 / 20.4 s,
#: 9.9 / 4.8 s without. Only effective before numpy is first imported.
HUGE_PAGES_VARIABLE = "NUMPY_MADVISE_HUGEPAGE"


def limit_blas_threads(environ=None):
    """Set each of :data:`BLAS_THREAD_VARIABLES` to 1, and :data:`HUGE_PAGES_VARIABLE` to 0,
    where it is not set: the process's settings, before numpy loads."""
    import os

    environ = os.environ if environ is None else environ
    for name in BLAS_THREAD_VARIABLES:
        environ.setdefault(name, "1")
    environ.setdefault(HUGE_PAGES_VARIABLE, "0")


def main(argv=None):
    """Run ``cas-freq``; returns the exit status."""
    limit_blas_threads()
    command = "cas-freq"
    try:
        from cas_freq.cli.common import (
            EXIT_BAD_INPUT,
            EXIT_OK,
            set_quiet,
            shipped_config_note,
        )
        from cas_freq.cli.signals import interrupts_not_lost, terminate_as_interrupt
        from cas_freq.core import jit

        with terminate_as_interrupt(), interrupts_not_lost():
            try:
                parser = build_parser()
                args = parser.parse_args(join_negative_values(
                    parser, sys.argv[1:] if argv is None else list(argv)))
                command = f"cas-freq {args.command_name}"
                set_quiet(getattr(args, "quiet", False))
                if not getattr(args, "quiet", False):
                    jit.compile_messages(_say)
                status = args.handler(args)
                shipped_config_note()
                return status
            except CasFreqError as exc:
                print(f"{command}: error: {exc}", file=sys.stderr)
                return EXIT_BAD_INPUT
            except BrokenPipeError:
                return EXIT_OK
            finally:  # after an interrupt its one line only, no summary
                _compile_summary(say=not isinstance(sys.exc_info()[1], KeyboardInterrupt))
                set_quiet(False)  # --quiet is per call (main may run more than once)
    except KeyboardInterrupt as exc:  # Ctrl-C, SIGTERM, SIGHUP
        return _interrupted(command, exc)
    except Exception as exc:
        # a Ctrl-C while a C extension module initialises (matplotlib's, at import) surfaces
        # as "ImportError: initialization failed" raised from the KeyboardInterrupt
        interrupt = _raised_by_interrupt(exc)
        if interrupt is None:
            raise
        return _interrupted(command, interrupt)


def _say(text):
    """One line on stderr (the first-compilation messages of :mod:`cas_freq.core.jit`)."""
    print(text, file=sys.stderr, flush=True)


def _compile_summary(say=True):
    """Say how long the kernels compiled, if they did while the messages went to stderr (not
    with ``--quiet``) and ``say`` is true, and send later messages to the logger again."""
    from cas_freq.core import jit

    summary = jit.compile_summary()
    if say and summary is not None and jit._SAY is _say:
        _say(summary)
    jit.compile_messages(None)


#: An option argument that starts like a negative number: ``-5deg``, ``-0.1rad``, ``-1:2:3``,
#: ``-.5``. No option of cas-freq starts with a dash and a digit, so it is never an option.
NEGATIVE_VALUE = r"-\.?[0-9]"


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
    import re

    negative_value = re.compile(NEGATIVE_VALUE)
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
            if value is not None and negative_value.match(value):
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
    """The KeyboardInterrupt in the chain of causes and contexts of ``exc``, or None."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _interrupted(command, interrupt):
    """One line on stderr after Ctrl-C (or SIGTERM, SIGHUP: ``interrupt`` is then a
    :class:`cas_freq.cli.signals.Terminated`); returns the exit status."""
    signum = getattr(interrupt, "signum", None)
    if signum is None:
        what = "interrupted"
    else:
        import signal

        what = f"terminated ({signal.Signals(signum).name})"
    try:
        print(f"\n{command}: {what}" if sys.stderr.isatty() else f"{command}: {what}",
              file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass
    return EXIT_INTERRUPTED if signum is None else 128 + signum
