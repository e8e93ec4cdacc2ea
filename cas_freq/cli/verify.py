"""``cas-freq verify``: check the config's requirements; exit 1 when a required one fails.

Never imports matplotlib or python-control, so it stays fast enough for every CI run.
"""

from cas_freq.cli.common import (
    EXIT_FAILED,
    EXIT_OK,
    add_config_arguments,
    load_variants,
    output_path,
    print_json,
)
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.fileio import check_output_file, write_text_atomic


def register(commands):
    """Add the ``verify`` sub-parser."""
    parser = commands.add_parser(
        "verify", help="check the config's requirements (exit 1 if a required one fails)",
        description="Measure every figure the config's requirements name and compare it with "
        "its bounds, for one or all variants. Exit 0 when every required requirement passes, "
        "1 when one fails, 2 on bad input.",
    )
    add_config_arguments(parser)
    parser.add_argument("--junit", metavar="FILE", type=output_path,
                        help="also write JUnit XML to FILE")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.set_defaults(handler=run)


def _number(value, unit=""):
    if value is None:
        return "—"
    return f"{value:.4g}{(' ' + unit) if unit else ''}"


def verdict_table(config_name, verdicts):
    """Plain-text table: requirement, variant, value, bound, margin, status."""
    from cas_freq.verify.evaluate import bound_text

    rows = [("requirement", "variant", "measured", "bound", "margin", "status")]
    for v in verdicts:
        rows.append((
            f"{v.id} {v.metric}", v.variant,
            (f"{v.bound} {_number(v.bound_value, v.unit)}" if v.bound is not None
             else _number(v.value, v.unit) + (" (worst case)" if v.worst_case else "")),
            bound_text(v.min, v.max, v.unit), _number(v.margin, v.unit),
            v.status if v.severity == "required" or v.status != "PASS" else "PASS (advisory)",
        ))
    widths = [max(len(row[k]) for row in rows) for k in range(len(rows[0]))]
    lines = [f"cas-freq verify {config_name}"]
    for index, row in enumerate(rows):
        lines.append("  " + "  ".join(cell.ljust(width) for cell, width in zip(row, widths,
                                                                             strict=True)))
        if index == 0:
            lines.append("  " + "  ".join("-" * width for width in widths))
    failed = [v for v in verdicts if v.status == "FAIL"]
    advisory = [v for v in verdicts if v.status == "ADVISORY"]
    lines.append(
        f"  {len(verdicts)} checks: {len(verdicts) - len(failed) - len(advisory)} pass, "
        f"{len(failed)} required FAIL, {len(advisory)} advisory not met"
    )
    lines += [f"  FAIL {v.id} ({v.variant}): {v.message}" for v in failed]
    lines += [f"  worst case {v.id} ({v.variant}): {v.condition}" for v in verdicts
              if v.worst_case and v not in failed]
    return "\n".join(lines)


def run(args):
    """Verify the selected variants; print a table or JSON; write JUnit; exit 0/1."""
    from cas_freq.verify import failed_required, junit_xml, verdict_dict, verify_variants

    if args.junit is not None:
        check_output_file(args.junit, "--junit")

    variants = load_variants(args)
    config_name = variants[0].params.name
    if not variants[0].params.requirements:
        raise CasFreqError(
            f"{variants[0].source}: the config has no 'requirements:' list, nothing to verify"
        )
    by_variant = verify_variants(variants)
    verdicts = [verdict for items in by_variant.values() for verdict in items]
    if args.junit:
        write_text_atomic(args.junit, junit_xml(config_name, by_variant))
    if args.json:
        failed = failed_required(verdicts)
        print_json({
            "config": config_name,
            "config_path": variants[0].source,
            "passed": not failed,
            "verdicts": [verdict_dict(verdict) for verdict in verdicts],
        })
    else:
        print(verdict_table(config_name, verdicts))
    return EXIT_FAILED if failed_required(verdicts) else EXIT_OK
