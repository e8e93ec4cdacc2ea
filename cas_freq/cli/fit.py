"""``cas-freq fit``: the report's second-order-plus-delay fit to a measured step response."""

import dataclasses
import math

from cas_freq.cli.common import EXIT_OK, column_option, output_path, print_json
from cas_freq.cli.fit_recordings import fit_lines, rms_line, run_recordings, step_lines
from cas_freq.cli.fit_sweep import are_sweeps, run_sweep
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.fileio import json_ready
from cas_freq.core.output import angle


def register(commands):
    """Add the ``fit`` sub-parser."""
    parser = commands.add_parser(
        "fit", help="fit bench recordings: the second-order-plus-delay model (docs/model.md §7), "
        "config keys through the nonlinear simulator (--params), or sweeps' frequency responses",
        description="Second-order-plus-delay fit (docs/model.md §7): (wn, zeta, td) with 95 % "
        "confidence intervals, the RMS residual and the closed-form bandwidth. "
        "With --data: of each bench step recording (a CSV whose header names time, command, "
        "position and optionally current and voltage columns with their units, e.g. "
        "'time_s,command_deg,position_deg'; the trigger and step size from the command, the "
        "pre-trigger mean removed; docs/identification.md) and, for several, of all at once, "
        "beside CONFIG's own simulated step (the base variant, or --variant). Sweep "
        "recordings (chirp or stepped sine) give the empirical frequency response and "
        "coherence against the variant's T (and T_i with a current_command column). "
        "With --params KEYS: those config keys fitted to the recordings through the nonlinear "
        "simulator (each replayed with its own command), with 95 % intervals, correlations and "
        "which keys and products of keys the data determine; several --params are alternative "
        "models ranked by AICc; -o FILE.yaml writes the config with the fitted variant. "
        "Without --data, 'cas-freq fit FILE --step 10deg' fits one step response CSV (the step "
        "at t = 0): two columns, time [s] and output angle [deg], with an optional header; or a "
        "header naming a time column (t or time, in s or ms: 't [s]', 'time_s') and an output "
        "angle column (delta, output_angle, fin_angle, fin or angle, in deg or rad: 'delta "
        "[deg]', 'output_angle_deg'), other columns ignored, as 'cas-freq "
        "simulate --csv' writes it.",
    )
    parser.add_argument("target", nargs="?", default=None, metavar="CONFIG|FILE",
                        help="with --data: the config YAML (default: the shipped "
                        "configs/qt_cas.yaml); without: the step response CSV (time [s], "
                        "output angle [deg], or named columns, see above)")
    parser.add_argument("--data", nargs="+", metavar="FILE",
                        help="step or sweep recordings (CSV with a header naming columns and "
                        "units; a command that oscillates makes a sweep: its frequency "
                        "response with coherence against the model's)")
    parser.add_argument("--variant", metavar="NAME",
                        help="with --data: the config's variant simulated beside the data "
                        "(default: base)")
    parser.add_argument("--model", choices=["second-order"], default="second-order",
                        help="model to fit (default and, for now, only: second-order)")
    parser.add_argument("--columns", metavar="ROLE=NAME,...",
                        help="name recording columns outright, e.g. time=t_ms,position=enc_deg "
                        "(roles: time, command, position, current, current_command, voltage)")
    parser.add_argument(
        "--step", metavar="ANGLE",
        help="the commanded step, e.g. 10deg (required without --data; with --data, for "
        "recordings without a command column, and checked against the command within 1 %%)",
    )
    parser.add_argument(
        "--params", action="append", metavar="[NAME:]KEY[=START],...",
        help="with --data: fit these config keys (e.g. motor.Km,motor.J,motor.mu_v; any key "
        "--set takes, load and drivetrain keys included; KEY=START sets a start, e.g. "
        "motor.coulomb_friction=1mN*m) through the nonlinear simulator, with 95 %% intervals, "
        "correlations and identifiability; give it again for alternative models, compared by "
        "AICc and BIC")
    parser.add_argument(
        "--candidates", metavar="FILE.yaml",
        help="with --data: candidate structures (YAML: each a name, the source that justifies "
        "it, --set overrides and free keys with start, bounds and the plausible range a "
        "datasheet or the report gives), each fitted to the recordings and ranked: estimates "
        "with intervals, identifiability, residual, AICc/BIC, plausibility, the step figures "
        "and second-order fit beside the bench's (docs/identification.md); -o DIR writes "
        "candidates.json and candidates.svg")
    parser.add_argument("--channels", metavar="position[,current]",
                        help="with --params: the recorded signals fitted (default: position, "
                        "and current where every recording has a current column)")
    parser.add_argument("--name", default="identified", metavar="VARIANT",
                        help="with --params: the fitted variant's name in the config -o writes "
                        "(default: identified)")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE",
                        help="with --params: change a key of the variant before the fit (e.g. "
                        "to give a drivetrain the recordings may need); repeatable")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("-o", "--output", metavar="DIR|FILE.yaml", type=output_path,
                        help="with --data: write fit.json and fit.svg (data vs fit, residuals; for "
                        "sweeps frf.json and frf.svg) "
                        "into DIR (replaced as a whole); with --params also config.yaml (the "
                        "config with the fitted variant), or only that config to FILE.yaml")
    parser.set_defaults(handler=run)


