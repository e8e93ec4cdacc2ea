"""``cas-freq compare``: several variants (of one or more configs) side by side.

Overlaid Bode, step and bandwidth-versus-amplitude figures, a table of every numeric figure per
variant with its difference to the first (the baseline), and the requirement verdict matrix;
written as index.html, report.md and results.json (atomically, like ``report``).

A difference is that of the two figures as results.json writes them (6 significant digits,
:mod:`cas_freq.report.numbers`); in the table it is 0 when below the table's 5 significant
digits of the figures, never the noise of their last bits.
"""

import math
from pathlib import Path

from cas_freq.exceptions import CasFreqError
from cas_freq.report.build import REPORTS_DIR, results_json
from cas_freq.report.data import (
    ReportSettings,
    display_path,
    gather_variant,
    reference_dict,
    variant_results,
)
from cas_freq.report.document import Bullets, Figure, Heading, Paragraph, Table
from cas_freq.report.numbers import JSON_DIGITS, difference, difference_value, number
from cas_freq.report.outdir import MAX_NAME_LENGTH, sanitise_name, write_directory_atomic

#: Keys of the analyze JSON that are identity or bookkeeping, not figures.
_NOT_FIGURES = {"config", "config_path", "variant", "overrides", "delay_model", "notes",
                "frequency_range_rad_s", "stability_pade_order"}

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
    out = {}
    analysis = {k: v for k, v in results["analyze"].items() if k not in _NOT_FIGURES}
    _flatten("analyze", analysis, out)
    for run in results["simulate"]:
        a = f"{run['step']['amplitude_deg']:g}°"
        _flatten(f"step {a}", {k: v for k, v in run["step"].items() if k != "amplitude_deg"},
                 out)
        _flatten(f"fit {a}", run["fit"], out)
    for run in results["linear_steps"]:
        a = f"{run['amplitude_deg']:g}°"
        _flatten(f"linear step {a}", {k: v for k, v in run.items()
                                       if k not in ("amplitude_deg", "pade_order")
                                       and v is not None}, out)
    dwell = results["sinedwell"]
    for entry in dwell["amplitudes"]:
        out[f"sinedwell.bandwidth_rad_s {entry['amplitude_deg']:g}°"] = entry["bandwidth_rad_s"]
    out["sinedwell.limit_onset_amplitude_deg"] = dwell["limit_onset_amplitude_deg"]
    return {k: v for k, v in out.items() if not isinstance(v, list)}


def difference_rows(all_results):
    """Rows of the every-figure table: key, then per entry its value and (after the first) the
    difference to the first. Keys missing from an entry show '—'."""
    flats = [flat_figures(r) for r in all_results]
    keys = list(dict.fromkeys(k for flat in flats for k in flat))
    rows = []
    for key in keys:
        base = flats[0].get(key)
        cells = [number(base, TABLE_DIGITS)]
        for flat in flats[1:]:
            value = flat.get(key)
            cells += [number(value, TABLE_DIGITS), _difference(value, base)]
        rows.append((key, *cells))
    return rows, flats, keys


def _difference(value, base):
    """The difference of the two figures, 0 below the precision the table shows them with."""
    if isinstance(value, str) or isinstance(base, str):
        return "same" if value == base else "differs"
    return difference(value, base, 4, shown_digits=TABLE_DIGITS)


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
    amplitudes = ", ".join(f"{math.degrees(a):g}°" for a in settings.amplitudes_rad)
    blocks = [Heading(1, "cas_freq compare: " + ", ".join(labels))]
    facts = [f"{label}: {display_path(d.loaded.source)}"
             + (" with " + ", ".join(f"{k}={v}" for k, v in d.loaded.overrides)
                if d.loaded.overrides else "")
             for label, d in zip(labels, datas, strict=True)]
    facts += [
        f"baseline (the differences are to it): {labels[0]}",
        "frequency responses: exact delays; linear steps: Padé order "
        f"{settings.pade_order}; nonlinear steps and sine-dwell: limits and exact delays",
        f"amplitudes at the output: {amplitudes}; sine-dwell frequencies: "
        f"{settings.frequencies_text}",
    ]
    if command:
        facts.append(f"regenerate with: {command}")
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
                        "units from each key's suffix (_rad_s rad/s, _deg deg, _db dB, _pct %, "
                        "_s s, _a A, _v V); Δ = value − baseline (relative change), 0 when below "
                        "the 5 significant digits shown"))
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
    from cas_freq.report import html, markdown

    figure_blocks = {}
    for stem, (draw, caption) in plots.COMPARE_FIGURES.items():
        fig = draw(datas, labels)
        svg = plots.svg_text(fig)
        path = f"figures/{stem}.svg"
        yield path, svg
        if png:
            yield f"figures/{stem}.png", plots.png_bytes(fig)
        figure_blocks[stem] = Figure(path, caption, svg)
    blocks = compare_blocks(datas, labels, figure_blocks, settings, command)
    all_results = [variant_results(d) for d in datas]
    rows, flats, keys = difference_rows(all_results)
    matrix, header = verdict_matrix(datas, labels)
    yield "results.json", results_json({
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
    })
    yield "report.md", markdown.render(blocks)
    yield "index.html", html.render(blocks, "cas_freq compare: " + ", ".join(labels))


def build_compare(variants, out_dir=None, *, settings=None, verdicts=None, png=False,
                  command=None, selected=None, progress=None):
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
    target = Path(out_dir) if out_dir is not None else default_compare_dir(variants, selected)
    return write_directory_atomic(target, compare_files(datas, labels, settings, png=png,
                                                        command=command))
