"""``cas-freq montecarlo``: distributions and yields of toleranced variants."""

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
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.output import output_json, output_step, output_unit
from cas_freq.report.outdir import check_output_dir
from cas_freq.report.studies import json_text, write_report
from cas_freq.studies.distributed import parse_scheduler, session

#: Figures summarised in the text output (besides those of the requirements).
SUMMARY_FIGURES = (
    "position_loop.phase_margin_deg", "position_loop.gain_margin_db",
    "current_loop.phase_margin_deg", "closed_loop.bandwidth_rad_s", "closed_loop.peak_db",
    "step.overshoot_pct", "fit.bandwidth_closed_form_rad_s",
)


def register(commands):
    """Add the ``montecarlo`` sub-parser."""
    parser = commands.add_parser(
        "montecarlo", help="figure distributions and requirement yields under tolerances",
        description="Draw N variants with the given tolerances, compute every figure, and "
        "report percentiles, the yield against each requirement and the worst samples. "
        "Tolerances: KEY=10% (relative) or KEY=0.02ms (absolute); normal draws use "
        "sigma = tolerance/3, uniform draws nominal ± tolerance. Several variants (--variant "
        "repeated, --all-variants): the same draws (one seed) around each; a summary per "
        "variant, a JSON array, samples.csv with a first column 'variant' and "
        "histograms.<variant>.svg per variant with -o.",
    )
    add_config_arguments(parser)
    parser.add_argument("--samples", type=int, default=1000, metavar="N",
                        help="number of samples (default 1000)")
    parser.add_argument("--tolerance", action="append", default=[], metavar="KEY=TOL",
                        help="tolerance of a key, e.g. motor.Km=10%% (repeatable)")
    parser.add_argument("--distribution", choices=("normal", "uniform"), default="normal")
    parser.add_argument("--seed", type=int, default=None,
                        help="random seed (default: fresh, printed for reproduction)")
    parser.add_argument("--step", metavar="ANGLE",
                        help="simulate an output step per sample (default: only when a requirement "
                        "needs step or fit figures)")
    parser.add_argument("--no-step", action="store_true",
                        help="simulate no step (step and fit requirements are then listed as "
                        "not evaluated)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")
    parser.add_argument(
        "--scheduler", metavar="ADDRESS",
        help="evaluate the samples in chunks on a dask.distributed cluster: local:N (N local "
        "worker processes) or a scheduler address such as tcp://10.0.0.5:8786 (needs "
        "pip install \"cas_freq[distributed]\"; same numbers as a local run)",
    )
    parser.add_argument("-o", "--output", metavar="DIR", type=output_path,
                        help="report directory: montecarlo.json, samples.csv, histograms.svg")
    parser.set_defaults(handler=run)


def summary(data):
    """Text summary of :func:`cas_freq.studies.montecarlo.montecarlo_dict` data."""
    lines = [
        f"{data['config']} ({data['variant']}): {data['samples']} samples, "
        f"{data['distribution']} ({data['distribution_note']}), seed {data['seed']}",
        "tolerances: " + ", ".join(
            f"{t['key']} ±{100 * t['relative']:g}%" if t["relative"] is not None
            else f"{t['key']} ±{t['absolute']:g} {t['unit']}" for t in data["tolerances"]),
        "stability: " + ", ".join(f"{k} {v}" for k, v in data["stability"].items()),
        "",
        f"{'figure':40s} {'p1':>10s} {'p5':>10s} {'p50':>10s} {'p95':>10s} {'p99':>10s}",
    ]
    names = list(SUMMARY_FIGURES) + [r["metric"] for r in data["requirements"]]
    for name in dict.fromkeys(names):
        stats = data["figures"].get(name)
        if not stats or not stats["count"]:
            continue
        lines.append(f"{name:40s} " + " ".join(f"{stats[p]:10.4g}"
                                               for p in ("p1", "p5", "p50", "p95", "p99")))
    lines += ["", "requirements:"]
    for r in data["requirements"]:
        if not r["evaluated"]:
            lines.append(f"  {r['id']:8s} {r['metric']:36s} {r['reason']}")
            continue
        worst = r["worst"][0] if r["worst"] else None
        worst_text = (f"; worst sample {worst['sample']}: {worst[r['metric']]:.4g}"
                      if worst and worst[r["metric"]] is not None else "")
        lines.append(f"  {r['id']:8s} {r['metric']:36s} yield {r['yield_pct']:6.2f} % "
                     f"({r['failed']} fail, {r['severity']}){worst_text}")
    return "\n".join(lines)


