"""``cas-freq report``: one folder with index.html, report.md, results.json and the figures.

:func:`build_report` gathers every variant's data (:mod:`cas_freq.report.data`), draws the
figures (:mod:`cas_freq.plots.report`; in two worker processes while the next variant is
computed, :class:`~cas_freq.report.rendering.FigureRenderer`), lays out the content once as blocks
(:mod:`cas_freq.report.document`) and renders them as Markdown and self-contained HTML; the
folder is written atomically (:mod:`cas_freq.report.outdir`). The same input gives the same
bytes in every file on one machine; every number is written at a stated precision
(:mod:`cas_freq.core.numbers`), so other machines differ at most in a last rounded digit.
"""

import hashlib
import json
import math
import os
import time
from pathlib import Path

from cas_freq.analysis.limit_cycles import report_sentence
from cas_freq.analysis.rate_envelope import envelope_lines
from cas_freq.config.wording import OutputWords
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.figures import FIGURES
from cas_freq.core.numbers import JSON_DIGITS, number, rounded_json
from cas_freq.core.output import output_json, output_unit
from cas_freq.core.parameters import current_limit
from cas_freq.report import html, markdown
from cas_freq.report.data import (
    SINEDWELL_FIGURES,
    ReportSettings,
    described_loops,
    display_path,
    gather_frequency,
    gather_time,
    not_computed,
    not_computed_notice,
    reference_dict,
    reference_rows,
    sinedwell_bandwidth,
    variant_results,
)
from cas_freq.report.disturbance import disturbance_blocks
from cas_freq.report.document import Bullets, Figure, Heading, Paragraph, Table
from cas_freq.report.drivetrain import drivetrain_blocks
from cas_freq.report.envelope import envelope_job, envelope_section, envelope_variants
from cas_freq.report.nonlinear import nonlinear_elements
from cas_freq.report.outdir import sanitise_name, write_directory_atomic
from cas_freq.report.parameter_table import parameter_table
from cas_freq.report.profile import profile_section
from cas_freq.report.rendering import FIGURE_WORKERS, FigureRenderer, render_figures
from cas_freq.report.text import pade_columns
from cas_freq.report.tolerances import tolerance_section
from cas_freq.report.workers import prepare_kernels
from cas_freq.studies.run import diverged_at

#: Folder that holds the reports by default (relative to the working directory).
REPORTS_DIR = Path("reports")

_VERDICT_COLUMNS = ("id", "variant", "metric", "value", "unit", "min", "max", "margin", "status",
                    "severity", "message")


def default_report_dir(config_name):
    """``reports/<config name>`` with the name made safe for a folder."""
    return REPORTS_DIR / sanitise_name(config_name)


def results_json(value):
    """Strict JSON text (no NaN), indented, ending with a newline; every float rounded to
    :data:`~cas_freq.core.numbers.JSON_DIGITS` significant digits, 0 when numerically zero
    (:func:`cas_freq.core.numbers.rounded_json`)."""
    return json.dumps(rounded_json(value, JSON_DIGITS), indent=2, allow_nan=False,
                      ensure_ascii=False) + "\n"


# ---- tables ---------------------------------------------------------------------------------

def verdict_blocks(datas):
    """The requirement-verdict section: a table, or a plain sentence saying why there is none."""
    requirements = {len(d.requirements) for d in datas}
    if requirements == {0}:
        return [Paragraph(f"The config {datas[0].loaded.params.name!r} has no requirements (no "
                          "`requirements:` list), so there is nothing to verify.")]
    blocks = []
    missing = [d.loaded.variant for d in datas if d.verdicts is None and d.requirements]
    if missing:
        blocks.append(Paragraph(
            f"The requirements were not evaluated for variant(s) {', '.join(missing)}."))
    rows = []
    for data in datas:
        for verdict in data.verdicts or ():
            rows.append(tuple(number(verdict.get(key), 5) for key in _VERDICT_COLUMNS))
    if rows:
        blocks.append(Table(_VERDICT_COLUMNS, tuple(rows), "requirement verdicts"))
    return blocks


