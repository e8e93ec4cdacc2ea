"""Readable plain-text tables of analysis results (no matplotlib).

Figures are written with :func:`cas_freq.core.numbers.number`: 4 significant digits, 0 when
numerically zero (a fitted delay of 3e-48 ms is 0 ms), "—" when absent.
"""

import math

from cas_freq.config.wording import GENERIC, OutputWords
from cas_freq.core.figures import FIGURES
from cas_freq.core.numbers import number
from cas_freq.core.output import ANGLE, output_unit
from cas_freq.model.sampled import TIME_VARYING, time_varying_views


def _fmt(value, unit="", digits=4):
    return number(value, digits, unit)


def _figure_line(key, value, tail="", indent=4):
    """``    label               value unit`` of a figure of the figure table
    (:data:`~cas_freq.core.figures.FIGURES`: label, shown unit and factor), then ``tail``."""
    return f"{' ' * indent}{FIGURES[key].label:<{_WIDTH}} {shown_text(key, value)}{tail}"


def shown_text(key, value):
    """A figure's value (its JSON unit) as text in the unit the tables show it in."""
    figure = FIGURES[key]
    return _fmt(figure.shown(value), figure.shown_unit)


#: Width of the labels in the text: the longest of a loop's (and of the drivetrain's).
_WIDTH = max(len(FIGURES[key].label) for key in (
    "current_loop.crossover_rad_s", "drivetrain.reflected_stiffness_n_m_rad"))


def _crossover_lines(key, margins):
    """The headline gain crossover (smallest |phase margin|) with its own phase and delay margin;
    with several crossovers, each other one with its margins, then the smallest delay margin
    with the crossover it belongs to (it need not be the headline one). ``key``: the loop's
    group of :data:`~cas_freq.core.figures.FIGURES`."""
    crossovers = margins.gain_crossovers
    headline = [c for c in crossovers if c.frequency_rad_s == margins.crossover_rad_s]
    own = headline[0].delay_margin_s if headline else margins.delay_margin_s
    several = len(crossovers) > 1
    pm, dm = f"{key}.phase_margin_deg", f"{key}.delay_margin_s"
    lines = [
        _figure_line(f"{key}.crossover_rad_s", margins.crossover_rad_s,
                     f" (smallest |{FIGURES[pm].label}| of {len(crossovers)})" if several else ""),
        _figure_line(pm, margins.phase_margin_deg),
        _figure_line(dm, own, " (at this crossover)" if several else ""),
    ]
    if several:
        label = f"    {'other crossovers':<{_WIDTH}} "
        for c in crossovers:
            if c.frequency_rad_s == margins.crossover_rad_s:
                continue
            lines.append(f"{label}{_fmt(c.frequency_rad_s, 'rad/s')}: {FIGURES[pm].label} "
                         f"{shown_text(pm, c.phase_margin_deg)}, {FIGURES[dm].label} "
                         f"{shown_text(dm, c.delay_margin_s)}")
            label = " " * len(label)
        at = margins.delay_margin_crossover_rad_s
        lines.append(_figure_line(dm, margins.delay_margin_s, " (the smallest, at "
                                  f"{shown_text(f'{key}.crossover_rad_s', at)})"))
    return lines


def _loop_lines(title, key, margins):
    def of(name):
        return shown_text(f"{key}.{name}", getattr(margins, name))

    lines = [
        f"  {title}",
        *_crossover_lines(key, margins),
        _figure_line(f"{key}.gain_margin_db", margins.gain_margin_db,
                     f" at {of('phase_crossover_rad_s')}"),
    ]
    if margins.gain_margin_low_db is not None:
        lines.append(_figure_line(f"{key}.gain_margin_low_db", margins.gain_margin_low_db,
                                  f" at {of('phase_crossover_low_rad_s')}"))
    lines += [
        _figure_line(f"{key}.sensitivity_peak_db", margins.sensitivity_peak_db,
                     f" at {of('sensitivity_peak_rad_s')}"),
        _figure_line(f"{key}.disk_margin_alpha", margins.disk_margin_alpha,
                     f" (±{of('disk_margin_gain_db')}, ±{of('disk_margin_phase_deg')})"),
        f"    {'crossings':<{_WIDTH}} {len(margins.gain_crossovers)} gain, "
        f"{len(margins.phase_crossovers)} phase in range",
    ]
    return lines


