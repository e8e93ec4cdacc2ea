"""``cas-freq compare``: several variants (of one or more configs) side by side.

First the config parameters that differ between the variants (:func:`parameter_differences`,
in the units the config writes them), then overlaid Bode, step and bandwidth-versus-amplitude
figures, the requirement verdict matrix, and a table of every numeric figure per variant with
its difference to the first (the baseline), each row a readable label in engineering units
(the figure table, :data:`cas_freq.core.figures.FIGURES`); written as index.html, report.md and
results.json (atomically, like ``report``). results.json keeps the machine-readable keys in SI
(``analyze.current_loop.delay_margin_s``); only the human tables carry labels and display
units.

A difference is that of the two figures as results.json writes them (6 significant digits,
:mod:`cas_freq.core.numbers`); in the table it is 0 when below the table's 5 significant
digits of the figures, never the noise of their last bits.
"""

import math
import re
from pathlib import Path

from cas_freq.config import read_config_file
from cas_freq.config.wording import common_output_label, name_the_output
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.figures import FIGURES, LOOPS, loop_label
from cas_freq.core.numbers import JSON_DIGITS, difference, difference_value, number
from cas_freq.core.output import LENGTH, output_json, output_unit
from cas_freq.core.parameters import PARAMETERS, parameter
from cas_freq.core.units import parse_unit, registry, split_quantity
from cas_freq.report import html, markdown
from cas_freq.report.build import REPORTS_DIR, results_json
from cas_freq.report.data import (
    ReportSettings,
    display_path,
    gather_variant,
    not_computed_notice,
    reference_dict,
    variant_results,
)
from cas_freq.report.document import Bullets, Figure, Heading, Paragraph, Table
from cas_freq.report.outdir import MAX_NAME_LENGTH, sanitise_name, write_directory_atomic

#: Keys of the analyze JSON that are identity or bookkeeping, not figures.
_NOT_FIGURES = {"config", "config_path", "variant", "overrides", "delay_model", "notes",
                "frequency_range_rad_s", "stability_pade_order", "limit_cycles_reason"}

#: Significant digits of the figures in the every-figure table (the differences are written
#: with 4, and are 0 below this precision of the figures).
TABLE_DIGITS = 5


def entry_labels(variants):
    """``config/variant`` per entry; a repeated label gets ``#2``, ``#3``... appended."""
    labels, seen = [], {}
    for loaded in variants:
        label = f"{loaded.params.name}/{loaded.variant}"
        seen[label] = seen.get(label, 0) + 1
        labels.append(label if seen[label] == 1 else f"{label}#{seen[label]}")
    return labels


def default_compare_dir(variants, selected=None):
    """``reports/compare-<config names>[-<selected variants>]``, sanitised."""
    names = list(dict.fromkeys(v.params.name for v in variants))
    text = "compare-" + "-".join(names)
    if selected:
        text += "-" + "-".join(selected)
    return REPORTS_DIR / sanitise_name(text[:MAX_NAME_LENGTH], fallback="compare")


# ---- the parameters that differ -----------------------------------------------------------------

#: Config settings that are not numbers, compared beside :data:`PARAMETERS` (key: meaning).
SETTINGS = {
    "position_loop.derivative_on": "the derivative acts on the error or on the measurement",
    "sampling.method": "discretisation of the sampled controllers: backward or tustin",
}

#: Parameters that are derived when the config does not set them (key: effective value of a
#: validated config, in SI).
_DERIVED = {
    "motor.mu_v": lambda params: params.motor.viscous_friction,
    "position_loop.Tf": lambda params: params.position_loop.filter_time_constant,
}

#: Display unit of a parameter that no compared config writes with a unit (SI unit: shown).
_UNWRITTEN_UNITS = {"s": "ms", "dimensionless": ""}