def reference_blocks(datas):
    """The "reference vs model" section: the config's ``reference:`` figures (measured or
    published) beside each variant's; no block when the config declares none."""
    reference = datas[0].reference
    if reference is None:
        return []
    names = [d.loaded.variant for d in datas]
    rows_by_variant = [reference_rows(d) for d in datas]
    rows = []
    for k, (figure, unit, value, _) in enumerate(rows_by_variant[0]):
        rows.append((figure, unit, number(value),
                     *(number(rows[k][3]) for rows in rows_by_variant)))
    steps = {_step_text(d.dwell.steps[d.reference_index]) for d in datas}
    size = ("" if reference.step_amplitude is None
            else f" ({math.degrees(reference.step_amplitude):g}° step)")
    source = f"{reference.source}: " if reference.source else ""
    return [Heading(2, "Reference vs model"),
            Table(("figure", "unit", f"reference{size}", *names), tuple(rows),
                  f"{source}declared in the config's reference: section, for comparison only "
                  f"(never used by the model); model steps of {'/'.join(sorted(steps))}")]


def _figure_row(key, value, prefix=""):
    """(label, shown unit, value) of a figure of the table (:data:`FIGURES`), the label after
    ``prefix``."""
    figure = FIGURES[key]
    return f"{prefix}{figure.label}", figure.shown_unit, FIGURES[key].shown(value)


#: The summary's figures of each loop (keys of :data:`FIGURES` after the loop's name).
_SUMMARY_LOOP_FIGURES = {
    "current_loop": ("phase_margin_deg", "crossover_rad_s", "gain_margin_db"),
    "current_loop.loop_at_a_time": ("phase_margin_deg", "crossover_rad_s", "gain_margin_db"),
    "velocity_loop": ("phase_margin_deg", "crossover_rad_s", "gain_margin_db"),
    "velocity_loop.loop_at_a_time": ("phase_margin_deg", "crossover_rad_s", "gain_margin_db"),
    "position_loop": ("phase_margin_deg", "crossover_rad_s", "delay_margin_s", "gain_margin_db",
                      "gain_margin_low_db", "sensitivity_peak_db", "disk_margin_gain_db",
                      "disk_margin_phase_deg"),
}


#: The continuous figures shown beside sampled ones (loop -> figures; ``closed_loop`` too).
_SUMMARY_CONTINUOUS = {
    "current_loop": ("phase_margin_deg", "gain_margin_db"),
    "velocity_loop": ("phase_margin_deg", "gain_margin_db"),
    "position_loop": ("phase_margin_deg", "gain_margin_db"),
    "closed_loop": ("bandwidth_rad_s", "peak_db"),
}


def summary_rows(data, continuous=False):
    """Headline figures of one variant: (figure, unit, value); with ``continuous`` (some
    variant of the table has sampled controllers) also the figures of its loops run
    continuously (a continuous variant's are its own)."""
    a = data.analysis
    cl = a.closed_loop
    poles = "Padé or discrete-time poles" if continuous else "Padé poles"
    rows = [(f"closed loop ({poles})", "", a.stability.verdict)]
    symbols = {loop.name: loop.symbol for loop in data.curves.described}
    for loop, names in _SUMMARY_LOOP_FIGURES.items():
        margins = a
        for part in loop.split("."):
            margins = margins and getattr(margins, part)
        if margins is None:  # a drive without that loop
            continue
        name, _, view = loop.partition(".")
        symbol = symbols[name] + (" (others closed)" if view else "")
        rows += [_figure_row(f"{loop}.{name}", getattr(margins, name), f"{symbol} ")
                 for name in names]
    rows += [_figure_row(f"closed_loop.{name}", getattr(cl, name) if cl else None, "T ")
             for name in ("bandwidth_rad_s", "peak_db", "phase_90_rad_s")]
    if continuous:
        rows += _continuous_rows(a, symbols)
    for k, run in enumerate(data.dwell.steps):  # one step per sine-dwell amplitude
        label, unit, _ = _figure_row("sinedwell.bandwidth_rad_s", None, "sine-dwell ")
        rows.append((f"{label} at {_step_text(run)}", unit,
                     sinedwell_bandwidth(data, k)))
    for k in sorted({data.small_index, data.large_index}):
        step = data.dwell.steps[k]
        prefix = f"{_step_text(step)} step "
        rows += [_figure_row(f"step.{name}", getattr(step.step, name), prefix)
                 for name in ("rise_time_s", "overshoot_pct", "settling_time_s")]
        rows += [(f"{prefix}limits", "", _limits_text(step.step)),
                 _figure_row("fit.bandwidth_closed_form_rad_s",
                             step.fit.bandwidth_closed_form_rad_s, f"{prefix}fit ")]
    return rows


