"""``cas-freq tune``: free keys tuned to the config's requirements (:mod:`cas_freq.tuning`).

Exit 0 with a feasible tuning, 1 when no candidate in the bounds meets every held requirement
(at the target yield), 2 on bad input.
"""

import time
from pathlib import Path

from cas_freq.cli.common import (
    EXIT_FAILED,
    EXIT_OK,
    add_config_arguments,
    load_variants,
    output_path,
    print_json,
    terminal_progress,
    wrote,
)
from cas_freq.core.exceptions import CasFreqError, ConfigError
from cas_freq.core.fileio import check_output_file, json_ready, write_text_atomic
from cas_freq.report.outdir import check_output_dir
from cas_freq.report.studies import json_text, write_report
from cas_freq.studies.distributed import session
from cas_freq.tuning.options import (
    CASCADE_DEFAULT_FREE,
    DEFAULT_FACTOR,
    DEFAULT_FREE,
    GLOBAL_COUNT,
    OBJECTIVES,
    ROUND_COUNT,
    ROUNDS,
)


def register(commands):
    """Add the ``tune`` sub-parser."""
    parser = commands.add_parser(
        "tune", help="tune keys (gains, filters, ...) to the config's requirements",
        description="Search free keys for the best objective subject to the config's "
        "requirements (every one, advisory included, unless --required-only; bounds tightened "
        "by --margin), on the nominal model or over a tolerance set and load cases: a global "
        "Sobol search of the bounds, then refinement around the best, every candidate checked "
        "with the figures verify uses. Prints the tuned values, every requirement before and "
        "after, the binding ones (or, when nothing in the bounds is feasible, how far the "
        "closest candidate is), the Pareto front of bandwidth, phase margin and overshoot, and, "
        "for a config whose drive: is epos4, the gains in EPOS4 units ('cas-freq epos4 export' "
        "writes them for any config); -o writes the config with the tuned variant.",
    )
    add_config_arguments(parser, all_by_default=False)
    parser.add_argument("--free", metavar="KEY,KEY,...",
                        help=f"keys to tune (default: {','.join(DEFAULT_FREE)}; with a "
                        f"velocity loop {','.join(CASCADE_DEFAULT_FREE)})")
    parser.add_argument("--bounds", action="append", default=[], metavar="KEY=LO:HI",
                        help="a free key's range, SI or with units (default: the variant's "
                        f"value /{DEFAULT_FACTOR:g} .. x{DEFAULT_FACTOR:g}); repeatable")
    parser.add_argument("--objective", choices=tuple(OBJECTIVES), default="max-bandwidth")
    parser.add_argument("--robust", metavar="montecarlo:N|corners",
                        help="hold the requirements over a tolerance set (--tolerance) too")
    parser.add_argument("--tolerance", action="append", default=[], metavar="KEY=TOL",
                        help="a toleranced key for --robust, as montecarlo takes it "
                        "(e.g. motor.Km=10%%)")
    parser.add_argument("--distribution", choices=("normal", "uniform"), default="normal")
    parser.add_argument("--yield", dest="yield_pct", type=float, default=None, metavar="PCT",
                        help="with --robust montecarlo:N, the share of the samples that must "
                        "pass (default 99; corners must all pass)")
    parser.add_argument("--load-cases", action="store_true",
                        help="also hold the requirements at every load spring K_h of the "
                        "config's load_envelope grid")
    parser.add_argument("--margin", type=float, default=2.0, metavar="PCT",
                        help="tighten every bound by this share of its magnitude (default 2)")
    parser.add_argument("--required-only", action="store_true",
                        help="hold only the required requirements (not the advisory ones)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the search (default 0)")
    parser.add_argument("--candidates", type=int, default=GLOBAL_COUNT, metavar="N",
                        help=f"global search points (default {GLOBAL_COUNT})")
    parser.add_argument("--rounds", type=int, default=ROUNDS, metavar="N",
                        help=f"refinement rounds of {ROUND_COUNT} points (default {ROUNDS})")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="evaluate on a dask.distributed cluster: local:N or an address")
    parser.add_argument("--name", default="tuned", metavar="VARIANT",
                        help="the tuned variant's name in -o's config (default: tuned)")
    parser.add_argument("-o", "--output", metavar="FILE.yaml", type=output_path,
                        help="write CONFIG with the tuned variant added (inputs never change)")
    parser.add_argument("--compare", metavar="DIR", type=output_path,
                        help="with -o: write the compare report of the variant before and "
                        "after into DIR")
    parser.add_argument("--report", metavar="DIR", type=output_path,
                        help="write tune.json and trade-off.svg (every candidate's bandwidth "
                        "against phase margin, the Pareto front) into DIR (replaced as a whole)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")
    parser.set_defaults(handler=run)


