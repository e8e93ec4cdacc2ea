"""Profile moves in text and in the report: the ``simulate --profile`` table and the report's
"Profile move" section (shown when the config has a ``profile.*`` requirement).

No matplotlib here but in :func:`profile_figure_svg`, which imports it when it draws.
"""

import math

from cas_freq.core.figures import FIGURES
from cas_freq.core.numbers import number
from cas_freq.core.output import output_unit
from cas_freq.report.document import Figure, Heading, Paragraph, Table
from cas_freq.report.outdir import sanitise_name
from cas_freq.simulation.commands import condition_profile
from cas_freq.studies.profile_run import (
    move_dict,
    profile_condition_text,
    profile_run_dict,
    profile_runs,
)


def _trapezoid_text(move, unit):
    t_a, t_c, t_d = (float(x) for x in move.phases())
    shape = "Trapezoidal" if t_c > 0 else "Triangular (the velocity limit is not reached)"
    peak = unit.value(math.degrees(float(move.peak_rate_rad_s)))
    return (f"{shape}: peak {number(peak, 4, f'{unit.shown}/s')}, "
            f"accelerating {number(t_a * 1e3, 4, 'ms')}, cruising {number(t_c * 1e3, 4, 'ms')}, "
            f"decelerating {number(t_d * 1e3, 4, 'ms')}")


def _limit(flag):
    return "limit hit" if flag else "within limit"


#: The figures of the table, by their name under ``profile.`` in the figure table
#: (:data:`~cas_freq.core.figures.FIGURES`, which gives their labels and units), in order.
_ROW_FIGURES = (
    "tracking_error_max_deg", "tracking_error_max_time_s", "tracking_error_rms_deg",
    "overshoot_pct", "settling_time_s", "settling_time_5pct_s", "arrival_time_s",
    "arrival_time_5pct_s", "final_error_deg", "max_current_a", "max_voltage_v",
)

#: A figure shown as a sub-row of the one before it, with this label instead of the table's.
_SUB_ROWS = {"tracking_error_max_time_s": "  at (from the move's start)"}

#: Rows of the figures table: (label, shown unit, figure name).
FIGURE_ROWS = tuple((_SUB_ROWS.get(name, FIGURES[f"profile.{name}"].label),
                     FIGURES[f"profile.{name}"].shown_unit, name) for name in _ROW_FIGURES)


def figure_rows(run):
    """(label, unit, with feed-forward, without) of every figure of a :class:`ProfileRun`,
    the values as text."""
    rows = []
    output = run.output_unit
    for label, unit, what in FIGURE_ROWS:
        cells = []
        angle = FIGURES[f"profile.{what}"].unit == "deg"  # an output quantity: mm if linear
        for figures in (run.profile, run.without_feedforward):
            value = getattr(figures, what)
            text = number(output.value(value) if angle else
                          value * FIGURES[f"profile.{what}"].scale, 4)
            if what == "max_current_a":
                text += f" ({_limit(figures.current_limited)})"
            elif what == "max_voltage_v":
                text += f" ({_limit(figures.voltage_limited)})"
            cells.append(text)
        rows.append((label, output.shown if angle else unit, *cells))
    return rows


def _feedforward_text(run):
    if not (run.ff_v or run.ff_a):
        return ("the config has no feed-forward (ff_v = ff_a = 0): both columns are the same "
                "loop")
    ff_v, ff_a = (" " + unit if unit != "dimensionless" else "" for unit in run.ff_units)
    return (f"feed-forward of the config: ff_v = {run.ff_v:g}{ff_v}, ff_a = {run.ff_a:g}{ff_a} "
            "(motor side); 'without': ff_v = ff_a = 0")


def move_text(run):
    """The move at the output and at the motor in the drive's units (profile position mode)."""
    motor = move_dict(run.move, run.ratio)["motor"]
    return (f"profile move of {profile_condition_text(run.move, run.output_unit)} at the "
            f"{run.output}; at the motor "
            f"(x {run.ratio:g}): {number(motor['distance_rev'], 4)} rev, profile velocity "
            f"{number(motor['velocity_rpm'], 4)} rpm, acceleration "
            f"{number(motor['acceleration_rpm_s'], 4)} rpm/s, deceleration "
            f"{number(motor['deceleration_rpm_s'], 4)} rpm/s")


