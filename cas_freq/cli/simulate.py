"""``cas-freq simulate``: the nonlinear step, its figures and the second-order fit."""

from cas_freq.cli.common import EXIT_OK, add_config_arguments, angle, load_variants, print_json


def register(commands):
    """Add the ``simulate`` sub-parser."""
    parser = commands.add_parser(
        "simulate", help="nonlinear step response, its figures and second-order fit",
        description="Nonlinear time-domain step of the fin (limits, anti-windup, exact delays).",
    )
    add_config_arguments(parser)
    parser.add_argument(
        "--step", required=True, metavar="ANGLE",
        help="fin step with a unit, e.g. 10deg or 0.1rad",
    )
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--csv", metavar="FILE", help="write the time series to FILE")
    parser.set_defaults(handler=run)


def run(args):
    """Simulate the step for the selected variants; print a table or JSON, write CSV."""
    from cas_freq.fileio import write_text_atomic
    from cas_freq.report.text import step_table
    from cas_freq.simulation.run import step_csv_name, step_run, step_run_csv, step_run_dict

    amplitude = angle(args.step, "--step")
    runs = [step_run(loaded, amplitude) for loaded in load_variants(args)]
    if args.csv:
        for result in runs:
            write_text_atomic(step_csv_name(args.csv, result, len(runs)), step_run_csv(result))
    if args.json:
        data = [step_run_dict(result) for result in runs]
        print_json(data if args.all_variants else data[0])
    else:
        print("\n\n".join(step_table(result) for result in runs))
    return EXIT_OK
