"""``cas-freq report``: index.html, report.md, results.json and the figures of a config."""

from cas_freq.cli.common import (
    EXIT_OK,
    add_config_arguments,
    label_progress,
    load_variants,
    output_path,
)
from cas_freq.cli.sinedwell import amplitudes_text, parse_amplitudes, parse_frequencies
from cas_freq.report.outdir import check_output_dir

#: Amplitudes when none are given: small signal, two intermediate sizes, the report's 10 deg.
DEFAULT_AMPLITUDES = "0.5deg,2deg,5deg,10deg"
#: The default amplitudes at a linear output (``gear.screw_lead``).
LINEAR_DEFAULT_AMPLITUDES = "0.1mm,0.5mm,1mm,5mm"
#: Sine-dwell frequencies when none are given: derived from each variant's loop (16
#: log-spaced over 0.1..5 x its linear bandwidth, cas_freq.report.data.ReportSettings).
DEFAULT_FREQUENCIES = None


def register(commands):
    """Add the ``report`` sub-parser."""
    parser = commands.add_parser(
        "report", help="HTML + Markdown + JSON report with every figure of a config's variants",
        description="Write a folder with a self-contained index.html, report.md, results.json "
        "and the figures (SVG) of every variant of a config (default: all of them).",
    )
    add_config_arguments(parser, all_by_default=True)
    parser.add_argument(
        "-o", "--output", default=None, metavar="DIR", type=output_path,
        help="report folder (default: reports/<config name>/); replaced as a whole",
    )
    parser.add_argument(
        "--amplitudes", default=DEFAULT_AMPLITUDES, metavar="A,B,...",
        help=f"sine-dwell and step amplitudes at the output, with units; the smallest and the "
        f"largest are the steps shown (default: {DEFAULT_AMPLITUDES}; a linear output: "
        f"{LINEAR_DEFAULT_AMPLITUDES})",
    )
    parser.add_argument(
        "--frequencies", default=DEFAULT_FREQUENCIES, metavar="MIN:MAX:N|F1,F2,...",
        help="sine-dwell frequencies in rad/s (default: 16 log-spaced over 0.1..5 x each "
        "variant's linear bandwidth)",
    )
    parser.add_argument(
        "--pade-order", type=int, default=10, metavar="N",
        help="Padé order of the linear step and highest order of the Padé table (default: 10)",
    )
    parser.add_argument("--png", action="store_true", help="also write every figure as PNG")
    parser.set_defaults(handler=run)


def settings_from_args(args, variants=None):
    """ReportSettings from the command-line options (amplitudes read as ``variants``' output
    takes them: lengths at a linear output, whose default is
    :data:`LINEAR_DEFAULT_AMPLITUDES`)."""
    from cas_freq.model.delay import DelayModel
    from cas_freq.report.data import ReportSettings

    DelayModel(args.pade_order)  # validates 1..MAX_PADE_ORDER with a clear message
    text = amplitudes_text(args.amplitudes, variants, DEFAULT_AMPLITUDES,
                           LINEAR_DEFAULT_AMPLITUDES)
    return ReportSettings(
        amplitudes_rad=tuple(parse_amplitudes(text, variants)),
        frequencies_rad_s=(None if args.frequencies is None
                           else tuple(parse_frequencies(args.frequencies))),
        pade_order=args.pade_order,
    )


def command_text(argv_tail):
    """``cas-freq report ...`` as the report shows it (the options as given)."""
    import shlex

    return " ".join(["cas-freq", "report", *(shlex.quote(a) for a in argv_tail)])


def run(args):
    """Build the report; print the folder it was written to."""
    from cas_freq.report.build import build_report

    variants = load_variants(args, all_by_default=True)
    settings = settings_from_args(args, variants)

    if args.output is not None:
        check_output_dir(args.output, "-o")
    elif variants:
        from cas_freq.report.build import default_report_dir

        check_output_dir(default_report_dir(variants[0].params.name), "-o")

    progress = label_progress("report")
    folder = build_report(variants, args.output, settings=settings, png=args.png,
                          command=command_text(_argv_tail(args)), progress=progress,
                          notice=_notice)
    print(folder / "index.html")
    return EXIT_OK


def _argv_tail(args):
    """The options that shaped the report, rebuilt from ``args`` (stable, no -o)."""
    tail = [] if args.config is None else [str(args.config)]
    for name in args.variants:
        tail += ["--variant", name]
    for text in args.overrides:
        tail += ["--set", text]
    if args.amplitudes != DEFAULT_AMPLITUDES:
        tail += ["--amplitudes", args.amplitudes]
    if args.frequencies != DEFAULT_FREQUENCIES:
        tail += ["--frequencies", args.frequencies]
    if args.pade_order != 10:
        tail += ["--pade-order", str(args.pade_order)]
    if args.png:
        tail.append("--png")
    return tail


def _notice(text):
    """A figure that was not computed: one line on stderr (the report is still written)."""
    import sys

    print(f"cas-freq report: warning: {text}", file=sys.stderr, flush=True)
