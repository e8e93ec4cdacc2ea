"""``cas-freq sweep``: every figure of analyze (and of a step) over a grid of config keys."""

from cas_freq.cli.common import (
    EXIT_OK,
    add_config_arguments,
    file_safe,
    load_variants,
    output_path,
    print_json,
    several_variants,
    terminal_progress,
    variant_csv,
)
from cas_freq.cli.sinedwell import parse_frequencies
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.fileio import check_output_file, write_text_atomic
from cas_freq.core.output import output_json, output_step, output_unit
from cas_freq.report.outdir import check_output_dir
from cas_freq.report.studies import json_text, write_report
from cas_freq.studies.distributed import parse_scheduler, session

#: Figures shown in the text table (all of them go to JSON and CSV).
TABLE_FIGURES = (
    ("position_loop.phase_margin_deg", "PM_p [deg]"),
    ("position_loop.gain_margin_db", "GM_p [dB]"),
    ("velocity_loop.phase_margin_deg", "PM_v [deg]"),
    ("current_loop.phase_margin_deg", "PM_i [deg]"),
    ("closed_loop.bandwidth_rad_s", "BW [rad/s]"),
    ("closed_loop.peak_db", "peak [dB]"),
    ("step.overshoot_pct", "OS [%]"),
    ("fit.bandwidth_closed_form_rad_s", "BW fit [rad/s]"),
    ("sinedwell.bandwidth_rad_s", "BW dwell [rad/s]"),
)


def register(commands):
    """Add the ``sweep`` sub-parser."""
    parser = commands.add_parser(
        "sweep", help="every figure over a grid of config keys (batch, vectorised)",
        description="Evaluate every figure of analyze (and, with --step, of simulate) at each "
        "point of a grid: --set KEY=START:STOP:COUNT or KEY=A,B,C (several --set make a "
        "Cartesian product); --set KEY=VALUE fixes a key. Several variants (--variant repeated, "
        "--all-variants): the same grid for each; a table per variant, a JSON array, and one CSV "
        "with a first column 'variant' (sweep.<variant>.svg per variant with -o).",
    )
    add_config_arguments(parser)
    parser.add_argument("--step", metavar="ANGLE", help="also simulate an output step, e.g. 10deg")
    parser.add_argument("--no-fit", action="store_true",
                        help="with --step: skip the second-order fit")
    parser.add_argument("--sinedwell", metavar="ANGLE",
                        help="also the sine-dwell bandwidth at this output amplitude, e.g. 10deg "
                        "(feed-forward off, as cas-freq sinedwell)")
    parser.add_argument("--frequencies", metavar="MIN:MAX:N|F1,F2,...",
                        help="with --sinedwell: frequencies in rad/s (default: 100:5000:30)")
    output = parser.add_mutually_exclusive_group()
    output.add_argument("--json", action="store_true", help="print JSON instead of a table")
    output.add_argument("--csv", metavar="FILE", type=output_path,
                        help="write one CSV row per grid point (and variant: a first column "
                        "'variant' when there are several)")
    parser.add_argument(
        "--scheduler", metavar="ADDRESS",
        help="evaluate the samples in chunks on a dask.distributed cluster: local:N (N local "
        "worker processes) or a scheduler address such as tcp://10.0.0.5:8786 (needs "
        "pip install \"cas_freq[distributed]\"; same numbers as a local run)",
    )
    parser.add_argument("-o", "--output", metavar="DIR", type=output_path,
                        help="report directory: sweep.json, sweep.csv and sweep.svg")
    parser.set_defaults(handler=run)


def split_settings(settings, config=None, parse=True):
    """(fixed overrides as ``KEY=VALUE`` texts, grid axes as key -> values [SI]) from
    ``--set``; the values in the units of ``config``'s architecture (a velocity loop changes
    the position gains' units). ``parse=False``, before the config is loaded: the axes of the
    keys whose unit depends on the architecture as their texts (the key checked)."""
    from cas_freq.config import parse_set_option
    from cas_freq.core.parameter_keys import is_grid_spec, parse_grid_values
    from cas_freq.core.parameters import CASCADE_PARAMETERS, check_key

    fixed, axes = [], {}
    for text in settings:
        key, sep, value = text.partition("=")
        key = key.strip()
        if sep and is_grid_spec(value):
            if key in axes:
                raise CasFreqError(f"--set {key}: swept twice")
            if parse or key not in CASCADE_PARAMETERS:
                axes[key] = parse_grid_values(key, value, config)
            else:
                check_key(key)
                axes[key] = value
        else:
            parse_set_option(text)  # refuses a malformed one before any work
            fixed.append(text)
    for text in fixed:
        key = text.partition("=")[0].strip()
        if key in axes:
            raise CasFreqError(f"--set {key}: both swept and fixed ({text!r}); give it once, "
                               "as a grid or as one value")
    return fixed, axes