def _at_a_time_lines(key, margins):
    """The headline margins of a loop broken with every other loop closed."""
    more = len(margins.gain_crossovers) - 1
    key = f"{key}.loop_at_a_time"
    pm = FIGURES[f"{key}.phase_margin_deg"].label
    others = f" (smallest |{pm}| of {more + 1})" if more > 0 else ""
    at = shown_text(f"{key}.phase_crossover_rad_s", margins.phase_crossover_rad_s)
    return [
        "    every other loop closed (loop at a time):",
        _figure_line(f"{key}.crossover_rad_s", margins.crossover_rad_s, others, 6),
        _figure_line(f"{key}.phase_margin_deg", margins.phase_margin_deg, "", 6),
        _figure_line(f"{key}.delay_margin_s", margins.delay_margin_s, "", 6),
        _figure_line(f"{key}.gain_margin_db", margins.gain_margin_db, f" at {at}", 6),
    ]


def _sampling_lines(analysis, described):
    """The sampled loops' rates and headline figures beside the continuous model's."""
    sampling, continuous = analysis.sampling, analysis.continuous
    rates = ", ".join(f"{name.replace('_loop', '')} {_fmt(rate / 1e3, 'kHz')}"
                      for name, rate in sampling["rates_hz"].items())
    rows = []
    for name, rate in sampling["rates_hz"].items():
        margins, symbol = getattr(analysis, name), described[name].symbol
        rows += [(f"{symbol} {FIGURES[f'{name}.{figure}'].heading}",
                  FIGURES[f"{name}.{figure}"].shown(getattr(margins, figure)),
                  FIGURES[f"{name}.{figure}"].shown(continuous[name][figure]))
                 for figure in ("phase_margin_deg", "crossover_rad_s", "gain_margin_db",
                                "delay_margin_s")]
        samples = None if margins.delay_margin_s is None else margins.delay_margin_s * rate
        rows.append((f"{symbol} {FIGURES[f'{name}.delay_margin_s'].label} [samples]", samples,
                     None))
    closed = analysis.closed_loop
    rows += [(f"T {FIGURES[f'closed_loop.{figure}'].heading}",
              closed and FIGURES[f"closed_loop.{figure}"].shown(getattr(closed, figure)),
              FIGURES[f"closed_loop.{figure}"].shown(continuous["closed_loop"][figure]))
             for figure in ("bandwidth_rad_s", "peak_db")]
    width = max(len(label) for label, *_ in rows)
    lines = [f"  sampled controllers: {rates} ({sampling['method']}, zero-order hold)",
             f"    {'figure':<{width}}    sampled     continuous"]
    lines += [f"    {label:<{width}} {_fmt(a):>10} {_fmt(b):>14}" for label, a, b in rows]
    # (the sampled column's verdict is of the discrete-time poles, not of the Padé model)
    lines.append(f"    {'stability':<{width}} {analysis.stability.verdict:>10} "
                 f"{continuous['stability']:>14}")
    return lines


def pade_columns(analysis):
    """The columns of the Padé-vs-exact table: (heading, attribute of
    :class:`cas_freq.analysis.analyze.PadeComparison`, figure key), after the delay model's;
    the loops named by their structure's symbols."""
    described = analysis_loops_named(analysis)
    columns = [("current_loop", "phase_margin_deg"), ("position_loop", "phase_margin_deg"),
               ("position_loop", "crossover_rad_s"), ("position_loop", "gain_margin_db"),
               ("position_loop", "gain_margin_low_db"), ("closed_loop", "bandwidth_rad_s"),
               ("closed_loop", "peak_db")]
    return [(f"{described[loop].symbol if loop in described else 'T'} "
             f"{FIGURES[f'{loop}.{name}'].short_heading}",
             name if loop == "closed_loop" else f"{loop.removesuffix('_loop')}_{name}",
             f"{loop}.{name}") for loop, name in columns]


