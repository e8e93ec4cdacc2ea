"""``cas-freq export-model``: the actuator as the outer loop's designer uses it, as JSON."""

from cas_freq.cli.common import (
    EXIT_OK,
    add_config_arguments,
    load_variants,
    output_path,
    terminal_progress,
    wrote,
)
from cas_freq.cli.sinedwell import (
    DEFAULT_AMPLITUDES,
    LINEAR_DEFAULT_AMPLITUDES,
    add_dwell_arguments,
    amplitudes_text,
    parse_amplitudes,
    parse_frequencies,
)
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.fileio import check_output_file, write_text_atomic


def register(commands):
    """Add the ``export-model`` sub-parser."""
    parser = commands.add_parser(
        "export-model", help="the actuator model for the outer loop's designer, as JSON",
        description="Write one variant as the designer of the loop around it (a flight-control "
        "system, a motion controller) uses it: the linear "
        "closed loop T (Padé delays) as state-space matrices and zeros/poles/gain, the "
        "sine-dwell gain and phase per amplitude, a second-order-plus-delay fit with a rate "
        "limit per amplitude, and the rate and torque envelope (docs/model.md §15).",
    )
    add_config_arguments(parser)
    parser.add_argument("--pade", type=int, default=None, metavar="N",
                        help="Padé order of both delays of the linear T (default: 6)")
    add_dwell_arguments(parser)  # the sine-dwell table's; the steps' amplitudes too
    parser.add_argument("-o", "--output", required=True, type=output_path, metavar="FILE",
                        help="the JSON file to write (replaced as a whole)")
    parser.set_defaults(handler=run)


def run(args):
    """Export one variant to ``args.output``."""
    import json

    from cas_freq.model.delay import MAX_PADE_ORDER
    from cas_freq.studies.exported_model import DEFAULT_EXPORT_PADE, export_model

    pade = DEFAULT_EXPORT_PADE if args.pade is None else args.pade
    if not 1 <= pade <= MAX_PADE_ORDER:
        shown = str(pade) if abs(pade) < 10**12 else "a huge number"
        raise CasFreqError(f"--pade: must be 1..{MAX_PADE_ORDER}, got {shown}")
    path = check_output_file(args.output, "-o")
    variants = load_variants(args)
    if len(variants) != 1:
        raise CasFreqError(f"--variant: export-model writes one variant, got {len(variants)}; "
                           "give one --variant NAME")
    loaded = variants[0]
    amplitudes = parse_amplitudes(amplitudes_text(args.amplitudes, variants, DEFAULT_AMPLITUDES,
                                                  LINEAR_DEFAULT_AMPLITUDES), variants)
    frequencies = None if args.frequencies is None else parse_frequencies(args.frequencies)
    progress = terminal_progress(f"sine-dwell {loaded.variant}")
    from cas_freq.simulation.simulator import BudgetError

    try:
        model = export_model(loaded, pade, amplitudes, frequencies,
                             feedforward=args.feedforward, progress=progress)
    except BudgetError as error:
        from cas_freq.studies.run import over_budget_reason

        raise CasFreqError(f"variant {loaded.variant}: "
                           f"{over_budget_reason(error, frequencies or ())}") from None
    if progress:
        progress.done()
    write_text_atomic(path, json.dumps(model.to_dict(), indent=1, allow_nan=False) + "\n")
    wrote(path)
    return EXIT_OK