def _continuous_rows(analysis, symbols):
    """The ``continuous`` figures of a sampled variant (a continuous one's own figures);
    ``symbols``: each loop's by name."""
    rows = []
    for loop, names in _SUMMARY_CONTINUOUS.items():
        own = getattr(analysis, loop)
        if own is None and loop != "closed_loop":  # a drive without that loop
            continue
        symbol = symbols.get(loop, "T")
        for name in names:
            value = (analysis.continuous[loop][name] if analysis.continuous
                     else own and getattr(own, name))
            label, unit, shown = _figure_row(f"{loop}.{name}", value, f"{symbol} ")
            rows.append((f"{label}, controllers continuous", unit, shown))
    return rows


def summary_table(datas):
    """Headline figures of every variant side by side."""
    sampled = any(d.analysis.sampling for d in datas)
    per_variant = [summary_rows(d, sampled) for d in datas]
    rows = []
    for k, (figure, unit, _) in enumerate(per_variant[0]):
        rows.append((figure, unit, *(number(values[k][2]) for values in per_variant)))
    note = ("; sampled controllers at their sampling instants, each figure also with the "
            "controllers continuous" if sampled else "")
    return Table(("figure", "unit", *(d.loaded.variant for d in datas)), tuple(rows),
                 f"headline figures (frequency responses with exact delays{note})")


def _limits_text(step):
    hit = [name for name, flag in (("current", step.current_limited),
                                   ("voltage", step.voltage_limited)) if flag]
    return "none hit" if not hit else " and ".join(hit) + " limit hit"


def analysis_loops(analysis):
    """(key of :data:`~cas_freq.core.figures.LOOPS`, symbol, break point, margins) of every loop of
    an analysis, innermost first, then each inner loop with every other loop closed. The
    symbols and break points are the loop structure's
    (:func:`cas_freq.model.structure.build`: a cascade's position loop is broken at the
    velocity command)."""
    described = described_loops(analysis.loaded.params)
    views = [(loop.name, loop, getattr(analysis, loop.name), loop.break_point)
             for loop in described]
    views += [(f"{name}.loop_at_a_time", loop, margins.loop_at_a_time,
               f"{where}, every other loop closed")
              for name, loop, margins, where in views[:-1] if margins.loop_at_a_time is not None]
    return [(key, loop.symbol, where, margins) for key, loop, margins, where in views]


def margins_table(analysis):
    """Every margin figure of every loop, and of each inner loop with every other loop closed
    (labels and units of :data:`FIGURES`)."""
    loops = analysis_loops(analysis)
    rows = []
    for figure in FIGURES.values():
        if figure.loop != "current_loop" or not figure.requirement:
            continue
        rows.append((figure.label, figure.shown_unit or "-",
                     *(number(figure.shown(getattr(margins, figure.name)))
                       for *_, margins in loops)))
    rows.append(("crossings in range", "",
                 *(f"{len(margins.gain_crossovers)} gain, {len(margins.phase_crossovers)} phase"
                   for *_, margins in loops)))
    columns = tuple(f"{symbol} ({where})" for _, symbol, where, _ in loops)
    return Table(("figure", "unit", *columns), tuple(rows),
                 f"stability margins ({analysis.delay_model} delays)")


