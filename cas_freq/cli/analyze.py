"""``cas-freq analyze``: every frequency-domain figure of docs/model.md."""

import argparse

from cas_freq.cli.common import (
    EXIT_OK,
    add_config_arguments,
    load_variants,
    print_json,
    several_variants,
)
from cas_freq.core.exceptions import CasFreqError

#: Accepted --range: within MIN_RAD_S..MAX_RAD_S, spanning at most MAX_DECADES decades.
MIN_RAD_S, MAX_RAD_S, MAX_DECADES = 1e-6, 1e9, 12


def frequency_range(text):
    """argparse type for ``MIN:MAX`` in rad/s."""
    try:
        low, high = (float(part) for part in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected MIN:MAX in rad/s, e.g. 0.01:1e6, got {text!r}"
        ) from None
    if not 0 < low < high < float("inf"):
        raise argparse.ArgumentTypeError(f"need 0 < MIN < MAX, got {text!r}")
    if not (MIN_RAD_S <= low and high <= MAX_RAD_S and high / low <= 10.0**MAX_DECADES):
        raise argparse.ArgumentTypeError(
            f"need {MIN_RAD_S:g} <= MIN < MAX <= {MAX_RAD_S:g} rad/s and at most {MAX_DECADES} "
            f"decades, got {text!r}"
        )
    return low, high


def register(commands):
    """Add the ``analyze`` sub-parser."""
    parser = commands.add_parser(
        "analyze", help="margins, bandwidth and stability of each loop",
        description="Every frequency-domain figure of docs/model.md for one or all variants.",
    )
    add_config_arguments(parser)
    parser.add_argument(
        "--delay", default="exact", metavar="exact|pade:N",
        help="delay model for the frequency responses (default: exact)",
    )
    parser.add_argument(
        "--pade-study", type=int, default=0, metavar="N",
        help="also tabulate the headline figures at Padé orders 1..N beside exact",
    )
    parser.add_argument(
        "--range", dest="frequency_range", type=frequency_range, default=None,
        metavar="MIN:MAX", help="analysed frequency range in rad/s (default: 0.01:1e6)",
    )
    parser.add_argument(
        "--limit-cycles", action="store_true",
        help="check each predicted limit cycle by a nonlinear simulation started near it",
    )
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.set_defaults(handler=run)


def run(args):
    """Analyse the selected variants and print a table or JSON."""
    from cas_freq.analysis import analyze, to_dict
    from cas_freq.analysis.frequency import DEFAULT_RANGE_RAD_S
    from cas_freq.model import DelayModel
    from cas_freq.report.text import analysis_table

    delay = DelayModel.parse(args.delay)
    from cas_freq.model.delay import MAX_PADE_ORDER

    if not 0 <= args.pade_study <= MAX_PADE_ORDER:
        shown = str(args.pade_study) if abs(args.pade_study) < 10**12 else "a huge number"
        raise CasFreqError(f"--pade-study: must be 0..{MAX_PADE_ORDER}, got {shown}"
                           if args.pade_study > 0 else
                           f"--pade-study: must be >= 0, got {shown}")
    frequency_range_rad_s = args.frequency_range or DEFAULT_RANGE_RAD_S
    results = [
        analyze(loaded, delay, frequency_range_rad_s, pade_orders=args.pade_study,
                limit_cycle_check=args.limit_cycles)
        for loaded in load_variants(args)
    ]
    if args.json:
        data = [to_dict(result) for result in results]
        print_json(data if several_variants(args) else data[0])
    else:
        print("\n\n".join(analysis_table(result) for result in results))
    return EXIT_OK