def _check_counts(args):
    for name, value, low in (("--candidates", args.candidates, 1), ("--rounds", args.rounds, 0)):
        if not low <= value <= 100_000:
            raise CasFreqError(f"{name}: must be {low}..100000, got {value}")
    if not 0.0 <= args.margin < 100.0:
        raise CasFreqError(f"--margin: a percentage 0..100, got {args.margin:g}")
    if args.yield_pct is not None and not (args.robust or "").startswith("montecarlo"):
        raise CasFreqError(f"--yield {args.yield_pct:g}: applies to --robust montecarlo:N "
                           "(every corner of --robust corners must pass; a nominal tune has "
                           "one scenario)")
    if args.yield_pct is not None and not 0.0 < args.yield_pct <= 100.0:
        raise CasFreqError(f"--yield: a percentage in (0, 100], got {args.yield_pct:g}")
    if args.compare is not None and args.output is None:
        raise CasFreqError("--compare needs -o FILE.yaml (the report compares its variants)")


def run(args):
    """Tune, print, write the config (and the comparison)."""
    from cas_freq.tuning.run import tune_variant
    from cas_freq.tuning.summary import tune_dict, tune_text

    _check_counts(args)
    output = check_output_file(args.output, "-o") if args.output is not None else None
    if args.report is not None:
        check_output_dir(args.report, "--report")
    variants = load_variants(args)
    if len(variants) != 1:
        raise CasFreqError("tune: one variant at a time (--variant NAME)")
    loaded = variants[0]
    if output is not None and output.exists() and output.resolve() == \
            Path(loaded.source).resolve():
        raise CasFreqError(f"-o {output}: is the input config; inputs are never modified")
    progress = terminal_progress("tune", unit="candidate")
    start = time.perf_counter()
    with session(args.scheduler):
        result = tune_variant(
            loaded, args.free, args.bounds, args.objective, args.robust, args.tolerance,
            99.0 if args.yield_pct is None else args.yield_pct, args.margin,
            args.required_only, args.seed, args.load_cases, args.distribution, args.scheduler,
            args.candidates, args.rounds, progress)
    if progress:
        progress.done()
    data = tune_dict(result, loaded.params.name, loaded.variant, time.perf_counter() - start)
    data["drive"] = None
    if result.feasible or output is not None:
        text, tuned = _tuned_config(loaded, result, args.name)
        if loaded.params.drive == "epos4":  # the only drive cas_freq knows the units of
            data["drive"] = _drive_settings(tuned)
        if output is not None:
            write_text_atomic(output, text)
            wrote(output)
            data["written"] = str(output)
            if args.compare:
                _compare(loaded, output, args.name, args.compare)
    data = json_ready(data)
    if args.report is not None:
        from cas_freq.plots.common import svg_text
        from cas_freq.plots.tune import trade_off_figure

        write_report(args.report, {"tune.json": json_text(data),
                                   "trade-off.svg": svg_text(trade_off_figure(result))})
        wrote(args.report)
    if args.json:
        print_json(data)
    else:
        print(tune_text(data))
        if data["drive"]:
            print("\n" + data["drive"]["table"])
    return EXIT_OK if result.feasible else EXIT_FAILED


def _tuned_config(loaded, result, name):
    """(config text with the tuned variant, the tuned LoadedVariant)."""
    from cas_freq.drive.variant_text import config_with_variant, si_text, variant_entries

    values = result.values()
    verdict = "meets every held requirement" if result.feasible else "INFEASIBLE: the closest"
    changed = {key: (si_text(key, value, loaded.params),
                     f"tuned ({result.objective}; {verdict})")
               for key, value in values.items()}
    comment = (f"cas-freq tune of {', '.join(values)} from variant {loaded.variant} "
               f"({result.scenarios.label}, seed {result.seed})")
    return config_with_variant(loaded.source, name, variant_entries(loaded, changed), comment,
                               values, "the tuned values", tolerance=1e-5)


def _drive_settings(tuned):
    """The tuned variant's gains in EPOS4 units (None if the drive cannot hold them)."""
    from cas_freq.drive import epos4

    try:
        settings = epos4.settings_of(tuned.params, f"variant {tuned.variant!r}")
    except ConfigError as exc:
        return {"table": f"EPOS4 units: not writable ({exc})", "objects": []}
    missing = epos4.not_exported(tuned.params)
    return {"table": epos4.settings_table(settings, f"{tuned.variant} in EPOS4 units", missing),
            "objects": [item.to_dict() for item in settings], "not_exported": missing}


def _compare(loaded, output, name, folder):
    """The compare report of the variant before and the tuned one (from the written file)."""
    from cas_freq.config import load_variant
    from cas_freq.report.compare import build_compare

    before = load_variant(output, loaded.variant, loaded.overrides)
    after = load_variant(output, name, loaded.overrides)
    build_compare([before, after], folder, command=f"cas-freq compare {output} --variants "
                  f"{loaded.variant},{name}", selected=[loaded.variant, name])
    wrote(folder)


__all__ = ["register", "run"]