_RANGE = re.compile(r",\s*(?:0 or\s+)?(?:\|\w+\|\s+)?[-+]?[\d.]+(?:e[-+]?\d+)?"
                    r"\.\.[\d.]+(?:e[-+]?\d+)?")


def config_keys():
    """Every compared config key: :data:`PARAMETERS` and :data:`SETTINGS`, grouped by section
    in the config's order; the sampling once, as ``sampling.*`` (``simulation.*`` is its older
    spelling, which a validated config makes agree with it)."""
    keys = [key for key in (*PARAMETERS, *SETTINGS) if not key.startswith("simulation.")]
    sections = list(dict.fromkeys(key.split(".")[0] for key in keys))
    return sorted(keys, key=lambda key: sections.index(key.split(".")[0]))


def short_meaning(key, config=None):
    """The meaning of a config key in ``config``'s architecture (a cascade's position gains,
    a linear output's loads) without its accepted range and unit (those of :data:`PARAMETERS`
    end with "..., 1e-6..1e6 [ohm]")."""
    if key in SETTINGS:
        return SETTINGS[key]
    text = re.sub(r"\s*\[[^\]]*\]\s*$", "", parameter(key, config).meaning)
    return _RANGE.sub("", text)


def effective_value(params, key):
    """The value of dotted ``key`` in validated ``params`` and whether it is derived.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
    key : str
        A key of :func:`config_keys`.

    Returns
    -------
    tuple of (float or str or None, bool)
        The value (numbers in the key's SI unit in the architecture of ``params``; None when
        not set and not derived) and True when it is derived (``mu_v`` from the no-load point,
        ``Tf`` = Kd/(10·Kp)).
    """
    node = params
    for part in key.split("."):
        node = getattr(node, part, None) if node is not None else None
    if node is None and key in _DERIVED:
        return _DERIVED[key](params), True
    return node, False


def written_units(loaded):
    """The unit each config key of a variant is written with, as written (``"ms"``, ``"rpm"``).

    The base file's value, replaced by the variant's and then by the ``--set`` overrides, as the
    loader applies them; ``""`` for a plain number (SI). Empty when the file cannot be read
    again.

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant

    Returns
    -------
    dict of str to str
    """
    try:
        raw = read_config_file(loaded.source)
    except CasFreqError:
        return {}
    written = {}
    _flatten("", {k: v for k, v in raw.items() if k != "variants"}, written)
    variants = raw.get("variants") or {}
    if isinstance(variants.get(loaded.variant), dict):
        _flatten("", variants[loaded.variant], written)
    for key, value in loaded.overrides:
        written[key] = value
    return {key: _unit_text(value) for key, value in written.items()}


def _unit_text(value):
    """The unit of a config value as written, ``""`` for a number or an unreadable string."""
    if not isinstance(value, str):
        return ""
    try:
        return split_quantity(value)[1]
    except ValueError:
        return ""


def display_units(key, variants, units):
    """The unit each variant's value of a parameter row is shown in.

    A variant's value is shown in the first unit that a compared variant of the same SI unit
    for ``key`` (the same architecture's parameter table: a cascade's position gain is in 1/s,
    a PID-on-PI's in A/rad) writes it with, else in its own SI unit (seconds as ms).

    Parameters
    ----------
    key : str
        A key of :data:`PARAMETERS`.
    variants : list of cas_freq.config.LoadedVariant
        The compared variants, the baseline first.
    units : list of dict
        One :func:`written_units` per variant, in the same order.

    Returns
    -------
    list of str
    """
    si = [parameter(key, loaded.params).unit for loaded in variants]
    shown = []
    for own in si:
        written = [w[key] for w, unit in zip(units, si, strict=True) if unit == own and w.get(key)]
        shown.append(written[0] if written else _UNWRITTEN_UNITS.get(own, own))
    return shown