def run(args):
    """Run the Monte Carlo of each selected variant; print text or JSON, write the report."""
    from cas_freq.core.tolerances import parse_tolerance
    from cas_freq.studies.montecarlo import (
        fresh_seed,
        montecarlo_dict,
        montecarlo_samples_csv,
        run_montecarlo,
    )

    if args.output is not None:
        check_output_dir(args.output, "-o")
    if args.no_step and args.step:
        raise CasFreqError("--no-step and --step exclude each other")
    if args.scheduler is not None:
        parse_scheduler(args.scheduler)
    from cas_freq.core.parameters import CASCADE_PARAMETERS, LINEAR_ONLY, LINEAR_PARAMETERS

    for text in args.tolerance:  # refused before any work, except a key whose unit depends on
        key = str(text).partition("=")[0].strip()  # the architecture or the output's kind
        if key not in CASCADE_PARAMETERS and key not in LINEAR_PARAMETERS \
                and key not in LINEAR_ONLY:
            parse_tolerance(text)
    variants = load_variants(args)
    # an angle at a rotary output, a length at a linear one
    step = output_step(args.step, "--step", variants) if args.step else None
    # one seed for every variant: each is drawn around its own values with the same numbers
    seed = args.seed if args.seed is not None or len(variants) == 1 else fresh_seed()
    results = []
    with session(args.scheduler):  # one cluster for every variant
        for loaded in variants:
            label = "montecarlo" if len(variants) == 1 else f"montecarlo {loaded.variant}"
            progress = terminal_progress(label, unit="sample")
            # an absolute width in the units of this variant's architecture
            tolerances = ([parse_tolerance(text, loaded.params) for text in args.tolerance]
                          or list(loaded.params.tolerance_list))
            results.append(run_montecarlo(loaded, tolerances, args.samples,
                                          distribution=args.distribution, seed=seed,
                                          step_rad=step, simulate=not args.no_step,
                                          progress=progress, scheduler=args.scheduler))
            if progress:
                progress.done()
    several = several_variants(args)

    data = [output_json(montecarlo_dict(result), output_unit(loaded.params))  # mm if linear
            for result, loaded in zip(results, variants, strict=True)]
    if args.output:
        from cas_freq.plots.studies import svg_text

        samples = (variant_csv([(r.variant, montecarlo_samples_csv(r)) for r in results])
                   if several else montecarlo_samples_csv(results[0]))
        files = {"montecarlo.json": json_text(data if several else data[0]),
                 "samples.csv": samples}
        for result, item in zip(results, data, strict=True):
            name = (f"histograms.{file_safe(result.variant)}.svg" if several
                    else "histograms.svg")
            files[name] = svg_text(histograms(result, item))
        write_report(args.output, files)
    if args.json:
        print_json(data if several else data[0])
    else:
        print("\n\n".join(summary(item) for item in data))
    return EXIT_OK


def histograms(result, data):
    """The histogram figure of a Monte Carlo run: the summary figures and every evaluated
    requirement's figure, with the requirement bounds."""
    from cas_freq.plots.studies import histogram_figure

    names = list(dict.fromkeys(
        [n for n in SUMMARY_FIGURES if n in result.figures]
        + [r["metric"] for r in data["requirements"] if r["evaluated"]]))
    limits = {}
    for r in data["requirements"]:
        for bound in ("min", "max"):
            if r["evaluated"] and r[bound] is not None:
                limits.setdefault(r["metric"], []).append((r[bound], f"{r['id']} {bound}"))
    return histogram_figure(result.figures, names, limits)
