"""``cas-freq compare``: variants of one or more configs side by side (HTML, Markdown, JSON)."""

import shlex

from cas_freq.cli.common import EXIT_OK, label_progress
from cas_freq.cli.report import DEFAULT_AMPLITUDES, DEFAULT_FREQUENCIES, settings_from_args


def register(commands):
    """Add the ``compare`` sub-parser."""
    parser = commands.add_parser(
        "compare", help="overlaid figures, a difference table and the verdict matrix of variants",
        description="Compare variants of one or more configs: overlaid Bode, step and "
        "bandwidth-vs-amplitude figures, every figure with its difference to the first (the "
        "baseline), and the requirement verdict matrix; index.html, report.md, results.json.",
    )
    parser.add_argument("configs", nargs="+", metavar="CONFIG", help="config YAML files")
    which = parser.add_mutually_exclusive_group()
    which.add_argument(
        "--variants", default=None, metavar="A,B,...",
        help="variants to take from each config, by name (default: all of them)",
    )
    which.add_argument(
        "--all-variants", action="store_true",
        help="take base and every variant of each config (the default)",
    )
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
        help="override a dotted key in every compared variant (repeatable)",
    )
    parser.add_argument(
        "-o", "--output", default=None, metavar="DIR",
        help="output folder (default: reports/compare-<config names>[-<variants>]/)",
    )
    parser.add_argument("--amplitudes", default=DEFAULT_AMPLITUDES, metavar="A,B,...",
                        help=f"fin amplitudes with units (default: {DEFAULT_AMPLITUDES})")
    parser.add_argument("--frequencies", default=DEFAULT_FREQUENCIES,
                        metavar="MIN:MAX:N|F1,F2,...",
                        help="sine-dwell frequencies in rad/s (default: 16 log-spaced over "
                        "0.1..5 x each variant's linear bandwidth)")
    parser.add_argument("--pade-order", type=int, default=10, metavar="N",
                        help="Padé order of the linear steps (default: 10)")
    parser.add_argument("--png", action="store_true", help="also write every figure as PNG")
    parser.set_defaults(handler=run)


def parse_variant_list(text):
    """``a,b`` → ['a', 'b'] (no empty names)."""
    from cas_freq.exceptions import CasFreqError

    names = [part.strip() for part in text.split(",")]
    if not text.strip() or any(not name for name in names):
        raise CasFreqError(f"--variants: expected names such as base,fitted, got {text!r}")
    return list(dict.fromkeys(names))


def run(args):
    """Build the comparison; print the path of its index.html."""
    from cas_freq.cli.report import selected_variants
    from cas_freq.report.compare import build_compare

    names = parse_variant_list(args.variants) if args.variants is not None else []
    variants = []
    for config in args.configs:
        variants += selected_variants(config, names, args.overrides)
    settings = settings_from_args(args)
    if args.output is not None or len(variants) >= 2:
        from cas_freq.fileio import check_output_dir
        from cas_freq.report.compare import default_compare_dir

        check_output_dir(args.output if args.output is not None
                         else default_compare_dir(variants, names or None), "-o")

    progress = label_progress("compare")
    tail = [*args.configs]
    if args.variants is not None:
        tail += ["--variants", ",".join(names)]
    for text in args.overrides:
        tail += ["--set", text]
    for option, value, default in (("--amplitudes", args.amplitudes, DEFAULT_AMPLITUDES),
                                   ("--frequencies", args.frequencies, DEFAULT_FREQUENCIES),
                                   ("--pade-order", args.pade_order, 10)):
        if value != default:
            tail += [option, str(value)]
    command = " ".join(["cas-freq", "compare", *(shlex.quote(str(a)) for a in tail)])
    folder = build_compare(variants, args.output, settings=settings, png=args.png,
                           command=command, selected=names or None, progress=progress)
    print(folder / "index.html")
    return EXIT_OK
