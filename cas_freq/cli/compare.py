"""``cas-freq compare``: variants of one or more configs side by side (HTML, Markdown, JSON)."""

import shlex

from cas_freq.cli.common import (
    EXIT_OK,
    add_config_arguments,
    label_progress,
    output_path,
    selected_variants,
)
from cas_freq.cli.report import DEFAULT_AMPLITUDES, DEFAULT_FREQUENCIES, settings_from_args
from cas_freq.core.exceptions import CasFreqError
from cas_freq.report.outdir import check_output_dir


def register(commands):
    """Add the ``compare`` sub-parser."""
    parser = commands.add_parser(
        "compare", help="overlaid figures, a difference table and the verdict matrix of variants",
        description="Compare variants of one or more configs: overlaid Bode, step and "
        "bandwidth-vs-amplitude figures, every figure with its difference to the first (the "
        "baseline), and the requirement verdict matrix; index.html, report.md, results.json.",
    )
    which = add_config_arguments(parser, all_by_default=True, several_configs=True)
    which.add_argument(
        "--variants", dest="variant_list", default=None, metavar="A,B,...",
        help="the same as --variant A --variant B ... (comma-separated names)",
    )
    parser.add_argument(
        "-o", "--output", default=None, metavar="DIR", type=output_path,
        help="output folder (default: reports/compare-<config names>[-<variants>]/)",
    )
    parser.add_argument("--amplitudes", default=DEFAULT_AMPLITUDES, metavar="A,B,...",
                        help=f"output amplitudes with units (default: {DEFAULT_AMPLITUDES})")
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
    names = [part.strip() for part in text.split(",")]
    if not text.strip() or any(not name for name in names):
        raise CasFreqError(f"--variants: expected names such as base,fitted, got {text!r}")
    return list(dict.fromkeys(names))


def command_text(args, names):
    """``cas-freq compare ...`` as the comparison shows it: the options that shaped it, as
    given (``--all-variants``, the default, and ``-o`` left out, so the same comparison always
    shows the same line)."""
    tail = [*args.configs]
    if args.variant_list is not None:
        tail += ["--variants", ",".join(names)]
    for name in args.variants:
        tail += ["--variant", name]
    for text in args.overrides:
        tail += ["--set", text]
    for option, value, default in (("--amplitudes", args.amplitudes, DEFAULT_AMPLITUDES),
                                   ("--frequencies", args.frequencies, DEFAULT_FREQUENCIES),
                                   ("--pade-order", args.pade_order, 10)):
        if value != default:
            tail += [option, str(value)]
    return " ".join(["cas-freq", "compare", *(shlex.quote(str(a)) for a in tail)])


def run(args):
    """Build the comparison; print the path of its index.html."""
    from cas_freq.report.compare import build_compare

    names = (parse_variant_list(args.variant_list) if args.variant_list is not None
             else list(dict.fromkeys(args.variants)))
    variants = []
    for config in args.configs or [None]:
        variants += selected_variants(config, names, args.overrides, all_by_default=True)
    settings = settings_from_args(args, variants)
    if args.output is not None or len(variants) >= 2:
        from cas_freq.report.compare import default_compare_dir

        check_output_dir(args.output if args.output is not None
                         else default_compare_dir(variants, names or None), "-o")

    progress = label_progress("compare")
    folder = build_compare(variants, args.output, settings=settings, png=args.png,
                           command=command_text(args, names), selected=names or None,
                           progress=progress, notice=_notice)
    print(folder / "index.html")
    return EXIT_OK


def _notice(text):
    """A figure that was not computed: one line on stderr (the compare is still written)."""
    import sys

    print(f"cas-freq compare: warning: {text}", file=sys.stderr, flush=True)