def crossings_table(analysis, frequency_range):
    """Every gain and phase crossover of both loops inside the plotted range."""
    low, high = frequency_range
    rows = []
    for key, symbol, _, loop in analysis_loops(analysis):
        name = symbol if "." not in key else f"{symbol} (every other loop closed)"
        pm, dm, gm = (FIGURES[f"{key}.{figure}"] for figure in (
            "phase_margin_deg", "delay_margin_s", "gain_margin_db"))
        for c in loop.gain_crossovers:
            if low <= c.frequency_rad_s <= high:
                rows.append((name, "gain crossover", number(c.frequency_rad_s),
                             f"{pm.label} {number(c.phase_margin_deg, unit=pm.shown_unit)}, "
                             f"{dm.label} "
                             f"{number(dm.shown(c.delay_margin_s), unit=dm.shown_unit)}"))
        for c in loop.phase_crossovers:
            if low <= c.frequency_rad_s <= high:
                rows.append((name, "phase crossover", number(c.frequency_rad_s),
                             f"gain margin {number(c.gain_margin_db, unit=gm.shown_unit)}"))
    return Table(("loop", "kind", "frequency [rad/s]", "margin"), tuple(rows),
                 f"every crossover in {low:g}..{high:g} rad/s (the plotted range)")


def closed_loop_table(analysis):
    """Closed-loop figures of T."""
    cl = analysis.closed_loop
    if cl is None:
        return Paragraph("The closed loop is not stable: no closed-loop figures.")
    rows = tuple((figure.label, figure.shown_unit,
                  number(figure.shown(getattr(cl, figure.name))))
                 for figure in FIGURES.values()
                 if figure.key.startswith("closed_loop.") and figure.requirement)
    x = OutputWords.of(analysis.loaded.params if analysis.loaded is not None else None).symbol
    return Table(("figure", "unit", f"T = {x}/{x}_cmd"), rows,
                 f"closed-loop figures ({analysis.delay_model} delays)")


def pade_table(analysis):
    """The Padé-vs-exact table of the analysis (the columns of
    :func:`cas_freq.report.text.pade_columns`)."""
    columns = pade_columns(analysis)
    rows = tuple((r.delay_model,
                  *(number(FIGURES[key].shown(getattr(r, attribute)))
                    for _, attribute, key in columns),
                  number(r.closed_loop_max_error, 3))
                 for r in analysis.pade_vs_exact)
    return Table(("delay model", *(heading for heading, *_ in columns),
                  "max |T_pade − T_exact|"), rows,
                 "headline figures with Padé delays of each order beside exact delays")


def _step_text(run):
    """A StepRun's size as labels show it: ``"10°"``, at a linear output ``"5 mm"``."""
    return run.output_unit.symbol(run.step.amplitude_deg)


def step_table(data):
    """Step figures of the smallest and largest steps, nonlinear and linear."""
    columns, figures = [], []
    for k in sorted({data.small_index, data.large_index}):
        run = data.dwell.steps[k]
        size = _step_text(run)
        columns += [f"{size} nonlinear", f"{size} linear (Padé {data.pade_order})"]
        figures += [run.step, data.linear_step_figures[k]]
    rows = tuple((figure.label, figure.shown_unit,
                  *(number(figure.shown(getattr(f, figure.name))) for f in figures))
                 for figure in FIGURES.values() if figure.key.startswith("step."))
    return Table(("figure", "unit", *columns), rows,
                 "step figures (nonlinear: limits and exact delays; linear: no limits)")


def fit_table(data):
    """Second-order fits of every step, beside the reference's fit when the config declares
    one."""
    rows = []
    td = FIGURES["fit.td_s"]
    for run in data.dwell.steps:
        fit = run.fit
        rows.append((f"{_step_text(run)} step (model)", number(fit.wn_rad_s),
                     number(fit.zeta, 3), number(td.shown(fit.td_s), 3),
                     number(fit.bandwidth_closed_form_rad_s),
                     number(fit.rms_residual * run.output_unit.scale, 3),
                     "yes" if fit.success else "no"))
    reference = data.reference
    if reference is not None and reference.fit is not None:
        fit = reference.fit
        size = ("" if reference.step_amplitude is None
                else f"{math.degrees(reference.step_amplitude):g}° ")
        rows.append((f"{size}step (reference)", number(fit.wn), number(fit.zeta),
                     number(td.shown(fit.td)), number(fit.bandwidth_rad_s), "—", "—"))
    shown = output_unit(data.loaded.params).shown  # the residual is in the output's unit
    header = tuple(f"{f.label} [{shown if f.key == 'fit.rms_residual' else f.shown_unit or '-'}]"
                   if f.name != "success" else f.label
                   for f in FIGURES.values() if f.key.startswith("fit.") and f.output != "length")
    return Table(("step", *header), tuple(rows),
                 "second-order-plus-delay fits (docs/model.md §7)")


