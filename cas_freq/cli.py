"""Command-line interface: ``cas-freq <command> ...`` (also ``python -m cas_freq``).

Exit status: 0 success, 1 a failed requirement, 2 bad input or config (one line on stderr, no
traceback).
"""

import argparse
import json
import math
import sys

from cas_freq import __version__
from cas_freq.exceptions import CasFreqError

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


class _Parser(argparse.ArgumentParser):
    """argparse with usage errors exiting 2 (as argparse does) and a one-line message."""

    def error(self, message):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def _frequency_range(text):
    try:
        low, high = (float(part) for part in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected MIN:MAX in rad/s, e.g. 0.01:1e6, got {text!r}"
        ) from None
    if not 0 < low < high < float("inf"):
        raise argparse.ArgumentTypeError(f"need 0 < MIN < MAX, got {text!r}")
    return low, high


def _add_config_arguments(parser):
    parser.add_argument(
        "config", nargs="?", default=None,
        help="config YAML (default: the shipped configs/qt_cas.yaml)",
    )
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--variant", default="base", help="variant to use (default: base)")
    which.add_argument("--all-variants", action="store_true", help="base and every variant")
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
        help="override a dotted key after the variant, e.g. position_loop.Kp=5 or "
        "current_loop.delay='0.1 ms' (repeatable)",
    )


def build_parser():
    """The argument parser of ``cas-freq``."""
    parser = _Parser(prog="cas-freq", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"cas-freq {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    analyze = commands.add_parser(
        "analyze", help="margins, bandwidth and stability of each loop",
        description="Every frequency-domain figure of MODEL.md for one or all variants.",
    )
    _add_config_arguments(analyze)
    analyze.add_argument(
        "--delay", default="exact", metavar="exact|pade:N",
        help="delay model for the frequency responses (default: exact)",
    )
    analyze.add_argument(
        "--pade-study", type=int, default=0, metavar="N",
        help="also tabulate the headline figures at Padé orders 1..N beside exact",
    )
    analyze.add_argument(
        "--range", dest="frequency_range", type=_frequency_range, default=None,
        metavar="MIN:MAX", help="analysed frequency range in rad/s (default: 0.01:1e6)",
    )
    analyze.add_argument("--json", action="store_true", help="print JSON instead of a table")
    analyze.set_defaults(handler=_run_analyze)

    simulate = commands.add_parser(
        "simulate", help="nonlinear step response, its figures and second-order fit",
        description="Nonlinear time-domain step of the fin (limits, anti-windup, exact delays).",
    )
    _add_config_arguments(simulate)
    simulate.add_argument(
        "--step", required=True, metavar="ANGLE",
        help="fin step with a unit, e.g. 10deg or 0.1rad",
    )
    simulate.add_argument("--json", action="store_true", help="print JSON instead of a table")
    simulate.add_argument("--csv", metavar="FILE", help="write the time series to FILE")
    simulate.set_defaults(handler=_run_simulate)
    return parser


def _load(args):
    from cas_freq.config import load_all_variants, load_variant, parse_set_option

    overrides = [parse_set_option(text) for text in args.overrides]
    if args.all_variants:
        return load_all_variants(args.config, overrides)
    return [load_variant(args.config, args.variant, overrides)]


def _run_analyze(args):
    from cas_freq.analysis import analyze, to_dict
    from cas_freq.analysis.frequency import DEFAULT_RANGE_RAD_S
    from cas_freq.model import DelayModel
    from cas_freq.report.text import analysis_table

    delay = DelayModel.parse(args.delay)
    if args.pade_study < 0:
        raise CasFreqError(f"--pade-study: must be >= 0, got {args.pade_study}")
    frequency_range = args.frequency_range or DEFAULT_RANGE_RAD_S
    variants = _load(args)
    results = [
        analyze(loaded, delay, frequency_range, pade_orders=args.pade_study)
        for loaded in variants
    ]
    if args.json:
        data = [to_dict(result) for result in results]
        payload = data if args.all_variants else data[0]
        print(json.dumps(payload, indent=2, allow_nan=False))
    else:
        print("\n\n".join(analysis_table(result) for result in results))
    return EXIT_OK


def _angle(text, option):
    """An angle with a unit ('10deg', '0.1 rad') in radians."""
    from cas_freq.config.units import registry, to_si

    try:
        value = to_si(text, "rad")  # raises ValueError for text pint cannot read
        if registry().Quantity(text).unitless:
            raise ValueError("it has no unit")
    except (ValueError, TypeError) as exc:
        raise CasFreqError(f"{option}: expected an angle with a unit such as 10deg, got "
                           f"{text!r} ({exc})") from None
    if not value != 0 or abs(value) > math.pi / 2:
        raise CasFreqError(
            f"{option}: must be non-zero and within ±90 deg at the fin, got {text!r}"
        )
    return value


def _run_simulate(args):
    from cas_freq.fileio import write_text_atomic
    from cas_freq.report.text import step_table
    from cas_freq.simulation.run import step_csv_name, step_run, step_run_csv, step_run_dict

    amplitude = _angle(args.step, "--step")
    runs = [step_run(loaded, amplitude) for loaded in _load(args)]
    if args.csv:
        for run in runs:
            write_text_atomic(step_csv_name(args.csv, run, len(runs)), step_run_csv(run))
    if args.json:
        data = [step_run_dict(run) for run in runs]
        print(json.dumps(data if args.all_variants else data[0], indent=2, allow_nan=False))
    else:
        print("\n\n".join(step_table(run) for run in runs))
    return EXIT_OK


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
