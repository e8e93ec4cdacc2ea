"""``cas-freq fit``: the report's second-order-plus-delay fit to a measured step response."""

import dataclasses
import math

from cas_freq.cli.common import EXIT_OK, angle, print_json
from cas_freq.exceptions import CasFreqError


def register(commands):
    """Add the ``fit`` sub-parser."""
    parser = commands.add_parser(
        "fit", help="second-order fit (report §7) to a measured step response CSV",
        description="Step figures and the (wn, zeta, td) least-squares fit, with 95 % "
        "confidence intervals, of a step response given as a CSV (the step applied at t = 0): "
        "two columns, time [s] and fin angle [deg], with an optional header; or a header naming "
        "a time column (t or time, in s or ms: 't [s]', 'time_s') and a fin angle column "
        "(delta, fin_angle, fin or angle, in deg or rad: 'delta [deg]', 'fin_angle_deg'), "
        "other columns ignored, as 'cas-freq simulate --csv' writes it.",
    )
    parser.add_argument("csv", metavar="FILE",
                        help="CSV: time [s], fin angle [deg]; or named columns (see above)")
    parser.add_argument(
        "--step", required=True, metavar="ANGLE", help="the commanded step, e.g. 10deg",
    )
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.set_defaults(handler=run)


def run(args):
    """Fit the response in the file and print the figures and the fit."""
    import numpy as np

    from cas_freq.fileio import json_ready
    from cas_freq.simulation.commands import read_angle_series_csv
    from cas_freq.simulation.second_order import fit_second_order
    from cas_freq.simulation.step_figures import step_figures

    step = angle(args.step, "--step")
    t, delta = read_angle_series_csv(args.csv, negative_times=True)
    if t[0] > 0 or t[-1] <= 0:
        raise CasFreqError(f"{args.csv}: the times must span the step at t = 0 s, got "
                           f"{t[0]:g}..{t[-1]:g} s")
    after = t >= 0
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
    s, f = data["step"], data["fit"]

    def ms(value, unit=" ms"):
        """A time [s] in ms; one below 1e-9 s is 0 (a delay fitted at its bound of 0 s)."""
        if value is None:
            return "—"
        return f"{0.0 if abs(value) < 1e-9 else value * 1e3:.4g}{unit}"

    print("\n".join([
        f"{args.csv}: step of {math.degrees(step):g} deg, {data['samples']} samples from t = 0",
        f"  rise time 10-90 %   {ms(s['rise_time_s'])}",
        f"  overshoot           {s['overshoot_pct']:.4g} %",
        f"  settling ±2 % / ±5 % {ms(s['settling_time_s'])} / {ms(s['settling_time_5pct_s'])}",
        "  second-order fit (report §7)",
        f"    wn {f['wn_rad_s']:.4g} rad/s [{f['wn_ci_rad_s'][0]:.4g}, {f['wn_ci_rad_s'][1]:.4g}]",
        f"    zeta {f['zeta']:.4g} [{f['zeta_ci'][0]:.4g}, {f['zeta_ci'][1]:.4g}]",
        f"    td {ms(f['td_s'])} [{ms(f['td_ci_s'][0], '')}, {ms(f['td_ci_s'][1], '')}]",
        f"    rms residual {100 * f['rms_residual'] / abs(step):.3g} % of the step",
        f"    closed-form bandwidth {f['bandwidth_closed_form_rad_s']:.4g} rad/s",
    ]))
    return EXIT_OK
