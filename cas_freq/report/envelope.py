"""The report's "Load envelope" section (shown when the config has a ``load_envelope:``).

For each chosen variant: where the closed loop is stable in hinge stiffness, each
requirement's verdict at the variant's own stiffness and the stiffness at which it is lost on
either side (:mod:`cas_freq.studies.envelope`), a table of the figures on the grid, and a
figure (:mod:`cas_freq.plots.envelope`).
"""

import math

import numpy as np

from cas_freq.core.figures import FIGURES, loop_label
from cas_freq.core.numbers import number
from cas_freq.core.threads import result_of
from cas_freq.report.document import Bullets, Figure, Heading, Paragraph, Table
from cas_freq.report.outdir import sanitise_name

#: Most rows of an envelope table (the figure shows every grid point).
TABLE_ROWS = 17

#: The figures of the envelope table's columns (labels, units and factors: :data:`FIGURES`).
_COLUMNS = ("closed_loop.bandwidth_rad_s", "closed_loop.peak_db", "position_loop.phase_margin_deg",
            "position_loop.gain_margin_db", "current_loop.phase_margin_deg",
            "step.overshoot_pct", "step.settling_time_s")


def _heading(key):
    """A column's heading: the figure's label and unit, after its loop's name."""
    figure = FIGURES[key]
    return (f"{loop_label(figure.loop)}: " if figure.loop else "") + figure.heading


class EnvelopeSection:
    """The section's blocks and its results.json entry (empty without ``load_envelope:``)."""

    def __init__(self, blocks=(), results=None):
        self.blocks = tuple(blocks)
        self.results = {} if results is None else {"load_envelope": results}


def _bound_text(requirement):
    parts = []
    if requirement.min is not None:
        parts.append(f"≥ {requirement.min:g}")
    if requirement.max is not None:
        parts.append(f"≤ {requirement.max:g}")
    return " and ".join(parts)


def _loss_text(loss, side, envelope):
    if loss is None:
        end = envelope.hinge_stiffness[0 if side == "below" else -1]
        return f"holds to the grid's end ({number(float(end), 4)} N·m/rad)"
    why = "the closed loop goes unstable" if loss.how == "unstable" else "the bound is crossed"
    return (f"lost {side} K_h ≈ {number(loss.at, 4)} N·m/rad ({why}; between "
            f"{number(loss.between[0], 4)} and {number(loss.between[1], 4)})")


def requirement_items(envelope):
    """One sentence per requirement: its verdict at the nominal stiffness, and its losses."""
    items = []
    for r in envelope.requirements:
        head = f"{r.id} ({r.severity}, {r.metric} {_bound_text(r)})"
        if not r.evaluated:
            items.append(f"{head}: not evaluated ({r.reason}).")
        elif not r.at_nominal:
            held = envelope.hinge_stiffness[r.passed]
            where = ("holds nowhere on the grid" if not held.size else
                     f"holds on grid points from {number(float(held.min()), 4)} to "
                     f"{number(float(held.max()), 4)} N·m/rad (not necessarily all between)")
            items.append(f"{head}: FAILS at the variant's own K_h "
                         f"({number(envelope.nominal_n_m_rad, 4)} N·m/rad); {where}.")
        else:
            items.append(f"{head}: holds at the variant's own K_h; aiding side: "
                         f"{_loss_text(r.lost_below, 'below', envelope)}; opposing side: "
                         f"{_loss_text(r.lost_above, 'above', envelope)}.")
    return items


def table_rows(envelope):
    """Rows of the envelope table: at most :data:`TABLE_ROWS` grid points, evenly chosen, and
    always the variant's own stiffness."""
    grid = envelope.hinge_stiffness
    picks = np.unique(np.round(np.linspace(0, grid.size - 1, min(TABLE_ROWS, grid.size))))
    nominal = int(np.flatnonzero(grid == envelope.nominal_n_m_rad)[0])
    picks = sorted({*picks.astype(int).tolist(), nominal})
    from cas_freq.studies.envelope import shown_figure

    columns = [key for key in _COLUMNS if key in envelope.figures]
    shown = {key: shown_figure(envelope, key) for key in columns}
    settling = envelope.figures.get("step.settling_time_s", np.full(grid.size, np.nan))
    rows = []
    for j in picks:
        failing = [r.id for r in envelope.requirements if r.evaluated and not r.passed[j]]
        cells = []
        stable = str(envelope.stability[j]) == "stable"
        settled = math.isfinite(float(settling[j]))
        for key in columns:
            if key == "step.overshoot_pct" and stable and not settled:
                cells.append("not settled")  # a run the limits let diverge, or still moving
                continue
            # closed-loop and step figures of a loop that is not stable are not shown (verify
            # does not trust them); the open-loop margins say how far it is from stability
            value = float(shown[key][j])
            value = value if math.isfinite(value) else None
            cells.append(number(FIGURES[key].shown(value), 4))
        label = number(float(grid[j]), 4) + (" (own)" if j == nominal else "")
        rows.append((label, str(envelope.stability[j]), *cells, ", ".join(failing) or "—"))
    header = (FIGURES["drivetrain.hinge_stiffness_n_m_rad"].heading, "closed loop",
              *map(_heading, columns), "requirements failed")
    return header, tuple(rows)