def analysis_loops_named(analysis):
    """The :class:`~cas_freq.report.data.CurveLoop` of every loop of the analysis's variant by
    name (the loop structure's symbols and break points)."""
    from cas_freq.report.data import described_loops

    return {loop.name: loop for loop in described_loops(analysis.loaded.params)}


def analysis_table(analysis):
    """Multi-line summary of one :class:`cas_freq.analysis.Analysis`."""
    low, high = analysis.frequency_range_rad_s
    head = f"{analysis.config} / {analysis.variant}"
    if analysis.overrides:
        head += " with " + ", ".join(analysis.overrides)
    poles = ("discrete-time poles" if analysis.sampling
             else f"Padé {analysis.stability.pade_order} poles")
    lines = [
        head,
        f"  delays {analysis.delay_model}; range {low:g}..{high:g} rad/s; closed loop "
        f"{analysis.stability.verdict.upper()} ({poles})",
    ]
    described = analysis_loops_named(analysis)
    if analysis.sampling:
        lines += _sampling_lines(analysis, described)
    loops = list(described.values())
    for k, loop in enumerate(loops):
        margins = getattr(analysis, loop.name)
        lines += _loop_lines(f"{loop.words} {loop.symbol} (broken at {loop.breaks_at})",
                             loop.name, margins)
        if k < len(loops) - 1 and margins.loop_at_a_time is not None:
            if analysis.sampling and loop.name in time_varying_views(
                    analysis.sampling["rates_hz"]):
                lines.append(f"    every other loop closed: not defined ({TIME_VARYING})")
                continue
            lines += _at_a_time_lines(loop.name, margins.loop_at_a_time)
    words = OutputWords.of(analysis.loaded.params)
    closed = analysis.closed_loop
    lines.append(f"  closed loop {words.closed_loop}")
    if closed is None:
        lines.append("    not reported: the closed loop is not stable")
    else:
        lines += [
            _figure_line("closed_loop.bandwidth_rad_s", closed.bandwidth_rad_s),
            _figure_line("closed_loop.peak_db", closed.peak_db,
                         f" at {shown_text('closed_loop.peak_rad_s', closed.peak_rad_s)}")
            if closed.peak_db is not None else
            f"    {FIGURES['closed_loop.peak_db'].label:<{_WIDTH}} none (|T| has no interior "
            "maximum)",
            _figure_line("closed_loop.phase_90_rad_s", closed.phase_90_rad_s),
        ]
    if analysis.drivetrain is not None:
        lines += _drivetrain_lines(analysis.drivetrain, analysis.loaded)
    from cas_freq.analysis.disturbance import text_lines

    lines += text_lines(getattr(analysis, "stiffness", None), getattr(analysis, "effort", None),
                        getattr(analysis, "noise", None), _fmt, words)
    if getattr(analysis, "limit_cycles", None) is not None:
        from cas_freq.analysis.limit_cycles import text_lines

        lines += text_lines(analysis.limit_cycles, output_unit(analysis.loaded.params))
    if analysis.envelope is not None:
        from cas_freq.analysis.rate_envelope import envelope_lines

        lines += [f"  {line}" for line in envelope_lines(
            analysis.envelope, output_unit(analysis.loaded.params),
            analysis.loaded.params.output_label)]
    if analysis.pade_vs_exact:
        columns = pade_columns(analysis)
        lines.append("  Padé vs exact")
        lines.append(f"    {'delay model':<16}" + "".join(
            f" {heading:>{len(heading)}}" for heading, *_ in columns) + "  max|dT|")
        for row in analysis.pade_vs_exact:
            lines.append(f"    {row.delay_model:<16}" + "".join(
                f" {_fmt(FIGURES[key].shown(getattr(row, attribute))):>{len(heading)}}"
                for heading, attribute, key in columns)
                + f"  {row.closed_loop_max_error:.2e}")
    lines += [f"  note: {note}" for note in analysis.notes]
    return "\n".join(lines)


def _limit_text(t, active):
    from cas_freq.studies.run import limit_activity

    activity = limit_activity(t, active)
    if activity["first_s"] is None:
        return "within limit"
    return (f"limit active {activity['active_s'] * 1e3:.3g} ms between "
            f"{activity['first_s'] * 1e3:.3g} and {activity['last_s'] * 1e3:.3g} ms")


