"""``cas-freq sinedwell``: the amplitude-dependent frequency response of the nonlinear loop."""

from cas_freq.cli.common import (
    EXIT_OK,
    add_config_arguments,
    load_variants,
    print_json,
    several_variants,
    terminal_progress,
)
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.output import angle, output_json, output_step, output_unit

#: Amplitudes when none are given: small signal, mid, and the report's 10 deg step size.
DEFAULT_AMPLITUDES = "0.5deg,2deg,10deg"


def register(commands):
    """Add the ``sinedwell`` sub-parser."""
    parser = commands.add_parser(
        "sinedwell", help="nonlinear frequency response per amplitude, and bandwidth three ways",
        description="Sine-dwell the nonlinear loop at each amplitude and frequency, and put the "
        "linear, sine-dwell and step-fit bandwidths side by side.",
    )
    add_config_arguments(parser)
    add_dwell_arguments(parser)
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.set_defaults(handler=run)


def add_dwell_arguments(parser):
    """The sine dwell's ``--amplitudes``, ``--frequencies`` and ``--feedforward`` (sinedwell,
    export-model)."""
    parser.add_argument(
        "--amplitudes", default=DEFAULT_AMPLITUDES, metavar="A,B,...",
        help=f"output amplitudes with units (default: {DEFAULT_AMPLITUDES}; a linear output: "
        f"{LINEAR_DEFAULT_AMPLITUDES})",
    )
    parser.add_argument(
        "--frequencies", default=None, metavar="MIN:MAX:N|F1,F2,...",
        help="frequencies in rad/s: N log-spaced from MIN to MAX, or a list (default: 16 "
        "log-spaced over 0.1..5 x each variant's linear bandwidth, as the report)",
    )
    parser.add_argument(
        "--feedforward", action="store_true",
        help="let the velocity/acceleration feed-forward act on the sines (default: off, as in "
        "docs/model.md's T)",
    )


#: The defaults at a linear output (``gear.screw_lead``): lengths.
LINEAR_DEFAULT_AMPLITUDES = "0.1mm,0.5mm,2mm"


def amplitudes_text(text, variants, default, linear_default):
    """``text``, or at a linear output the linear default where ``text`` is the rotary
    ``default`` (an option left unset)."""
    linear = any(output_unit(loaded.params).linear for loaded in variants or ())
    return linear_default if linear and text == default else text


def parse_amplitudes(text, variants=None):
    """Comma-separated output amplitudes with units → list in SI: angles [rad], or lengths [m]
    at a linear output of ``variants`` (:func:`cas_freq.core.output.output_step`)."""
    parts = [part.strip() for part in text.split(",")]
    if not text.strip() or any(not part for part in parts):
        example = "angles such as 0.5deg,2deg,10deg"
        if variants and any(getattr(v.params, "linear", False) for v in variants):
            example = f"lengths such as {LINEAR_DEFAULT_AMPLITUDES}"
        raise CasFreqError(f"--amplitudes: expected {example}, got {text!r}")
    if variants is None:
        return [abs(angle(part, "--amplitudes")) for part in parts]
    return [abs(output_step(part, "--amplitudes", variants)) for part in parts]


def parse_frequencies(text):
    """``MIN:MAX:N`` (log-spaced) or ``F1,F2,...`` in rad/s → sorted list of rad/s."""
    from cas_freq.config.requirement import parse_frequency_spec

    try:
        return list(parse_frequency_spec(text))
    except ValueError as exc:
        raise CasFreqError(f"--frequencies: {exc}") from None


def run(args):
    """Sine-dwell the selected variants; print a table or JSON."""
    from cas_freq.analysis import analyze
    from cas_freq.config.wording import OutputWords
    from cas_freq.report.text import sinedwell_table
    from cas_freq.simulation.simulator import BudgetError
    from cas_freq.simulation.sinedwell import dwell_frequencies
    from cas_freq.studies.run import over_budget_reason, sinedwell_run, sinedwell_run_dict

    variants = load_variants(args)
    amplitudes = parse_amplitudes(amplitudes_text(args.amplitudes, variants, DEFAULT_AMPLITUDES,
                                                  LINEAR_DEFAULT_AMPLITUDES), variants)
    frequencies = None if args.frequencies is None else parse_frequencies(args.frequencies)
    data, words = [], []
    for loaded in variants:
        progress = terminal_progress(f"sine-dwell {loaded.variant}")
        analysis = analyze(loaded)
        try:  # by default the report's grid; none for a loop that is not stable
            result = sinedwell_run(
                loaded, amplitudes, frequencies, feedforward=args.feedforward,
                progress=progress, analysis=analysis,
            )
        except BudgetError as error:  # refused before anything was simulated
            grid = frequencies or dwell_frequencies(analysis)
            raise CasFreqError(f"variant {loaded.variant}: {over_budget_reason(error, grid)}"
                               ) from None
        if progress:
            progress.done()
        data.append(output_json(sinedwell_run_dict(result), output_unit(loaded.params)))
        words.append(OutputWords.of(loaded.params))
    if args.json:
        print_json(data if several_variants(args) else data[0])
    else:
        print("\n\n".join(sinedwell_table(item, named)
                            for item, named in zip(data, words, strict=True)))
    return EXIT_OK