def profile_table(run):
    """Multi-line summary of a :class:`~cas_freq.studies.profile_run.ProfileRun`."""
    r = run.result
    head = f"{run.config} / {run.variant}"
    if run.overrides:
        head += " with " + ", ".join(run.overrides)
    lines = [head]
    if run.linear_stability != "stable":
        lines.append(f"  WARNING: the linear closed loop is {run.linear_stability.upper()} "
                     "(Padé poles); these figures describe a loop only the limits keep bounded")
    settled = "settled" if r.settled else "NOT settled"
    if run.result_without_feedforward.settled != r.settled:
        settled += (", without feed-forward "
                    + ("settled" if run.result_without_feedforward.settled else "NOT settled"))
    lines += [
        f"  {move_text(run)}",
        f"  {_trapezoid_text(run.move, run.output_unit)}",
        f"  nonlinear run; dt {r.dt_s * 1e6:g} us, {r.t_end_s * 1e3:g} ms ({settled}"
        f"{', horizon extended' if r.extended else ''}); {_feedforward_text(run)}",
    ]
    rows = figure_rows(run)
    width = max(len(f"{label} [{unit}]") for label, unit, *_ in rows)
    on_width = max(len("feed-forward"), *(len(row[2]) for row in rows))
    lines.append(f"    {'':<{width}}  {'feed-forward':>{on_width}}  without")
    for label, unit, on, off in rows:
        lines.append(f"    {label + ' [' + unit + ']':<{width}}  {on:>{on_width}}  {off}")
    return "\n".join(lines)


def _table_rows(runs):
    """Rows of the report's table: one per figure, a pair of columns (with, without the
    feed-forward) per variant."""
    rows = []
    per_run = [figure_rows(run) for run in runs]
    for k, (label, *_) in enumerate(FIGURE_ROWS):
        cells = [cell for rows_of_run in per_run for cell in rows_of_run[k][2:]]
        rows.append((label.strip(), per_run[0][k][1], *cells))  # mm at a linear output
    return tuple(rows)


class ProfileSection:
    """The report's "Profile moves" section: its blocks, and its data for results.json.

    Built by :func:`profile_section`; empty (no blocks, no results) when the config has no
    ``profile.*`` requirement.
    """

    def __init__(self, blocks=(), results=None):
        self.blocks = tuple(blocks)
        self.results = {} if results is None else {"profile_moves": results}


def profile_section(datas, png=False):
    """Simulate the moves of the config's ``profile.*`` requirements on every stable variant.

    A generator: yields (path, content) of the section's figures (one per variant and move:
    command vs output angle and tracking error, with and without feed-forward) and returns a
    :class:`ProfileSection`.

    Parameters
    ----------
    datas : list of cas_freq.report.data.VariantData
    png : bool
        Also write each figure as PNG.
    """
    requirements = datas[0].loaded.params.requirements
    conditions = list(dict.fromkeys(r.profile for r in requirements if r.kind == "profile"))
    if not conditions:
        return ProfileSection()
    stable = [d for d in datas if d.analysis.stable]
    skipped = [d.loaded.variant for d in datas if not d.analysis.stable]
    blocks = [Heading(2, "Profile moves"), Paragraph(
        "Trapezoidal moves as the drive's profile position mode makes them (the moves of the "
        "config's profile.* requirements), simulated nonlinearly with the config's "
        "feed-forward (i_ff = ff_v·dθ_cmd/dt + ff_a·d²θ_cmd/dt²) and without it (ff_v = ff_a "
        "= 0); figures defined in docs/model.md, \"Profile moves\"."
        + (f" Not simulated (closed loop not stable): {', '.join(skipped)}." if skipped
           else ""))]

    unit = output_unit(datas[0].loaded.params)
    results = []
    for number_, condition in enumerate(conditions, start=1):
        move = condition_profile(condition)
        verdicts = {id(d.loaded): d.analysis.stability.verdict for d in stable}
        runs = profile_runs([d.loaded for d in stable], move, verdicts) if stable else []
        blocks.append(Heading(3, f"Move {number_}: {profile_condition_text(move, unit)}"))
        if not runs:
            continue
        blocks.append(Paragraph(f"{move_text(runs[0])}. {_trapezoid_text(move, unit)}."))
        header = ("figure", "unit", *(f"{run.variant}, {which}" for run in runs
                                      for which in ("with ff", "without ff")))
        blocks.append(Table(header, _table_rows(runs),
                            f"profile move {number_}: with and without the feed-forward"))
        paths = []
        for run in runs:
            stem = f"figures/{sanitise_name(run.variant, fallback='variant')}/profile_{number_}"
            paths.append(f"{stem}.svg")
            svg, png_data = _draw(run, png)
            yield f"{stem}.svg", svg
            if png:
                yield f"{stem}.png", png_data
            blocks.append(Figure(
                f"{stem}.svg", f"Profile move {number_}: command and {run.output} {unit.quantity}, "
                f"tracking error, with and without feed-forward — {run.config} / {run.variant}",
                svg))
        results.append({"condition": profile_condition_text(move, unit),
                        "variants": [{**profile_run_dict(run), "figure": path}
                                     for run, path in zip(runs, paths, strict=True)]})
    return ProfileSection(blocks, results)


def _draw(run, png):
    """(SVG text, PNG bytes or None) of a run's figure (imports matplotlib)."""
    from cas_freq.plots import report as plots
    from cas_freq.plots.profile import profile_figure

    fig = profile_figure(run)
    return plots.svg_text(fig), plots.png_bytes(fig) if png else None