def _sampled_controllers(result):
    """``; controllers sampled (...)`` for a run with sampled controllers, else nothing."""
    from cas_freq.studies.run import controllers_text

    text = controllers_text(result)
    return "" if text == "continuous" else f"; controllers {text}"


def step_table(run):
    """Multi-line summary of a :class:`cas_freq.studies.run.StepRun`."""
    step, fit, result = run.step, run.fit, run.result
    head = f"{run.config} / {run.variant}"
    if run.overrides:
        head += " with " + ", ".join(run.overrides)
    settled = "settled" if result.settled else "NOT settled"
    from cas_freq.studies.run import diverged_at

    warning = []
    diverged = diverged_at(run)
    if diverged is not None:
        warning = [f"  WARNING: the run DIVERGED: beyond 1e6 times the step (or overflowed) at "
                   f"t = {_fmt(diverged * 1e3, 'ms')}; no step figure or fit exists"]
    if run.linear_stability != "stable":
        warning.insert(0, f"  WARNING: the linear closed loop is "
                       f"{run.linear_stability.upper()} (Padé poles)" + (
                           "" if diverged is not None else
                           "; these figures describe a loop only the limits keep bounded"))
    extended = ", horizon extended" if result.extended else ""
    return "\n".join([
        head,
        *warning,
        f"  nonlinear step of {run.output_unit.show(step.amplitude_deg)} at the {run.output}; "
        f"dt {result.dt_s * 1e6:g} us, {result.t_end_s * 1e3:g} ms ({settled}{extended})"
        + _sampled_controllers(result),
        _figure_line("step.rise_time_s", step.rise_time_s),
        _figure_line("step.overshoot_pct", step.overshoot_pct),
        _figure_line("step.settling_time_s", step.settling_time_s),
        _figure_line("step.settling_time_5pct_s", step.settling_time_5pct_s),
        _figure_line("step.peak_time_s", step.peak_time_s),
        _figure_line("step.max_current_a", step.max_current_a,
                     f" ({_limit_text(result.t, result.current_limited)})"),
        _figure_line("step.max_voltage_v", step.max_voltage_v,
                     f" ({_limit_text(result.t, result.voltage_limited)})"),
        "  second-order-plus-delay fit (docs/model.md §7)",
        *(_figure_line(f"fit.{name}", getattr(fit, name))
          for name in ("wn_rad_s", "zeta", "td_s")),
        f"    {FIGURES['fit.rms_residual'].label:<{_WIDTH}} "
        f"{_fmt(100 * fit.rms_residual / math.radians(abs(step.amplitude_deg)))} % of the step",
        _figure_line("fit.bandwidth_closed_form_rad_s", fit.bandwidth_closed_form_rad_s),
    ])


def _amplitude(entry):
    """An amplitude of a sine-dwell dict as text: ``amplitude_deg``, or ``amplitude_mm`` at a
    linear output (:func:`cas_freq.core.output.output_json`)."""
    if "amplitude_mm" in entry:
        return _fmt(entry["amplitude_mm"], "mm")
    return _fmt(entry["amplitude_deg"], "deg")


def _sinedwell_not_computed_table(head, data):
    """:func:`sinedwell_table` of a variant whose sine-dwell was not computed: why, and the
    nonlinear steps with their fits (or when they diverged)."""
    reason = data["not_computed"]["sinedwell"]
    lines = [head]
    if data.get("linear_closed_loop", "stable") != "stable":
        lines.append(f"  the linear closed loop is {data['linear_closed_loop'].upper()} "
                     "(Padé poles): no sine-dwell bandwidth exists")
    lines += [f"  sine-dwell not computed: {reason}",
              "  nonlinear steps (second-order fit, docs/model.md §7)",
              f"    {'amplitude':>10}{FIGURES['step.overshoot_pct'].heading:>15}"
              f"{'step fit [rad/s]':>18}"]
    for entry in data["amplitudes"]:
        diverged = entry.get("diverged_at_s")
        if diverged is not None:
            cells = f"{'diverged at t = ' + f'{diverged * 1e3:.4g} ms':>33}"
        else:
            cells = (f"{_fmt(entry['step'].get('overshoot_pct')):>15}"
                     f"{_fmt(entry['fit'].get('bandwidth_closed_form_rad_s')):>18}")
        lines.append(f"    {_amplitude(entry):>10}{cells}")
    return "\n".join(lines)