def in_unit(value, key, unit, config=None):
    """An SI ``value`` [the SI unit of ``key`` in ``config``'s architecture,
    :func:`~cas_freq.core.parameters.parameter`] converted to ``unit`` (text as configs write
    units)."""
    quantity = registry().Quantity(value, parameter(key, config).unit)
    return float(quantity.to(parse_unit(unit)).magnitude)


def _same(values):
    """True when every value equals the first (numbers within 1e-9 relative: a unit
    conversion's last bits)."""
    first = values[0]
    for value in values[1:]:
        if isinstance(first, float) and isinstance(value, float):
            if not math.isclose(first, value, rel_tol=1e-9, abs_tol=0.0):
                return False
        elif first != value:
            return False
    return True


def _parameter_cell(value, derived, key, unit, config):
    """One variant's value of a parameter with its unit: ``"0.06 ms"``, ``"—"`` when not set."""
    if value is None:
        return "—"
    if isinstance(value, str):
        return value
    text = number(in_unit(value, key, unit, config), JSON_DIGITS, unit)
    return f"{text} (derived)" if derived else text


def parameter_differences(variants):
    """The config keys whose value differs between the variants, as table rows.

    Parameters
    ----------
    variants : list of cas_freq.config.LoadedVariant
        The compared variants, the baseline first.

    Returns
    -------
    rows : list of tuple of str
        Per differing key (in :func:`config_keys` order): the key, its meaning (the output named
        as the variants' configs name it, :func:`~cas_freq.config.wording.common_output_label`),
        then each variant's value in the unit the config writes it (:func:`display_units`, its
        architecture's), with the unit.
    equal : int
        How many of the :func:`config_keys` are equal in every variant.
    """
    units = [written_units(loaded) for loaded in variants]
    output = common_output_label(loaded.params for loaded in variants)
    rows, equal = [], 0
    for key in config_keys():
        values = [effective_value(loaded.params, key) for loaded in variants]
        si = [None if key in SETTINGS else parameter(key, loaded.params).unit
              for loaded in variants]
        if _same([value for value, _ in values]) and len(set(si)) == 1:
            equal += 1
            continue
        shown = ([""] * len(variants) if key in SETTINGS else
                 display_units(key, variants, units))
        rows.append((key, name_the_output(short_meaning(key, variants[0].params), output),
                     *(_parameter_cell(value, derived, key, unit, loaded.params)
                       for (value, derived), unit, loaded in zip(values, shown, variants,
                                                                 strict=True))))
    return rows, equal


def parameter_blocks(variants, labels):
    """The parameter-difference section: a heading, the table (when any differs) and how many
    parameters are equal."""
    rows, equal = parameter_differences(variants)
    total = len(config_keys())
    blocks = [Heading(2, "Parameters that differ")]
    if not rows:
        blocks.append(Paragraph(f"No config parameter differs: all {total} are equal in every "
                                "variant."))
        return blocks
    header = ("parameter", "meaning", f"{labels[0]} (baseline)", *labels[1:])
    blocks.append(Table(header, tuple(rows),
                        "config keys whose value differs between the variants, in the unit the "
                        "config writes them; (derived): not set, derived (μv from the no-load "
                        "point, Tf = Kd/(10·Kp)); —: not set"))
    blocks.append(Paragraph(f"{equal} of the {total} config parameters are equal in every "
                            "variant and not listed."))
    return blocks


# ---- every figure ------------------------------------------------------------------------------

#: Unit and factor from SI of a figure missing from the figure table (:data:`FIGURES`; the
#: drivetrain's figures), by its name's suffix.
_SUFFIX_UNITS = (("_rad_s", "rad/s", 1.0), ("_deg", "deg", 1.0), ("_db", "dB", 1.0),
                 ("_pct", "%", 1.0), ("_s", "ms", 1e3), ("_a", "A", 1.0), ("_v", "V", 1.0),
                 ("_mm", "mm", 1.0))