def envelope_variants(params):
    """Names of the variants whose load envelope is asked for (() without a
    ``load_envelope:``; None for every variant of the report)."""
    spec = params.load_envelope
    if spec is None:
        return ()
    return spec.variants or None


def compute_envelope(loaded, spec, drivetrain=None):
    """The load envelope of one variant of the report.

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant
    spec : cas_freq.config.schema.LoadEnvelopeSpec
        The report's ``load_envelope:`` (its first variant's, used for every variant, as
        the section's text describes it): hinge-stiffness grid and step.
    drivetrain : cas_freq.analysis.drivetrain.DrivetrainFigures, optional
        The variant's drivetrain figures from its analysis (a loaded variant's stable range,
        then not computed again; computed the same way otherwise).
    """
    from cas_freq.studies.envelope import load_envelope

    return load_envelope(loaded, spec.hinge_stiffness, spec.step, stable_range=None
                         if drivetrain is None else drivetrain.stable_hinge_stiffness_n_m_rad)


def envelope_job(loaded, spec, drivetrain, config_name, png):
    """(envelope, (SVG, PNG or None)): :func:`compute_envelope` and :func:`draw_envelope`, as
    one task for a worker process."""
    envelope = compute_envelope(loaded, spec, drivetrain)
    return envelope, draw_envelope(envelope, config_name, png)


def envelope_section(datas, png=False, computed=None):
    """Lay out the load envelope of each chosen variant (computed and drawn here unless
    ``computed`` holds it).

    A generator: yields (path, content) of each variant's figure and returns an
    :class:`EnvelopeSection`.

    Parameters
    ----------
    datas : list of cas_freq.report.data.VariantData
    png : bool
        Also write each figure as PNG.
    computed : dict, optional
        Variant name -> an object whose ``result()`` is its :func:`envelope_job` (a future
        of a worker process that computed and drew it while the report was being computed).
    """
    from cas_freq.studies.envelope import envelope_dict

    params = datas[0].loaded.params
    spec = params.load_envelope
    if spec is None:
        return EnvelopeSection()
    computed = computed or {}
    wanted = envelope_variants(params) or tuple(d.loaded.variant for d in datas)
    chosen = [d for d in datas if d.loaded.variant in wanted]
    grid = spec.hinge_stiffness
    blocks = [Heading(2, "Load envelope"), Paragraph(
        f"Every figure against the load spring K_h (load.hinge_stiffness) at the "
        f"{params.output_label} (the load moment −K_h·δ; > 0 opposes the motion, < 0 aids it, "
        f"a statically unstable load), from "
        f"{number(min(grid), 4)} to {number(max(grid), 4)} N·m/rad ({len(grid)} points, the "
        "config's load_envelope: section), each variant's other load and drivetrain values "
        "kept. Requirements are checked at every point as `cas-freq verify` checks them (a "
        "figure of a loop that is not stable never passes); where one is lost is found by "
        "bisection between grid points, of the requirement's verdict or, where the loop goes "
        "unstable first, of the Padé model's stability verdict. Figures need not vary "
        "smoothly: the bandwidth drops at once where a low-frequency dip of T (the load "
        "spring taking the loop's stiffness until the integrator catches up) crosses −3 dB.")]
    missing = [name for name in wanted if name not in {d.loaded.variant for d in datas}]
    if missing:
        blocks.append(Paragraph(f"Not in this report (not selected): {', '.join(missing)}."))
    results = []
    for data in chosen:
        job = computed.get(data.loaded.variant)
        envelope, (svg, png_data) = (
            envelope_job(data.loaded, spec, data.analysis.drivetrain, params.name, png)
            if job is None else result_of(job))
        low, high = envelope.stable_range
        span = ("nowhere on the scan" if low is None and high is None else
                f"for K_h from {'−∞' if low is None else number(low, 4)} to "
                f"{'+∞' if high is None else number(high, 4)} N·m/rad")
        step = ("" if envelope.step_deg is None else
                f" Step figures: nonlinear {envelope.step_deg:g}° {params.output_label} steps.")
        blocks += [
            Heading(3, f"Load envelope ({data.loaded.variant})"),
            Paragraph(f"Own load spring K_h {number(envelope.nominal_n_m_rad, 4)} N·m/rad. "
                      f"The closed loop is stable {span}.{step}"),
            Bullets(tuple(requirement_items(envelope))),
        ]
        header, rows = table_rows(envelope)
        blocks.append(Table(header, rows, f"load envelope of {data.loaded.variant} (every "
                                          "grid point is in results.json and the figure)"))
        stem = f"figures/{sanitise_name(data.loaded.variant, fallback='variant')}/load_envelope"
        yield f"{stem}.svg", svg
        if png:
            yield f"{stem}.png", png_data
        blocks.append(Figure(f"{stem}.svg", f"Load envelope: bandwidth, margins and step "
                             f"overshoot against the load spring K_h — {params.name} / "
                             f"{data.loaded.variant}", svg))
        results.append(envelope_dict(envelope))
    return EnvelopeSection(blocks, results)


def draw_envelope(envelope, config_name, png):
    """(SVG text, PNG bytes or None) of the envelope's figure (imports matplotlib)."""
    from cas_freq.plots.common import png_bytes, svg_text
    from cas_freq.plots.envelope import envelope_figure

    fig = envelope_figure(envelope, config_name)
    return svg_text(fig), png_bytes(fig) if png else None
