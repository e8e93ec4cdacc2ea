"""``cas-freq worstcase``: the worst case of every requirement's figure over the tolerance box
(:mod:`cas_freq.studies.worstcase`)."""

from cas_freq.cli.common import (
    EXIT_OK,
    add_config_arguments,
    load_variants,
    output_path,
    print_json,
)
from cas_freq.report.outdir import check_output_dir
from cas_freq.report.studies import json_text, write_report
from cas_freq.studies.distributed import parse_scheduler, session


def register(commands):
    """Add the ``worstcase`` sub-parser."""
    parser = commands.add_parser(
        "worstcase", help="worst case of each requirement's figure over the tolerance box",
        description="The worst value of every figure a requirement names over the box of the "
        "tolerances (the config's 'tolerances:' section, or --tolerance KEY=TOL: 10%% "
        "relative, 0.02ms or ±0.036ohm absolute), the parameter combination that reaches it "
        "and how it was found: the nominal, every corner and uniform samples of the box, "
        "then a compass search from each figure's worst corner and sample. The worst found "
        "is printed; for the position loop's phase and gain margins of a continuous "
        "PID-on-PI also a bound guaranteed over the whole box (interval branch and bound) and "
        "whether stability over the whole box is proved. "
        "Stability is checked at every point evaluated, and the position loop's margins are "
        "searched even where no requirement names them. Exit 0 (a failing worst case is a "
        "result; `verify` with 'worst_case: true' on a requirement gates on it).",
    )
    add_config_arguments(parser)
    parser.add_argument("--tolerance", action="append", default=[], metavar="KEY=TOL",
                        help="tolerance of a key, e.g. motor.Km=10%% (repeatable; replaces the "
                        "config's tolerances: section)")
    parser.add_argument("--samples", type=int, default=256, metavar="N",
                        help="uniform samples of the box besides its corners (default 256)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the samples (default 0)")
    parser.add_argument("--resolution", type=float, default=1e-3, metavar="SHARE",
                        help="the local search stops below this share of each key's width "
                        "(default 0.001)")
    parser.add_argument("--bound-cells", type=int, default=4_000_000, metavar="N",
                        help="most cells of the guaranteed bound's branch and bound (about 2 s "
                        "per million; default 4000000; 0: no bound)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run the evaluations on a dask.distributed cluster: local:N or a "
                        "scheduler address (same numbers as a local run)")
    parser.add_argument("-o", "--output", metavar="DIR", type=output_path,
                        help="write worstcase.json into DIR (replaced as a whole)")
    parser.set_defaults(handler=run)


def run(args):
    """The worst case of each selected variant; print text or JSON; write ``-o``."""
    from cas_freq.core.tolerances import parse_tolerance
    from cas_freq.studies.worstcase import worst_case, worst_case_text

    if args.output is not None:
        check_output_dir(args.output, "-o")
    if args.scheduler is not None:
        parse_scheduler(args.scheduler)
    variants = load_variants(args)
    results = []
    with session(args.scheduler):
        for loaded in variants:
            tolerances = ([parse_tolerance(text, loaded.params) for text in args.tolerance]
                          or None)
            results.append(worst_case(loaded, tolerances, samples=args.samples,
                                      seed=args.seed, resolution=args.resolution,
                                      scheduler=args.scheduler,
                                      bound_cells=args.bound_cells))
    data = results if len(results) > 1 else results[0]
    if args.output is not None:
        write_report(args.output, {"worstcase.json": json_text(data)})
    if args.json:
        print_json(data)
    else:
        print("\n\n".join(worst_case_text(result) for result in results))
    return EXIT_OK