def bandwidth_table(data):
    """Bandwidth three ways per amplitude."""
    result = data.dwell.result
    unit = output_unit(data.loaded.params)
    rows = []
    for k, run in enumerate(data.dwell.steps):  # one step per sine-dwell amplitude
        hit = "not computed" if result is None else number(bool(result.limit_hit[k].any()))
        rows.append((f"{unit.value(run.step.amplitude_deg):g}",
                     number(data.dwell.linear_bandwidth_rad_s),
                     number(sinedwell_bandwidth(data, k)),
                     number(run.fit.bandwidth_closed_form_rad_s), hit))
    onset = data.dwell.limit_onset_rad
    w = data.dwell.frequencies_rad_s
    if result is None:
        caption = ("bandwidth three ways; the sine-dwell was not computed: "
                   f"{data.dwell.not_computed}")
    else:
        caption = ("bandwidth three ways; a limit first acts at "
                   f"{unit.symbol(math.degrees(onset))}" if onset is not None else
                   "bandwidth three ways; no limit acts at any amplitude")
        caption += (f"; sine-dwell grid {len(w)} points over {w[0]:.4g}..{w[-1]:.4g} rad/s"
                    "; > / <: the −3.01 dB point lies beyond the grid's top / bottom")
    return Table((f"amplitude [{unit.shown}]", "linear −3 dB of T [rad/s]",
                  "sine-dwell −3 dB [rad/s]", "step fit closed form [rad/s]",
                  "limit acts in the dwell"), tuple(rows),
                 caption)


def small_signal_sentence(data):
    """Whether the smallest step stays clear of the limits, and what else (if anything) sets
    the nonlinear simulation apart from the linear model (:func:`nonlinear_elements`)."""
    run = data.dwell.steps[data.small_index]
    step = run.step
    params = data.loaded.params
    diverged = diverged_at(run)
    if diverged is not None:
        return (f"The {_step_text(run)} step diverged (beyond 10⁶ times the step at t = "
                f"{number(diverged * 1e3)} ms), so it has no figures and no fit.")
    head = (f"The {_step_text(run)} step reaches {number(step.max_current_a)} A of the "
            f"±{current_limit(params):g} A current limit and {number(step.max_voltage_v)} V "
            f"of the ±{params.current_loop.v_max:g} V voltage limit: ")
    elements = nonlinear_elements(params, data.analysis.drivetrain is not None)
    others = "; ".join(elements)
    if step.current_limited or step.voltage_limited:
        tail = f" The simulation also has {others}." if elements else ""
        return head + (f"{_limits_text(step)}, so even this step is not small-signal; the "
                       "linear model is not its reference." + tail)
    if elements:
        return head + ("no limit is hit, but the simulation has elements the linear model does "
                       f"not: {others}. Differences between the nonlinear and the linear step "
                       "come from these.")
    return head + ("no limit is hit, so it is the small-signal case and the nonlinear "
                   "simulation should agree with the linear model (differences come from the "
                   f"Padé order {data.pade_order} delays of the linear model).")


# ---- the document ---------------------------------------------------------------------------

def variant_slug(data):
    """Folder name of a variant's figures."""
    return sanitise_name(data.loaded.variant, fallback="variant")