def sinedwell_table(data, words=GENERIC):
    """Multi-line summary of a sine-dwell run, from its dict (``sinedwell_run_dict``); ``words``
    name the output (:class:`~cas_freq.config.wording.OutputWords`)."""
    head = f"{data['config']} / {data['variant']}"
    if data["overrides"]:
        head += " with " + ", ".join(data["overrides"])
    sim = data["simulation"]
    amplitudes = data["amplitudes"]
    warning = []
    if data.get("linear_closed_loop", "stable") != "stable":
        warning = [f"  WARNING: the linear closed loop is {data['linear_closed_loop'].upper()} "
                   "(Padé poles): no linear response or bandwidth exists, and the nonlinear "
                   "figures describe a loop only the limits keep bounded"]
    if data.get("not_computed"):
        return _sinedwell_not_computed_table(head, data)
    lines = [
        head,
        *warning,
        f"  nonlinear sine-dwell, feed-forward {'on' if data['feedforward'] else 'off'}, "
        f"{sim['controllers']} controllers, dt {sim['dt_s'] * 1e6:g} us; "
        f"first harmonic of the {words.value} / of its command",
        "  " + f"{'[rad/s]':>10}" + "".join(
            f"{_amplitude(a):>18}" for a in amplitudes
        ) + f"{'linear':>18}",
    ]
    missing = False
    for j, omega in enumerate(data["frequencies_rad_s"]):
        cells = []
        for a in [*amplitudes, data["linear"]]:
            mark = "*" if a.get("current_limited", [False] * (j + 1))[j] or a.get(
                "voltage_limited", [False] * (j + 1))[j] else " "
            magnitude, phase = a["magnitude_db"][j], a["phase_deg"][j]
            if magnitude is None or phase is None:  # a run that diverged (or no response)
                missing = True
                cells.append(f"{'—':>17}{mark}")
            else:
                cells.append(f"{magnitude:7.2f} dB{phase:6.0f}°{mark}")
        lines.append("  " + f"{omega:10.1f}" + "".join(cells))
    lines.append("  (* a current or voltage limit acts during the measured periods)")
    if missing:
        lines.append("  (— no first harmonic: the run diverged until its state overflowed, or "
                     "no linear response exists)")
    onset_mm = data.get("limit_onset_amplitude_mm")
    onset = data.get("limit_onset_amplitude_deg", onset_mm)
    unit = "deg" if "limit_onset_amplitude_deg" in data else "mm"
    lines.append(
        "  limits act from " + (f"{onset:g} {unit}" if onset is not None else
                                "no amplitude given")
    )
    bench = data.get("report_bench")
    wide = 7 if data.get("bandwidth_requirement_rad_s") is not None else 0
    lines += [
        "  bandwidth three ways [rad/s]  (-3.01 dB; step fit = closed form of the "
        "second-order-plus-delay fit, docs/model.md §7)",
        f"    {'amplitude':>10}{'linear T':>{11 + wide}}{'sine-dwell':>{12 + wide}}"
        f"{'step fit':>{10 + wide}}",
    ]
    required = data.get("bandwidth_requirement_rad_s")

    def cell(row, name, width):
        text = _fmt(row[name])
        bound = row.get("sinedwell_bound") if name == "sinedwell_rad_s" else None
        if row[name] is None and bound is not None:
            text = f"{bound['relation']} {bound['edge_rad_s']:.4g}"
        if required is not None:
            meets = row["meets_requirement"][name]
            text += " ok" if meets else " LOW" if meets is False else " undecided"
        return f"{text:>{width}}"

    for row in data["bandwidth_three_ways"]:
        wide = 7 if required is not None else 0
        lines.append(
            f"    {_amplitude(row):>10}{cell(row, 'linear_rad_s', 11 + wide)}"
            f"{cell(row, 'sinedwell_rad_s', 12 + wide)}{cell(row, 'step_fit_rad_s', 10 + wide)}"
        )
    if any(row.get("sinedwell_bound") for row in data["bandwidth_three_ways"]):
        lines.append("    (> w / < w: the -3.01 dB point lies above the grid's top / below its "
                     "bottom w)")
    if required is not None:
        lines.append(f"    (ok / LOW: against the config's required bandwidth >= {required:g} "
                     "rad/s; undecided: no value, or a bound that cannot tell: widen "
                     "--frequencies)")
    if bench is not None:
        lines.append(f"    {_reference_line(bench)}")
    return "\n".join(lines)


