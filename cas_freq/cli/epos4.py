"""``cas-freq epos4``: EPOS4 drive parameters into a config variant, and a variant's gains out.

- ``cas-freq epos4 import EXPORT [CONFIG] --variant NAME [-o OUT.yaml] [--force]``: the
  controller gains and current limit of an EPOS Studio parameter file, as a new variant of
  CONFIG (printed, or written to OUT; CONFIG itself is never modified).
- ``cas-freq epos4 export [CONFIG] [--variant NAME ...] [--set ...] [-o FILE]``: a variant's
  gains in the drive's units and object indices, as a table (or ``--json``), and with ``-o``
  as a parameter file that ``import`` reads back.

The objects, their units and their sources: :mod:`cas_freq.drive.epos4`.
"""

import argparse
import os
from pathlib import Path

from cas_freq.cli.common import (
    EXIT_OK,
    Parser,
    add_config_arguments,
    config_path,
    load_variants,
    output_path,
    print_json,
    say_shipped_config,
    several_variants,
    wrote,
)
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.fileio import check_output_file, write_text_atomic


def register(commands):
    """Add the ``epos4`` sub-parser and its ``import`` and ``export`` sub-commands."""
    parser = commands.add_parser(
        "epos4", help="EPOS4 drive parameters: import an EPOS Studio export, export a variant",
        description="maxon EPOS4 controller gains: read an EPOS Studio parameter file into a "
        "config variant, or print a variant's gains in the drive's units and object indices.",
    )
    actions = parser.add_subparsers(dest="epos4_action", required=True, parser_class=Parser,
                                    metavar="{import,export}")

    importer = actions.add_parser(
        "import", help="an EPOS Studio parameter file as a new config variant",
        description="Read the current and position controller gains, feed-forward and current "
        "limit of an EPOS4 parameter file (INI-style DCF; for a CONFIG with a velocity loop the "
        "current and velocity controller gains and the current limit) and write CONFIG with a "
        "new variant holding them (to stdout, or to -o OUT). CONFIG is never modified.",
    )
    importer.add_argument("export_file", metavar="EXPORT_FILE",
                          help="EPOS Studio parameter file (.dcf)")
    importer.add_argument("config", nargs="?", default=None, metavar="CONFIG",
                          help="config YAML (default: the shipped configs/qt_cas.yaml)")
    importer.add_argument("--variant", required=True, metavar="NAME",
                          help="name of the new variant")
    importer.add_argument("-o", "--output", default=None, metavar="OUT.yaml", type=output_path,
                          help="write the config with the new variant here (default: stdout)")
    importer.add_argument("--force", action="store_true",
                          help="replace a variant of that name")
    importer.add_argument("--json", action="store_true",
                          help="print what was imported as JSON (needs -o)")
    importer.set_defaults(handler=run_import, command_name="epos4 import")  # errors name it

    exporter = actions.add_parser(
        "export", help="a variant's gains in the drive's units and object indices",
        description="Print a variant's EPOS4 gains (object index, name, value in the drive's "
        "unit, SI value), rounded to the drive's resolution; with -o also write them as an "
        "EPOS4 parameter file that 'cas-freq epos4 import' reads back.",
    )
    add_config_arguments(exporter)
    exporter.add_argument("-o", "--output", default=None, metavar="FILE", type=output_path,
                          help="also write an EPOS4 parameter file (.dcf; one variant only)")
    exporter.add_argument("--json", action="store_true", help="print JSON instead of a table")
    exporter.set_defaults(handler=run_export, command_name="epos4 export")
    for sub in (importer, exporter):
        # SUPPRESS: `cas-freq epos4 -q export` keeps the -q given before the action
        sub.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                         help="do not say on stderr which file was written")