def variant_blocks(data, figure_blocks, settings):
    """The section of one variant."""
    a = data.analysis
    blocks = [Heading(2, f"Variant {data.loaded.variant}")]
    poles = ("discrete-time poles of the sampled loops" if a.sampling else
             f"poles of the Padé order {a.stability.pade_order} model")
    blocks.append(Paragraph(
        f"{data.label}: closed loop {a.stability.verdict} ({poles}); every frequency response "
        "below uses exact delays."))
    if a.notes:
        blocks.append(Bullets(tuple(a.notes)))
    blocks += drivetrain_blocks(data)
    if getattr(a, "limit_cycles", None) is not None:
        blocks.append(Paragraph(report_sentence(a.limit_cycles,
                                                output_unit(data.loaded.params))))
    blocks += [Heading(3, f"Frequency response ({data.loaded.variant})"), margins_table(a),
               crossings_table(a, data.curve_range_rad_s), closed_loop_table(a)]
    blocks += [figure_blocks[n] for n in ("bode_loops", "closed_loop", "sensitivity", "nichols",
                                          "nyquist", "pole_zero")]

    blocks += disturbance_blocks(data, figure_blocks.get("stiffness"))
    blocks += [Heading(3, f"Padé vs exact delays ({data.loaded.variant})"), pade_table(a)]
    blocks += [Heading(3, f"Step responses ({data.loaded.variant})"),
               Paragraph(small_signal_sentence(data)), step_table(data), figure_blocks["steps"],
               fit_table(data), figure_blocks["step_fit"]]
    blocks += [Heading(3, f"Bandwidth versus amplitude ({data.loaded.variant})"),
               bandwidth_table(data), figure_blocks["bandwidth_vs_amplitude"],
               figure_blocks["sinedwell"]]
    if a.envelope is not None:  # the rate and torque envelope (docs/model.md §15)

        blocks.append(Paragraph("Rate and torque " + "; ".join(envelope_lines(
            a.envelope, output_unit(data.loaded.params), data.loaded.params.output_label))
            + ". The sine-dwell figure's lowest panel draws these limits with the dwell's own "
            "feed-forward setting."))
    return blocks


def overall_verdict(datas):
    """The report's first sentence: PASS / FAIL of the required requirements over every
    variant, unstable variants named plainly, failed advisories counted."""
    unstable = [d.loaded.variant for d in datas if not d.analysis.stable]
    failed, advisory, unevaluated = [], [], []
    for data in datas:
        if data.requirements and data.verdicts is None:
            unevaluated.append(data.loaded.variant)
        for verdict in data.verdicts or ():
            if verdict.get("status") == "FAIL":
                failed.append(f"{verdict.get('id')} on {data.loaded.variant}")
            elif verdict.get("status") == "ADVISORY":
                advisory.append(f"{verdict.get('id')} on {data.loaded.variant}")
    names = ", ".join(d.loaded.variant for d in datas)
    has_requirements = any(d.requirements for d in datas)
    if failed or unstable:
        head = "Verdict: FAIL."
    elif not has_requirements or unevaluated:
        head = "Verdict: not judged."
    else:
        head = "Verdict: PASS."
    parts = [head]
    for name in unstable:
        verdict = next(d.analysis.stability.verdict for d in datas if d.loaded.variant == name)
        state = "UNSTABLE" if verdict == "unstable" else f"NOT STABLE ({verdict})"
        parts.append(f"Variant {name} is {state} in closed loop: its margins below are not a "
                     "working design and it has no closed-loop figures.")
    if not has_requirements:
        parts.append("The config has no requirements, so nothing was checked.")
    elif failed:
        parts.append(f"Required requirements failed: {', '.join(failed)}.")
    elif unevaluated:
        parts.append(f"The requirements were not evaluated for {', '.join(unevaluated)}.")
    else:
        parts.append(f"Every required requirement passes on every variant ({names}).")
    if advisory:
        parts.append(f"Advisory requirements not met (reported, never failing): "
                     f"{', '.join(advisory)}.")
    return " ".join(parts)