def run(args):
    """``fit --data FILE...`` (:mod:`cas_freq.cli.fit_recordings`) or ``fit FILE --step``."""
    if args.candidates is not None:
        if not args.data:
            raise CasFreqError("--candidates needs --data FILE... (the recordings to fit)")
        from cas_freq.cli.fit_candidates import run_candidates

        return run_candidates(args)
    if args.data and args.params:
        from cas_freq.cli.fit_params import run_params

        return run_params(args)
    for option, name in (("channels", "--channels"), ("overrides", "--set")):
        if getattr(args, option):
            raise CasFreqError(f"{name} needs --params KEYS (a fit of config keys)")
    if args.data:
        if are_sweeps(args.data, column_option(args)):
            return run_sweep(args)

        return run_recordings(args)
    if args.params:
        raise CasFreqError("--params needs --data FILE... (step recordings to fit)")
    for option, name in (("columns", "--columns"), ("output", "-o"), ("variant", "--variant")):
        if getattr(args, option) is not None:
            raise CasFreqError(f"{name} needs --data FILE...")
    if args.target is None:
        raise CasFreqError("give --data FILE [FILE ...] (step recordings) or a step response "
                           "FILE with --step ANGLE")
    if args.step is None:
        raise CasFreqError(f"{args.target}: --step ANGLE is required to fit a step response "
                           "FILE (or give recordings with --data)")
    args.csv = args.target
    return run_file(args)


def run_file(args):
    """Fit the response in the file and print the figures and the fit."""
    import numpy as np

    from cas_freq.simulation.commands import read_angle_series_csv
    from cas_freq.simulation.second_order import fit_second_order
    from cas_freq.simulation.step_figures import step_figures

    step = angle(args.step, "--step")
    t, delta = read_angle_series_csv(args.csv, negative_times=True, what="step response file")
    if t[0] > 0 or t[-1] <= 0:
        raise CasFreqError(f"{args.csv}: the times must span the step at t = 0 s, got "
                           f"{t[0]:g}..{t[-1]:g} s")
    after = t >= 0
    if np.count_nonzero(after) < 4:  # three parameters and a residual
        raise CasFreqError(f"{args.csv}: {np.count_nonzero(after)} samples from t = 0 s on; "
                           "the fit needs at least 4")
    try:
        figures = step_figures(t[after], delta[after], step)
        fit = fit_second_order(t[after], delta[after], step)
    except ValueError as exc:
        raise CasFreqError(f"{args.csv}: {exc}") from None
    data = json_ready({
        "source": str(args.csv),
        "samples": int(np.count_nonzero(after)),
        "step": dataclasses.asdict(figures),
        "fit": dataclasses.asdict(fit),
    })
    if args.json:
        print_json(data)
        return EXIT_OK

    f = dict(data["fit"])
    f["rms_residual_of_step"] = (None if f["rms_residual"] is None
                                 else f["rms_residual"] / abs(step))
    print("\n".join([
        f"{args.csv}: step of {math.degrees(step):g} deg, {data['samples']} samples from t = 0",
        *step_lines(data["step"]),
        "  second-order-plus-delay fit (docs/model.md §7)",
        *fit_lines(f),
        rms_line(f, "rms_residual_of_step"),
    ]))
    return EXIT_OK