#: Readable name of each group of figures (the key before the figure's name).
_GROUP_LABELS = {
    "analyze": "closed loop",
    **{f"analyze.{key}": loop_label(key) for key in LOOPS},
    "analyze.closed_loop": "closed loop",
    "analyze.drivetrain": "drivetrain",
    "analyze.envelope": "rate and torque envelope",
    "sinedwell": "sine-dwell",
}

#: Groups named after a step amplitude (``step 10°``, ``fit 10°``, ``linear step 10°``): their
#: start, their readable name and the group of their figures in :data:`FIGURES`.
_STEP_GROUPS = (("linear step ", "linear step {}", "step"), ("step ", "nonlinear step {}", "step"),
                ("fit ", "fit to the {} step", "fit"))

_AMPLITUDE = re.compile(r"(?P<key>.*?) (?P<amplitude>[-+\d.e]+(?:°| mm))")


def table_figure(key):
    """The :data:`FIGURES` record of a :func:`flat_figures` key (its amplitude removed), None
    for a figure the table lacks (the drivetrain's).

    ``"analyze.position_loop.phase_margin_deg"`` is ``position_loop.phase_margin_deg``;
    ``"linear step 10°.rise_time_s"`` and ``"step 10°.rise_time_s"`` are
    ``step.rise_time_s``; ``"fit 10°.zeta"`` is ``fit.zeta``.
    """
    group, _, name = key.rpartition(".")
    if group == "analyze" or group.startswith("analyze."):
        group = group[len("analyze."):]
    else:
        group = next((table for start, _, table in _STEP_GROUPS if group.startswith(start)),
                     group)
    return FIGURES.get(f"{group}.{name}" if group else name)


def figure_display(key):
    """The readable label, display unit and factor from SI of a :func:`flat_figures` key.

    ``"analyze.current_loop.delay_margin_s"`` gives ``("current loop: delay margin [ms]",
    "ms", 1000.0)``; ``"sinedwell.bandwidth_rad_s 10°"`` gives ``("sine-dwell: bandwidth
    ω_BW (−3.01 dB) at 10° [rad/s]", "rad/s", 1.0)``. Labels, units and factors are the figure
    table's (:data:`FIGURES`); a figure it lacks is shown by its name with the unit of its
    suffix.

    Returns
    -------
    tuple of (str, str, float)
    """
    amplitude = ""
    match = _AMPLITUDE.fullmatch(key)
    if match:
        key, amplitude = match["key"], match["amplitude"]
    group, _, name = key.rpartition(".")
    figure = table_figure(key)
    if figure is None:
        label, unit, scale = _unlisted(name)
    else:
        label, unit, scale = figure.label, figure.shown_unit, figure.scale
    if amplitude:
        label += f" at {amplitude}"
    group_label = _GROUP_LABELS.get(group)
    if group_label is None:
        group_label = next((form.format(group[len(start):]) for start, form, _ in _STEP_GROUPS
                            if group.startswith(start)), group)
    text = f"{group_label}: {label}" if group_label else label
    return (f"{text} [{unit}]" if unit else text), unit, scale


def _unlisted(name):
    """(label, unit, factor from SI) of a figure name missing from :data:`FIGURES`."""
    for suffix, unit, scale in _SUFFIX_UNITS:
        if name.endswith(suffix):
            return name[: -len(suffix)].replace("_", " "), unit, scale
    return name.replace("_", " "), "", 1.0