def config_hash(path):
    """First 12 hex digits of the sha256 of the config file's bytes, or None if unreadable."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:12]
    except (OSError, TypeError):
        return None


def _version():
    from cas_freq import __version__

    return __version__


def footer_text(datas):
    """Who made the report from what: tool version, config path and content hash; a date only
    from SOURCE_DATE_EPOCH (so that the same input gives the same bytes)."""
    source = datas[0].loaded.source
    digest = config_hash(source)
    text = (f"Generated by cas_freq {_version()} from config {display_path(source)} "
            f"(sha256 {digest or 'unavailable'})")
    epoch = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
    if epoch.isdigit():
        text += f" on {time.strftime('%Y-%m-%d', time.gmtime(int(epoch)))} (UTC)"
    return text + "."


def report_blocks(datas, figure_blocks, settings, command=None, extra=()):
    """Every block of the report, in order: the verdict, the parameters, the summary, the
    requirement verdicts, the reference (if declared), one section per variant, the footer.

    Parameters
    ----------
    datas : list of VariantData
    figure_blocks : list of dict of str to Figure
        Per variant, the figure blocks by file stem.
    settings : ReportSettings
    command : str, optional
        The command that regenerates the report, shown near the top.
    extra : sequence of blocks
        Sections shown after the reference (the profile moves and the load envelope,
        :mod:`cas_freq.report.profile`, :mod:`cas_freq.report.envelope`).
    """
    params = datas[0].loaded.params
    amplitudes = ", ".join(output_unit(params).symbol(math.degrees(a))
                           for a in settings.amplitudes_rad)
    blocks = [Heading(1, f"cas_freq report: {params.name}"), Paragraph(overall_verdict(datas))]
    if params.description:
        blocks.append(Paragraph(params.description))
    facts = [
        f"config: {display_path(datas[0].loaded.source)}; variants: "
        + ", ".join(d.loaded.variant for d in datas),
        "frequency responses, margins and bandwidth: exact delays (e^(−sτ)); stability: poles "
        "of the Padé model; linear step responses: Padé order "
        f"{settings.pade_order}; nonlinear simulation: exact delays as delay lines, ±i_max and "
        "±v_max clamps with anti-windup",
        f"sine-dwell and step amplitudes at the {params.output_label}: {amplitudes}; sine-dwell "
        "frequencies: "
        f"{settings.frequencies_text} (one batch per variant, "
        "feed-forward off as in docs/model.md's T)",
        "figure definitions: docs/model.md (motor-shaft loops, "
        f"{OutputWords.of(params).definition})",
    ]
    if command:
        facts.append(f"regenerate with: {command}")
    blocks.append(Bullets(tuple(facts)))
    blocks += [Heading(2, "Parameters"), parameter_table(datas),
               Heading(2, "Summary"), summary_table(datas),
               Heading(2, "Requirement verdicts"), *verdict_blocks(datas),
               *reference_blocks(datas), *extra]
    for data, figures in zip(datas, figure_blocks, strict=True):
        blocks += variant_blocks(data, figures, settings)
    blocks.append(Paragraph(footer_text(datas)))
    return blocks


def _figure_files(data, png, rendered=None):
    """Yield (path, content) of a variant's figures; returns {stem: Figure block}.
    ``rendered``: the variant's figures already drawn (:meth:`FigureRenderer.results`); None
    draws them here."""
    from cas_freq.plots.report import VARIANT_FIGURES

    if rendered is None:
        drawn = render_figures(data, list(VARIANT_FIGURES), png)
        rendered = {stem: rest for stem, *rest in drawn}

    slug = variant_slug(data)
    blocks = {}
    for stem, (svg, png_data, text) in rendered.items():
        path = f"figures/{slug}/{stem}.svg"
        yield path, svg
        if png:
            yield f"figures/{slug}/{stem}.png", png_data
        blocks[stem] = Figure(path, f"{text} — {data.label}", svg)
    reason = not_computed(data).get("sinedwell")
    for stem in SINEDWELL_FIGURES if reason else ():
        caption = VARIANT_FIGURES[stem][1]
        caption = caption(data) if callable(caption) else caption
        blocks[stem] = Paragraph(f"{caption} — {data.label}: not computed: {reason}.")
    return blocks


def report_files(datas, settings, *, png=False, command=None, rendered=None, envelopes=None):
    """Every file of the report folder as (relative path, content), figures first.
    ``rendered``: per variant, its figures already drawn (:meth:`FigureRenderer.results`);
    None draws them here, one after the other. ``envelopes``: the load envelopes already
    computed and drawn (:func:`cas_freq.report.envelope.envelope_section`'s ``computed``)."""
    figure_blocks = []
    for k, data in enumerate(datas):
        figure_blocks.append((yield from _figure_files(
            data, png, None if rendered is None else rendered[k])))

    profile = yield from profile_section(datas, png)  # nothing without a profile requirement
    # nothing without a load_envelope:
    envelope = yield from envelope_section(datas, png, envelopes)
    tolerance = yield from tolerance_section(datas, png)  # nothing without tolerances:
    blocks = report_blocks(datas, figure_blocks, settings, command,
                           (*profile.blocks, *envelope.blocks, *tolerance.blocks))
    params = datas[0].loaded.params
    yield "results.json", results_json(output_json({
        "config": params.name,
        "config_path": display_path(datas[0].loaded.source),
        "description": params.description,
        "settings": settings.to_dict(),
        "generated_by": {"tool": "cas_freq", "version": _version(),
                         "config_sha256": config_hash(datas[0].loaded.source)},
        "reference": reference_dict(params.reference),
        "variants": [variant_results(d) for d in datas],
        **profile.results,
        **envelope.results,
        **tolerance.results,
        "figures": {d.loaded.variant: sorted(b.path for b in f.values()
                                             if isinstance(b, Figure))
                    for d, f in zip(datas, figure_blocks, strict=True)},
    }, output_unit(params)))
    yield "report.md", markdown.render(blocks)
    yield "index.html", html.render(blocks, f"cas_freq report: {params.name}")


def build_report(variants, out_dir=None, *, settings=None, verdicts=None, png=False,
                 command=None, progress=None, workers=FIGURE_WORKERS, notice=None):
    """Compute, draw and write the report of one config's variants.

    Parameters
    ----------
    variants : list of cas_freq.config.LoadedVariant
        Variants of one config (each one a section of the report).
    out_dir : str or Path, optional
        Report folder; default ``reports/<config name>`` (sanitised).
    settings : ReportSettings, optional
        Amplitudes, frequencies, Padé order (defaults: :class:`ReportSettings`).
    verdicts : list of dict, optional
        Requirement verdicts (``cas-freq verify`` JSON); None evaluates them through
        :func:`cas_freq.report.data.requirement_verdicts`.
    png : bool
        Also write every figure as PNG.
    command : str, optional
        The command that regenerates the report (shown in it).
    progress : callable, optional
        ``progress(label)`` called before each variant's computation.
    notice : callable, optional
        ``notice(text)`` with a line naming a variant and the figures of it that were not
        computed, and why (:func:`~cas_freq.report.data.not_computed_notice`); the report
        shows them as "not computed: ..." and is written whole.
    workers : int
        Processes that draw the figures while the next variant is computed
        (:class:`FigureRenderer`); 1 draws them in this process. The files are the same.

    Returns
    -------
    Path
        The report folder.
    """
    if not variants:
        raise CasFreqError("report: no variant selected")
    names = {v.params.name for v in variants}
    if len(names) > 1:
        raise CasFreqError(f"report: variants of one config expected, got configs {sorted(names)}"
                           "; use `cas-freq compare` for several configs")

    settings = settings or ReportSettings()
    params = variants[0].params
    enveloped = envelope_variants(params)
    datas, envelopes = [], {}
    if workers > 1:
        # compiled (first run) or loaded here once, then inherited by the forked workers
        prepare_kernels(variants)
    with FigureRenderer(workers, png) as renderer:
        if renderer.parallel:
            # a worker computes and draws the load envelopes first, while this process
            # analyses and simulates the first variant (the other worker draws its figures)
            envelopes = {loaded.variant: renderer.draw(envelope_job, loaded,
                                                       params.load_envelope, None,
                                                       params.name, png)
                         for loaded in variants
                         if enveloped is None or loaded.variant in enveloped}
        for index, loaded in enumerate(variants):
            if progress:
                progress(loaded.variant)
            early = gather_frequency(loaded, settings)
            renderer.submit(index, early, "frequency")
            datas.append(gather_time(early, settings, verdicts))
            renderer.submit(index, datas[-1], "time")
            text = not_computed_notice(datas[-1])
            if text and notice:
                notice(text)
        rendered = renderer.results()
        target = Path(out_dir) if out_dir is not None else default_report_dir(params.name)
        return write_directory_atomic(target, report_files(
            datas, settings, png=png, command=command, rendered=rendered, envelopes=envelopes))