def table(sweep):
    """Text table: swept keys, stability and the headline figures per grid point ("-" where a
    figure does not exist or is not shown, with the reason below the table)."""
    from cas_freq.studies.shown import DIVERGED
    from cas_freq.studies.sweep import not_shown, shown_figures

    keys = list(sweep.points)
    figures, reasons = shown_figures(sweep), not_shown(sweep)
    shown = [(name, label) for name, label in TABLE_FIGURES if name in sweep.figures]
    header = [*keys, "stability", *(label for _, label in shown)]
    rows = []
    for index in range(len(sweep.stability)):
        row = [f"{sweep.points[k][index]:.6g}" for k in keys]
        row.append(str(sweep.stability[index]))
        for name, _ in shown:
            value = figures[name][index]
            row.append(f"{value:.4g}" if value == value else "-")
        rows.append(row)
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    lines = ["  ".join(h.rjust(w) for h, w in zip(header, widths, strict=True))]
    lines += ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    title = f"{sweep.config} ({sweep.variant}): sweep of {len(rows)} points"
    notes = [f"(- not shown: {reason}" + ("" if reason == DIVERGED else
                                         ": its closed-loop, step and fit figures") + ")"
             for reason in dict.fromkeys(r for r in reasons if r is not None)]
    return "\n".join([title, *lines, *notes])


def run(args):
    """Run the sweep of each selected variant; print tables or JSON, write CSV and the report."""
    from cas_freq.studies.sweep import run_sweep, sweep_csv, sweep_dict

    if args.csv is not None:
        check_output_file(args.csv, "--csv")
    if args.output is not None:
        check_output_dir(args.output, "-o")
    if args.scheduler is not None:
        parse_scheduler(args.scheduler)
    fixed, axes = split_settings(args.overrides, parse=False)
    if not axes:
        raise CasFreqError("sweep: give at least one grid, e.g. --set position_loop.Kp=2:12:200")
    if args.frequencies and not args.sinedwell:
        raise CasFreqError("--frequencies: only with --sinedwell")
    variants = load_variants(args, overrides=fixed)
    # an angle at a rotary output, a length at a linear one
    step = output_step(args.step, "--step", variants) if args.step else None
    sinedwell = None
    if args.sinedwell:
        from cas_freq.studies.run import DEFAULT_SINEDWELL_FREQUENCIES_RAD_S

        frequencies = (DEFAULT_SINEDWELL_FREQUENCIES_RAD_S if args.frequencies is None
                       else parse_frequencies(args.frequencies))
        sinedwell = (abs(output_step(args.sinedwell, "--sinedwell", variants)), frequencies)
    results = []
    with session(args.scheduler):  # one cluster for every variant
        for loaded in variants:
            label = "sweep" if len(variants) == 1 else f"sweep {loaded.variant}"
            progress = terminal_progress(label, unit="point")
            # the grid in the units of this variant's architecture
            axes = split_settings(args.overrides, loaded.params)[1]
            results.append(run_sweep(loaded, axes, step_rad=step, fit=not args.no_fit,
                                     sinedwell=sinedwell, progress=progress,
                                     scheduler=args.scheduler))
            if progress:
                progress.done()
    several = several_variants(args)

    data = [output_json(sweep_dict(result), output_unit(loaded.params))  # mm if linear
            for result, loaded in zip(results, variants, strict=True)]
    data = data if several else data[0]
    csv_text = None
    if args.csv or args.output:
        csv_text = (variant_csv([(r.variant, sweep_csv(r)) for r in results]) if several
                    else sweep_csv(results[0]))
    if args.csv:
        write_text_atomic(args.csv, csv_text)
    if args.output:
        from cas_freq.plots.studies import svg_text, sweep_figure
        from cas_freq.studies.sweep import shown_figures

        files = {"sweep.json": json_text(data), "sweep.csv": csv_text}
        for result in results:
            name = f"sweep.{file_safe(result.variant)}.svg" if several else "sweep.svg"
            files[name] = svg_text(sweep_figure(result.points, shown_figures(result),
                                                list(result.points)))
        write_report(args.output, files)
    if args.json:
        print_json(data)
    else:
        print("\n\n".join(table(result) for result in results))
    return EXIT_OK