def _reference_line(bench):
    """The config's reference fit: ``reference, 10 deg step fit: 566 (wn .., zeta ..; SOURCE)``."""
    step = "" if bench["step_deg"] is None else f", {bench['step_deg']:g} deg step"
    notes = [f"{name} {_fmt(bench[key], unit)}" for name, key, unit in
             (("wn", "wn_rad_s", "rad/s"), ("zeta", "zeta", "")) if bench[key] is not None]
    notes = ", ".join(notes) + ("; " if notes and bench["source"] else "") + (bench["source"] or "")
    return (f"reference{step} fit: {_fmt(bench['bandwidth_rad_s'])}"
            + (f" ({notes})" if notes else ""))


def command_table(run):
    """Multi-line summary of a :class:`cas_freq.studies.run.CommandRun`."""
    from cas_freq.studies.run import command_run_dict

    data = command_run_dict(run)
    head = f"{run.config} / {run.variant}"
    if run.overrides:
        head += " with " + ", ".join(run.overrides)
    r, tracking = run.result, data["tracking"]
    lines = [head]
    if run.linear_stability != "stable":
        lines.append(f"  WARNING: the linear closed loop is {run.linear_stability.upper()} "
                     "(Padé poles)")
    settled = "settled" if r.settled else "NOT settled"
    lines += [
        f"  nonlinear run of the command {run.source}; dt {r.dt_s * 1e6:g} us, "
        f"{r.t_end_s * 1e3:g} ms ({settled}{', horizon extended' if r.extended else ''})",
        f"    tracking error      max {_fmt(tracking['max_abs_error_deg'], 'deg')}, "
        f"RMS {_fmt(tracking['rms_error_deg'], 'deg')}, "
        f"final {_fmt(tracking['final_error_deg'], 'deg')}",
        f"    largest current     {_fmt(data['max_current_a'], 'A')} "
        f"({_limit_text(r.t, r.current_limited)})",
        f"    largest voltage     {_fmt(data['max_voltage_v'], 'V')} "
        f"({_limit_text(r.t, r.voltage_limited)})",
    ]
    return "\n".join(lines)


def _drivetrain_lines(load, loaded=None):
    """The drivetrain block of the analyze text (cas_freq.analysis.drivetrain); the load
    spring at the output as ``loaded``'s output names it (K_h [N*m/rad], at a linear output
    K [N/m])."""
    unit = ANGLE if loaded is None else output_unit(loaded.params)
    gear = "compliant gear, two masses" if load.compliant else "rigid gear"
    lines = [
        f"  load and drivetrain ({gear}), reflected to the motor shaft",
        *(_figure_line(f"drivetrain.{name}", getattr(load, name)) for name in (
            "reflected_inertia_kg_m2", "reflected_damping_n_m_s_rad",
            "reflected_stiffness_n_m_rad")),
        f"    {'open-loop plant':<{_WIDTH}} " + ("stable" if load.plant_stable else
                                    f"UNSTABLE (pole at +{_fmt(load.plant_unstable_pole_rad_s)}"
                                    " rad/s)"),
    ]
    for label, modes in (("resonance", load.resonances),
                         ("anti-resonance", load.anti_resonances)):
        for mode in modes:
            lines.append(f"    {label:<{_WIDTH}} {_fmt(mode.frequency_rad_s, 'rad/s')}, "
                         f"zeta {_fmt(mode.damping)}")
    low, high = load.stable_hinge_stiffness_n_m_rad
    lines.append(f"    {'stable for ' + unit.spring:<{_WIDTH}} " + (
        "none scanned" if low is None and high is None else
        f"{'-inf' if low is None else _fmt(low)} .. {'+inf' if high is None else _fmt(high)} "
        f"{unit.spring_unit}"))
    return lines
