"""Pieces shared by every ``cas-freq`` command: exit codes, the parser class, config options."""

import argparse
import json

from cas_freq.core.exceptions import CasFreqError, ConfigError
from cas_freq.report.studies import write_report

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


class Parser(argparse.ArgumentParser):
    """argparse with usage errors exiting 2 (as argparse does) and a one-line message."""

    def error(self, message):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def output_path(text):
    """argparse ``type`` of every option that names an output (``-o``, ``--csv``, ``--junit``,
    ``--report``, ``--compare``): a path, not an empty or blank word (``-o ""`` would otherwise
    read as "no output" and write nothing, with exit 0). argparse reports the option by name
    (exit 2): ``argument -o/--output: expected a file or folder name, got ''``."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a file or folder name, got {text!r}")
    return text


def add_config_arguments(parser, all_by_default=False, several_configs=False):
    """CONFIG, ``--variant NAME`` (repeatable) / ``--all-variants`` and ``--set``, as every
    command takes them.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The command's sub-parser.
    all_by_default : bool
        Without ``--variant``, select base and every variant (report, compare) instead of
        ``base`` alone.
    several_configs : bool
        CONFIG may be given any number of times (compare: ``args.configs``, a list) instead of
        at most once (``args.config``).

    Returns
    -------
    argparse._MutuallyExclusiveGroup
        The group of ``--variant`` and ``--all-variants`` (compare adds ``--variants`` to it).
    """
    if several_configs:
        parser.add_argument("configs", nargs="*", metavar="CONFIG",
                            help="config YAML files (default: the shipped configs/qt_cas.yaml)")
    else:
        parser.add_argument("config", nargs="?", default=None, metavar="CONFIG",
                            help="config YAML (default: the shipped configs/qt_cas.yaml)")
    which = parser.add_mutually_exclusive_group()
    default = "base and every variant" if all_by_default else "base"
    which.add_argument("--variant", dest="variants", action="append", default=[],
                       metavar="NAME", help=f"variant to use (repeatable; default: {default})")
    which.add_argument("--all-variants", action="store_true",
                       help="base and every variant" + (" (the default)" if all_by_default
                                                        else ""))
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
        help="override a dotted key after the variant, e.g. position_loop.Kp=5 or "
        "current_loop.delay='0.1 ms' (repeatable)",
    )
    return which


def config_path(config):
    """The config file to read: ``config``, or the shipped one when CONFIG was omitted."""
    from pathlib import Path

    from cas_freq.config import default_config_path

    return Path(config) if config is not None else default_config_path()


def say_shipped_config(config):
    """Remember that the command uses the shipped config if CONFIG was omitted (``config``
    None): :func:`shipped_config_note` says so when the command has run."""
    global _SHIPPED
    if config is None:
        _SHIPPED = config_path(None)


def shipped_config_note():
    """Say on stderr which config the command used, if it was the shipped one because CONFIG
    was omitted (one line; not with ``--quiet``), so a user's data is never compared with the
    QT-CAS silently. Called by :func:`cas_freq.cli.main` once the command has run (its output
    written, exit 0 or 1), so that a bad-input error stays one line (a config error names the
    file itself)."""
    import sys

    global _SHIPPED
    if _SHIPPED is not None and not _QUIET:
        print(f"cas-freq: used the shipped config {_SHIPPED} (give CONFIG to use another)",
              file=sys.stderr, flush=True)
    _SHIPPED = None


def several_variants(args):
    """Whether the options ask for more than one variant (``--all-variants`` or two different
    ``--variant``): the JSON output is then an array, one object per variant."""
    return args.all_variants or len(set(args.variants)) > 1


def selected_variants(config, names, overrides, all_by_default=False):
    """The LoadedVariants of ``config`` named in ``names``, in the file's order.

    Every variant of the file is loaded and validated (a typo in one is reported whichever is
    selected), as :func:`cas_freq.config.load_variant` does; the overrides apply to the
    selected variants and are validated there only.

    Parameters
    ----------
    config : str or Path or None
        Config file (None: the shipped one, :func:`cas_freq.config.default_config_path`,
        said on stderr by :func:`config_path`).
    names : sequence of str
        Variant names; empty selects every variant if ``all_by_default``, else ``base``.
    overrides : sequence of str
        ``--set KEY=VALUE`` texts, applied after the variant.
    all_by_default : bool
        What an empty ``names`` selects.

    Raises
    ------
    ConfigError
        For an unknown name, listing the config's variants.
    """
    from cas_freq.config import BASE_VARIANT, load_all_variants, parse_set_option
    from cas_freq.config.loader import one_line, shown

    parsed = [parse_set_option(text) for text in overrides]
    chosen = set(names) if names else None if all_by_default else {BASE_VARIANT}
    loaded = load_all_variants(config_path(config), parsed, selected=chosen)
    known = [item.variant for item in loaded]
    unknown = [name for name in dict.fromkeys(names) if name not in known]
    if unknown:
        what = "variant" if len(unknown) == 1 else "variants"
        raise ConfigError(f"{one_line(loaded[0].source)}: unknown {what} "
                          f"{', '.join(shown(name) for name in unknown)}; the file has "
                          f"{', '.join(shown(name) for name in known)}")
    say_shipped_config(config)
    if names:
        return [item for item in loaded if item.variant in names]
    return loaded if all_by_default else [item for item in loaded
                                          if item.variant == BASE_VARIANT]


def load_variants(args, all_by_default=False, overrides=None):
    """The variants the options select, as a list of ``LoadedVariant`` (file order).

    ``overrides``: ``--set`` texts to apply instead of ``args.overrides`` (sweep passes only
    its fixed ones).
    """
    return selected_variants(args.config, args.variants,
                             args.overrides if overrides is None else overrides,
                             all_by_default=all_by_default or args.all_variants)


def wrote(path):
    """Say on stderr that a file with a name of cas-freq's making was written (not with
    ``--quiet``)."""
    import sys

    if not _QUIET:
        print(f"wrote {path}", file=sys.stderr, flush=True)


def write_and_print(args, data, files, text):
    """The end of a command with ``-o DIR`` and ``--json``: write ``files()`` (name -> text,
    called only with ``-o``; None: the command wrote its output itself) into ``args.output``
    as a whole, then print ``data`` as JSON or ``text(data)``. Returns EXIT_OK."""
    if args.output is not None and files is not None:
        write_report(args.output, files())
        wrote(args.output)
    if args.json:
        print_json(data)
    else:
        print(text(data))
    return EXIT_OK


def file_safe(name):
    """``name`` for use in a file name: every character but letters, digits, ``.``, ``_``
    and ``-`` replaced by ``_``."""
    import re

    return re.sub(r"[^A-Za-z0-9._-]", "_", name)


def variant_csv(parts):
    """One CSV text from several variants' CSV texts, with a first column ``variant``.

    Parameters
    ----------
    parts : sequence of (str, str)
        (variant name, CSV text with one header line); every header must be the same.

    Returns
    -------
    str
        The header ``variant,<header>``, then each part's rows prefixed by its name.
    """
    import csv
    import io

    headers = {text.split("\n", 1)[0] for _, text in parts}
    if len(headers) != 1:
        raise ValueError("variant_csv: the variants' CSV headers differ")
    lines = ["variant," + headers.pop()]
    for name, text in parts:
        cell = io.StringIO()
        csv.writer(cell, lineterminator="").writerow([name])  # quoted if CSV needs it
        lines += [f"{cell.getvalue()},{row}" for row in text.splitlines()[1:]]
    return "\n".join(lines) + "\n"


def print_json(data):
    """Print strict JSON (no NaN), indented."""
    print(json.dumps(data, indent=2, allow_nan=False))


def column_option(args):
    """The ``--columns`` mapping of ``args`` (None without the option); a malformed one is
    bad input (exit 2)."""
    from cas_freq.identification.columns import parse_column_option

    if args.columns is None:
        return None
    try:
        return parse_column_option(args.columns)
    except ValueError as exc:
        raise CasFreqError(str(exc)) from None


def refuse_linear(loaded, option):
    """Raise CasFreqError when ``loaded`` (a LoadedVariant) has a linear output: ``option``
    reads the output as an angle (a recording, a command table), which this version does not
    read in lengths."""
    if getattr(loaded.params, "linear", False):
        raise CasFreqError(f"{option}: {loaded.params.name} has a linear output (gear.screw_lead); "
                           "its tables are read as angles (deg or rad), so this version does "
                           "not read them for a linear output")


class _Progress:
    """A tqdm bar driven by ``(done, planned)`` calls (the plan may grow).

    Counts are shown as the whole numbers they are ("23/300"), not scaled to three digits
    (tqdm's ``unit_scale`` shows 11 as "11.0")."""

    def __init__(self, label, stream, unit):
        from tqdm import tqdm

        self.bar = tqdm(total=1, desc=label, file=stream, unit=unit, leave=True,
                        dynamic_ncols=True)

    def __call__(self, done, planned):
        if planned != self.bar.total:
            self.bar.total = planned
        self.bar.update(done - self.bar.n)

    def done(self):
        """Close the bar (ends its line)."""
        self.bar.close()


class _PeriodicProgress:
    """``(done, planned)`` calls reported as a line on ``stream`` every ``interval_s`` seconds
    (for a CI log or a pipe, where a bar would not render)."""

    def __init__(self, label, stream, unit, interval_s):
        import time

        self.label, self.stream, self.unit, self.interval_s = label, stream, unit, interval_s
        self.clock = time.monotonic
        self.start = self.last = self.clock()
        self.state = None

    def __call__(self, done, planned):
        self.state = (done, planned)
        now = self.clock()
        if now - self.last >= self.interval_s:
            self.last = now
            self._line(now)

    def _line(self, now):
        done, planned = self.state
        share = f" ({100.0 * done / planned:.0f} %)" if planned else ""
        print(f"{self.label}: {done:g} of {planned:g} {self.unit}s{share}, "
              f"{now - self.start:.0f} s", file=self.stream, flush=True)

    def done(self):
        """A last line if any was printed before."""
        if self.state is not None and self.last > self.start:
            self._line(self.clock())


#: Seconds between progress lines when stderr is not a terminal.
PROGRESS_INTERVAL_S = 10.0

_QUIET = False
#: The shipped config's path once a command has loaded it because CONFIG was omitted.
_SHIPPED = None


def set_quiet(quiet):
    """Turn progress reports off (``--quiet``) or on; forget a shipped config used before
    (each call of :func:`cas_freq.cli.main` starts afresh)."""
    global _QUIET, _SHIPPED
    _QUIET = bool(quiet)
    _SHIPPED = None


def label_progress(command, stream=None):
    """A callable ``progress(label)`` for work done in named stages (report, compare): on a
    terminal a line per stage, otherwise a line when :data:`PROGRESS_INTERVAL_S` seconds have
    passed since the last one; a no-op with ``--quiet``."""
    import sys
    import time

    stream = sys.stderr if stream is None else stream
    last = [time.monotonic()]
    every = 0.0 if stream.isatty() else PROGRESS_INTERVAL_S

    def progress(label):
        now = time.monotonic()
        if _QUIET or now - last[0] < every:
            return
        last[0] = now
        print(f"{command}: {label} ...", file=stream, flush=True)

    return progress


def terminal_progress(label, stream=None, unit="step"):
    """A progress callable ``(done, planned)`` on ``stream`` (stderr); None with ``--quiet``.

    On a terminal it is a tqdm bar; otherwise (a CI log, a pipe) a line every
    :data:`PROGRESS_INTERVAL_S` seconds, so a long run never looks hung and a short one prints
    nothing.
    """
    import sys

    if _QUIET:
        return None
    stream = sys.stderr if stream is None else stream
    if stream.isatty():
        return _Progress(label, stream, unit)
    return _PeriodicProgress(label, stream, unit, PROGRESS_INTERVAL_S)
