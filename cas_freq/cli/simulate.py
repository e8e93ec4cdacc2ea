"""``cas-freq simulate``: the nonlinear step, its figures and the second-order fit; a profile
move with and without feed-forward; or any command from a CSV table."""

from cas_freq.cli.common import (
    EXIT_OK,
    add_config_arguments,
    load_variants,
    output_path,
    print_json,
    refuse_linear,
    several_variants,
    terminal_progress,
    wrote,
)
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.fileio import check_output_file, write_text_atomic
from cas_freq.core.output import ANGLE, output_step, output_unit


def register(commands):
    """Add the ``simulate`` sub-parser."""
    parser = commands.add_parser(
        "simulate", help="nonlinear step response (figures, second-order fit) or a CSV command",
        description="Nonlinear time-domain simulation of the output (limits, anti-windup, exact "
        "delays): a step with its figures and second-order fit, or a command table.",
    )
    add_config_arguments(parser)
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument(
        "--step", metavar="STEP", help="output step with a unit, e.g. 10deg or 0.1rad (a linear "
        "output: 5mm)",
    )
    what.add_argument(
        "--command", metavar="FILE",
        help="output command from a CSV of time [s], angle [deg] (optional header; held after "
        "its last point)",
    )
    what.add_argument(
        "--profile", metavar="DIST",
        help="trapezoidal profile move of DIST at the output (e.g. 10deg), as the drive's profile "
        "position mode moves; needs --velocity and --acceleration",
    )
    parser.add_argument("--velocity", metavar="V",
                        help="profile velocity limit at the output, e.g. 2000deg/s (motor side: x "
                        "the gear ratio)")
    parser.add_argument("--acceleration", metavar="A",
                        help="profile acceleration limit at the output, e.g. 1e5deg/s^2")
    parser.add_argument("--deceleration", metavar="D",
                        help="profile deceleration limit at the output (default: --acceleration)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--csv", metavar="FILE", type=output_path,
                        help="write the time series to FILE (for several variants: FILE's "
                        "stem.<variant>.csv per variant, e.g. out.base.csv, each path said on "
                        "stderr)")
    parser.set_defaults(handler=run)


def run(args):
    """Simulate for the selected variants; print a table or JSON, write CSV."""
    if args.csv is not None:
        check_output_file(args.csv, "--csv")
    from cas_freq.report.text import command_table, step_table
    from cas_freq.studies.run import (
        command_run,
        command_run_dict,
        step_csv_name,
        step_run_csv,
        step_run_dict,
        step_runs,
    )

    _profile(args, None)  # its options refused before the config is read
    variants = load_variants(args)
    move = _profile(args, variants)
    if args.csv and len(variants) > 1:
        for loaded in variants:
            check_output_file(step_csv_name(args.csv, loaded, len(variants)), "--csv")
    progress = terminal_progress("simulate")
    if args.command:
        from cas_freq.simulation.commands import read_command_csv

        for loaded in variants:
            refuse_linear(loaded, "--command")
        command = read_command_csv(args.command)
        runs = [command_run(loaded, command, progress=progress) for loaded in variants]
        to_dict, to_table = command_run_dict, command_table
    elif move is not None:
        from cas_freq.report.profile import profile_table
        from cas_freq.studies.profile_run import profile_run_dict, profile_runs

        runs = profile_runs(variants, move, progress=progress)
        to_dict, to_table = profile_run_dict, profile_table
    else:
        runs = step_runs(variants, output_step(args.step, "--step", variants),
                         progress=progress)
        to_dict, to_table = step_run_dict, step_table
    if progress:
        progress.done()
    if args.csv:
        for result in runs:
            path = step_csv_name(args.csv, result, len(runs))
            write_text_atomic(path, step_run_csv(result))
            if len(runs) > 1:  # a name of cas-freq's making: say it
                wrote(path)
    if args.json:
        data = [to_dict(result) for result in runs]
        print_json(data if several_variants(args) else data[0])
    else:
        print("\n\n".join(to_table(result) for result in runs))
    return EXIT_OK


def _profile(args, variants):
    """The :class:`~cas_freq.simulation.commands.Profile` of ``--profile`` and its limits, or
    None without ``--profile`` (when the limits must not be given either); ``variants``: the
    loaded variants, whose output's kind says how the move is read (None: check the options
    only, the move as an angle)."""
    limits = {"velocity": args.velocity, "acceleration": args.acceleration,
              "deceleration": args.deceleration}
    if args.profile is None:
        given = [f"--{name}" for name, value in limits.items() if value is not None]
        if given:
            raise CasFreqError(f"{', '.join(given)}: only with --profile DIST (a profile move)")
        return None
    missing = [f"--{name}" for name in ("velocity", "acceleration") if limits[name] is None]
    if missing:
        raise CasFreqError(f"--profile: needs {' and '.join(missing)} (e.g. --profile 10deg "
                           "--velocity 2000deg/s --acceleration 1e5deg/s^2)")
    from cas_freq.studies.profile_run import make_profile

    units = {output_unit(loaded.params) for loaded in variants or ()}
    if len(units) > 1:
        raise CasFreqError("--profile: the selected variants mix rotary and linear outputs; "
                           "select one kind with --variant")
    if variants is None:
        return None
    return make_profile(args.profile, **limits,
                        names={"distance": "--profile", **{k: f"--{k}" for k in limits}},
                        unit=units.pop() if units else ANGLE)