def _scaled(value, scale):
    """A number [SI] times ``scale``; anything else (bool, text, None) unchanged."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return value * scale
    return value


def _flatten(prefix, value, out):
    if isinstance(value, dict):
        for key, item in value.items():
            _flatten(f"{prefix}.{key}" if prefix else key, item, out)
    elif isinstance(value, bool) or value is None or isinstance(value, (int, float, str)):
        out[prefix] = value


def flat_figures(results):
    """Every scalar figure of a variant's results entry, by dotted key, in a stable order.

    ``analyze.*`` (margins, closed loop, stability; not the crossover lists or the Padé
    table), ``step <a>°.*`` and ``fit <a>°.*`` (the simulated steps), ``linear step <a>°.*``,
    ``sinedwell.bandwidth <a>°`` and ``sinedwell.limit_onset_amplitude_deg``.
    """
    # a linear output's entry (its steps' amplitude_mm): every output quantity in mm
    linear = any("amplitude_mm" in run["step"] for run in results["simulate"])
    results = output_json(results, LENGTH) if linear else results
    amplitude, onset = (("amplitude_mm", "sinedwell.limit_onset_amplitude_mm") if linear else
                        ("amplitude_deg", "sinedwell.limit_onset_amplitude_deg"))

    def size(entry):  # "10°", or "5 mm"
        return f"{entry[amplitude]:g} mm" if linear else f"{entry[amplitude]:g}°"

    out = {}
    analysis = {k: v for k, v in results["analyze"].items() if k not in _NOT_FIGURES}
    _flatten("analyze", analysis, out)
    for key in [key for key in out if key.endswith(".note")]:  # words, not figures (§15's)
        del out[key]
    for run in results["simulate"]:
        a = size(run["step"])
        _flatten(f"step {a}", {k: v for k, v in run["step"].items() if k != amplitude},
                 out)
        _flatten(f"fit {a}", run["fit"], out)
    for run in results["linear_steps"]:
        a = size(run)
        _flatten(f"linear step {a}", {k: v for k, v in run.items()
                                       if k not in (amplitude, "pade_order")
                                       and v is not None}, out)
    dwell = results["sinedwell"]
    if dwell is None:  # not computed (results["not_computed"] says why)
        for run in results["simulate"]:
            out[f"sinedwell.bandwidth_rad_s {size(run['step'])}"] = "not computed"
        out[onset] = "not computed"
    else:
        for entry in dwell["amplitudes"]:
            bound = entry.get("bandwidth_bound")
            out[f"sinedwell.bandwidth_rad_s {size(entry)}"] = (
                entry["bandwidth_rad_s"] if bound is None
                else f"{bound['relation']} {bound['edge_rad_s']:.4g}")
        out[onset] = dwell[onset.rpartition(".")[2]]
    return {k: v for k, v in out.items() if not isinstance(v, list)}


def difference_rows(all_results):
    """Rows of the every-figure table, one per key of :func:`flat_figures`.

    Each row is the figure's label with its display unit (:func:`figure_display`), then per
    entry its value in that unit with :data:`TABLE_DIGITS` significant digits and (after the
    first) the difference to the first in the same unit. Keys missing from an entry show '—'.

    Returns
    -------
    rows : list of tuple of str
        ``rows[i]`` is the row of ``keys[i]``.
    flats : list of dict
        :func:`flat_figures` of each entry (SI, as results.json writes them).
    keys : list of str
    """
    flats = [flat_figures(r) for r in all_results]
    keys = list(dict.fromkeys(k for flat in flats for k in flat))
    rows = []
    for key in keys:
        label, _, scale = figure_display(key)
        base = _scaled(flats[0].get(key), scale)
        cells = [number(base, TABLE_DIGITS)]
        for flat in flats[1:]:
            value = _scaled(flat.get(key), scale)
            cells += [number(value, TABLE_DIGITS), _difference(value, base)]
        rows.append((label, *cells))
    return rows, flats, keys


def _difference(value, base):
    """The difference of the two figures, 0 below the precision the table shows them with; the
    relative change's "%" kept on the line of its number (a no-break space: a narrow column
    wraps before "(-1.26 %)", not inside it)."""
    if isinstance(value, str) or isinstance(base, str):
        return "same" if value == base else "differs"
    text = difference(value, base, 4, shown_digits=TABLE_DIGITS)
    return text.replace(" %)", "\N{NO-BREAK SPACE}%)")


def verdict_matrix(datas, labels):
    """(requirement rows, column labels) of the verdict matrix; rows empty when none."""
    ids = list(dict.fromkeys(v["id"] for d in datas for v in (d.verdicts or ())))
    rows = []
    for requirement in ids:
        cells, metric = [], ""
        for data in datas:
            found = [v for v in (data.verdicts or ()) if v["id"] == requirement]
            if data.verdicts is None:
                cells.append("not evaluated")
            elif not found:
                cells.append("—")
            else:
                verdict = found[0]
                metric = metric or verdict.get("metric", "")
                cells.append(f"{verdict['status']} ({number(verdict.get('value'))}"
                             f"{' ' + verdict['unit'] if verdict.get('unit') else ''})")
        rows.append((requirement, metric, *cells))
    return rows, ("requirement", "metric", *labels)


def compare_blocks(datas, labels, figure_blocks, settings, command=None):
    """Every block of the comparison, in order."""
    unit = output_unit(datas[0].loaded.params)  # the entries share their output's kind
    amplitudes = ", ".join(unit.symbol(math.degrees(a)) for a in settings.amplitudes_rad)
    output = common_output_label(d.loaded.params for d in datas)
    blocks = [Heading(1, "cas_freq compare: " + ", ".join(labels))]
    blocks += parameter_blocks([d.loaded for d in datas], labels)
    facts = [f"{label}: {display_path(d.loaded.source)}"
             + (" with " + ", ".join(f"{k}={v}" for k, v in d.loaded.overrides)
                if d.loaded.overrides else "")
             for label, d in zip(labels, datas, strict=True)]
    facts += [
        f"baseline (the differences are to it): {labels[0]}",
        "frequency responses: exact delays; linear steps: Padé order "
        f"{settings.pade_order}; nonlinear steps and sine-dwell: limits and exact delays",
        f"amplitudes at the {output}: {amplitudes}; sine-dwell frequencies: "
        f"{settings.frequencies_text}",
    ]
    if command:
        facts.append(f"regenerate with: {command}")
    blocks.append(Heading(2, "What was compared"))
    blocks.append(Bullets(tuple(facts)))
    blocks.append(Heading(2, "Figures overlaid"))
    blocks += list(figure_blocks.values())
    blocks.append(Heading(2, "Requirement verdicts"))
    rows, header = verdict_matrix(datas, labels)
    if rows:
        blocks.append(Table(header, tuple(rows), "status (value) per requirement and variant"))
    elif all(not d.requirements for d in datas):
        blocks.append(Paragraph("No compared config has requirements: nothing to verify."))
    else:
        blocks.append(Paragraph("The requirements were not evaluated."))
    blocks.append(Heading(2, "Every figure"))
    table_rows, _, _ = difference_rows([variant_results(d) for d in datas])
    header = ["figure", f"{labels[0]} (baseline)"]
    for label in labels[1:]:
        header += [label, f"Δ {label}"]
    blocks.append(Table(tuple(header), tuple(table_rows),
                        "each figure in the unit in brackets (results.json has them in SI "
                        "under their keys); Δ = value − baseline in that unit (relative change), "
                        "0 when below the 5 significant digits shown"))
    for text in _reference_sentences(datas):
        blocks.append(Paragraph(text))
    return blocks


def _references(datas):
    """(config name, reference) of each compared config that declares a ``reference:``."""
    seen = {}
    for data in datas:
        name = data.loaded.params.name
        if data.reference is not None and name not in seen:
            seen[name] = data.reference
    return list(seen.items())


def _reference_sentences(datas):
    """One sentence per declared reference: its source and figures in display units."""
    sentences = []
    for name, reference in _references(datas):
        shown = reference_dict(reference)
        figures = []
        for key, value in shown.items():
            if key in ("source", "fit") or value is None:
                continue
            figures.append(f"{key} {value:.4g}")
        for key, value in (shown.get("fit") or {}).items():
            if value is not None:
                figures.append(f"fit {key} {value:.4g}")
        source = f" ({reference.source})" if reference.source else ""
        sentences.append(f"Reference of {name}{source}, for comparison only: "
                         + ", ".join(figures) + ".")
    return sentences


def compare_files(datas, labels, settings, *, png=False, command=None):
    """Every file of the comparison folder as (relative path, content), figures first."""
    from cas_freq.plots import report as plots
    from cas_freq.plots.overlays import COMPARE_FIGURES

    figure_blocks = {}
    for stem, (draw, caption) in COMPARE_FIGURES.items():
        fig = draw(datas, labels)
        svg = plots.svg_text(fig)
        path = f"figures/{stem}.svg"
        yield path, svg
        if png:
            yield f"figures/{stem}.png", plots.png_bytes(fig)
        text = caption(datas, labels) if callable(caption) else caption
        figure_blocks[stem] = Figure(path, text, svg)
    blocks = compare_blocks(datas, labels, figure_blocks, settings, command)
    all_results = [variant_results(d) for d in datas]
    rows, flats, keys = difference_rows(all_results)
    matrix, header = verdict_matrix(datas, labels)

    yield "results.json", results_json(output_json({
        "baseline": labels[0],
        "labels": labels,
        "settings": settings.to_dict(),
        "references": {name: reference_dict(reference)
                       for name, reference in _references(datas)},
        "entries": [{**result, "label": label, "config": d.loaded.params.name,
                     "config_path": display_path(d.loaded.source)}
                    for label, d, result in zip(labels, datas, all_results, strict=True)],
        "figures_table": [
            {"figure": key, "values": [flat.get(key) for flat in flats],
             "differences": [difference_value(flat.get(key), flats[0].get(key), JSON_DIGITS)
                             for flat in flats]}
            for key in keys
        ],
        "verdict_matrix": {"header": list(header), "rows": [list(r) for r in matrix]},
        "figures": sorted(b.path for b in figure_blocks.values()),
    }, output_unit(datas[0].loaded.params)))  # output quantities in mm at a linear output
    yield "report.md", markdown.render(blocks)
    yield "index.html", html.render(blocks, "cas_freq compare: " + ", ".join(labels))


def build_compare(variants, out_dir=None, *, settings=None, verdicts=None, png=False,
                  command=None, selected=None, progress=None, notice=None):
    """Compute, draw and write the comparison of several variants.

    Parameters
    ----------
    variants : list of cas_freq.config.LoadedVariant
        Two or more; the first is the baseline.
    out_dir : str or Path, optional
        Default :func:`default_compare_dir`.
    settings : ReportSettings, optional
    verdicts : list of dict, optional
        Requirement verdicts; None evaluates them per variant (see
        :func:`cas_freq.report.data.requirement_verdicts`).
    png : bool
        Also write PNG figures.
    command : str, optional
        The command that regenerates the comparison.
    selected : list of str, optional
        Variant names chosen with ``--variants`` (only for the default folder name).
    progress : callable, optional
        ``progress(label)`` before each entry's computation.
    notice : callable, optional
        ``notice(text)`` with a line per entry that lacks a figure (as
        :func:`cas_freq.report.build.build_report`).

    Returns
    -------
    Path
    """
    if len(variants) < 2:
        raise CasFreqError(f"compare: needs at least two variants, got {len(variants)}; give "
                           "more configs, --variants a,b or --all-variants")
    settings = settings or ReportSettings()
    labels = entry_labels(variants)
    datas = []
    for label, loaded in zip(labels, variants, strict=True):
        if progress:
            progress(label)
        datas.append(gather_variant(loaded, settings, verdicts))
        text = not_computed_notice(datas[-1])
        if text and notice:
            notice(f"{label}: {text}")
    target = Path(out_dir) if out_dir is not None else default_compare_dir(variants, selected)
    return write_directory_atomic(target, compare_files(datas, labels, settings, png=png,
                                                        command=command))