def _same_file(a, b):
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def run_import(args):
    """Read the export, add the variant to the config's text, check it loads, write it."""
    from cas_freq.drive import epos4
    from cas_freq.drive.variant_text import config_with_variant

    if args.json and args.output is None:
        raise CasFreqError("--json: prints what was imported, so the config needs -o OUT.yaml")
    config = config_path(args.config)
    output = check_output_file(args.output, "-o") if args.output is not None else None
    if output is not None and output.exists() and _same_file(output, config):
        raise CasFreqError(f"-o {output}: is the input config {config}; inputs are never "
                           "modified, write the result to another file")

    from cas_freq.config import load_variant

    structure = epos4.architecture(load_variant(config).params)
    export = epos4.read_export(args.export_file, structure)
    values = epos4.import_values(export)
    absent = list(export.absent)
    comment = f"EPOS4 parameters imported by cas-freq epos4 import from {Path(export.path).name}"
    new_text, _ = config_with_variant(
        config, args.variant, epos4.variant_entries(export), comment,
        {key: si for key, (_, si) in values.items()}, "the imported values", force=args.force)
    say_shipped_config(args.config)
    from cas_freq.core.parameters import unit_of

    if output is None:
        print(new_text, end="")
    else:
        write_text_atomic(output, new_text)
        if not args.quiet:
            wrote(output)
    if args.json:
        print_json({
            "variant": args.variant, "source": export.path, "config": str(config),
            "output": str(output),
            "objects": [{"object": read.obj.label, "name": read.obj.name, "key": read.obj.key,
                         "drive_value": read.value, "drive_unit": read.obj.unit,
                         "si_value": values[read.obj.key][1],
                         "si_unit": unit_of(read.obj.key),
                         "line": read.line, "from_default": read.from_default}
                        for read in export.values],
            "absent": [obj.label for obj in absent],
            "ignored_sections": export.ignored,
        })
    elif output is not None and not args.quiet:
        import sys

        notes = [f"{len(export.values)} objects imported as variant {args.variant!r}"]
        if absent:
            notes.append("not in the file (the config's value kept): " + ", ".join(
                f"{obj.label} {obj.name} ({obj.key})" for obj in absent))
        defaults = [read.obj.label for read in export.values if read.from_default]
        if defaults:
            notes.append("read from DefaultValue (no ParameterValue): " + ", ".join(defaults))
        for note in notes:
            print(f"cas-freq epos4 import: {note}", file=sys.stderr)
    return EXIT_OK


def run_export(args):
    """Print the selected variants' settings; write a parameter file with ``-o``."""
    from cas_freq.config.loader import one_line, shown
    from cas_freq.drive import epos4

    output = check_output_file(args.output, "-o") if args.output is not None else None
    if output is not None and several_variants(args):
        raise CasFreqError("-o: writes the parameter file of one variant; select one with "
                           "--variant NAME")
    items = []
    for loaded in load_variants(args):
        origin = f"{one_line(loaded.source)} (variant {shown(loaded.variant)})"
        items.append((loaded, origin, epos4.settings_of(loaded.params, origin)))
    if output is not None:
        loaded, origin, settings = items[0]
        if loaded.overrides:
            origin += " with --set " + ", ".join(f"{k}={v}" for k, v in loaded.overrides)
        write_text_atomic(output, epos4.export_text(settings, origin, output.name,
                                                    epos4.not_exported(loaded.params)))
        if not args.quiet:
            wrote(output)
    if args.json:
        data = [{"config": loaded.source, "variant": loaded.variant,
                 "objects": [item.to_dict() for item in settings],
                 "not_exported": epos4.not_exported(loaded.params),
                 "output": str(output) if output is not None else None}
                for loaded, _, settings in items]
        print_json(data if several_variants(args) else data[0])
    else:
        print("\n\n".join(
            epos4.settings_table(settings, f"{loaded.params.name} / {loaded.variant}: EPOS4 "
                                 "objects (units of the EPOS4 Firmware Specification)",
                                 epos4.not_exported(loaded.params))
            for loaded, _, settings in items))
    return EXIT_OK
