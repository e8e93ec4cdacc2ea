"""What the design page shows for one state: the existing engine on the config with overrides.

Every figure is computed by the code the commands use, so the page and the commands agree to
their printed digits: :func:`cas_freq.analysis.analyze` (exact delays, default range) for the
margins and the bandwidth, :func:`cas_freq.report.data.curves` for the Bode data (the report's
curves), :func:`cas_freq.verify.evaluate.verify_variant` for the verdicts of the config's
analyze-kind requirements (the figures ``verify`` uses),
:func:`cas_freq.report.data.linear_steps` for the linear step (Padé model, as the report draws
it) and :func:`cas_freq.studies.run.step_run` (``simulate --step``) for the nonlinear step.
"""

import math

import numpy as np

from cas_freq.core.exceptions import CasFreqError, ConfigError
from cas_freq.core.figures import FIGURES
from cas_freq.core.fileio import json_ready
from cas_freq.core.numbers import number
from cas_freq.core.output import output_unit
from cas_freq.core.parameters import (
    PARAMETERS,
    check_key,
    loop_values,
    parameter,
    parse_value,
    variant_parameters,
)
from cas_freq.model import DEFAULT_PADE_ORDER
from cas_freq.tuning.options import DEFAULT_FACTOR
from cas_freq.tuning.space import default_free

#: Points per decade of the Bode curves sent to the page.
CURVE_POINTS_PER_DECADE = 40
#: Samples of each step curve sent to the page (decimated from the simulation).
STEP_SAMPLES = 400
#: Digits of the figures shown in the page: those ``cas-freq analyze`` prints.
DIGITS = 4


def _finite(value):
    return None if value is None or not math.isfinite(value) else float(value)


def _sample_rate(key, params):
    """The variant's rate [Hz] of sample-rate key ``sampling.<loop>``; ConfigError for a loop
    the variant runs continuously (the page changes a rate, it does not make a loop
    sampled: that is the config's architecture)."""
    value = getattr(getattr(params, "sampling", None), key.split(".", 1)[1], None)
    if value is None:
        raise ConfigError(f"{key}: the variant runs this loop continuously; a sample rate is "
                          "changed here, not introduced (give it in the config's sampling:)")
    return float(value)


#: The keys that take one of a few words, not a number: the page shows a choice for them.
CHOICES = {"sampling.method": ("backward", "tustin")}
#: Decades the slider of a key at zero spans below the table's upper bound when the table has
#: no smallest magnitude.
ZERO_DECADES = 12


def _check(key, params):
    """ConfigError unless ``key`` can have a control: a key a sweep can vary, or a sample
    rate of a sampled loop, or the discretisation of a sampled variant (static for a batch,
    but one variant at a time here). Returns the sample rate [Hz] of a rate key, else None."""
    if key in CHOICES:
        if not params.sampling.sample_rates:
            raise ConfigError(f"{key}: the variant's controllers are continuous; the "
                              "discretisation is chosen for sampled ones (give their rates in "
                              "the config's sampling:)")
        return None
    if key.startswith("sampling.") and key in PARAMETERS:
        return _sample_rate(key, params)
    check_key(key, params)
    return None


def _slider(value, record):
    """The slider of a key at ``value`` [SI] whose parameter-table record is ``record``:
    ``{"slider", "sign", "lower", "upper"}``, ``lower``/``upper`` the magnitudes [SI] its log
    scale spans.

    ``"log"``: tune's default range around the value (|value| /4 .. x4, ``sign`` that of the
    value) within the table's range. A key at zero has no such range: its slider spans the
    table's non-zero magnitudes (its smallest accepted one .. its largest) with zero at its
    start (``"zero-log"``), or on both sides of a zero at its centre for a key that takes
    negative values too (``"signed-log"``, e.g. ``load.hinge_stiffness``).
    """
    low = record.lower if record.lower is not None else -math.inf
    high = record.upper if record.upper is not None else math.inf
    smallest = record.smallest or (low if low > 0 else -high if high < 0 else None)
    if value != 0:
        sign = 1.0 if value > 0 else -1.0
        # the magnitudes the table accepts on the value's side of zero
        near, far = sorted((abs(low), abs(high))) if low * high > 0 else (0.0, max(
            high * sign, low * sign))
        return {"slider": "log", "sign": sign,
                "lower": max(abs(value) / DEFAULT_FACTOR, near, smallest or 0.0),
                "upper": min(abs(value) * DEFAULT_FACTOR, far)}
    top = max(high, -low)
    if not math.isfinite(top):
        top = (smallest or 1.0) * 10.0 ** ZERO_DECADES
    return {"slider": "signed-log" if low < 0 else "zero-log", "sign": 1.0,
            "lower": smallest or top * 10.0 ** -ZERO_DECADES, "upper": top}


def controls(loaded, keys=None):
    """The keys the page offers, grouped by loop, with their value, unit and ranges.

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant
    keys : sequence of str, optional
        Default: the free keys of ``tune`` (:func:`cas_freq.tuning.space.default_free`), and
        ``sampling.method`` for a sampled variant. Any key a sweep can vary, the sample rates
        of a sampled variant's loops and its ``sampling.method``.

    Returns
    -------
    list of dict
        ``{"key", "group", "value" [SI], "unit", "slider", "sign", "lower", "upper", ...}``
        (the slider: :func:`_slider`, within the parameter table's range
        (:data:`cas_freq.core.parameters.PARAMETERS`), which bounds the typed entry); a key of
        :data:`CHOICES` has ``"choices"`` and its word as ``value`` instead.
    """
    params = loaded.params
    if keys is None:
        keys = (*default_free(params), *(CHOICES if params.sampling.sample_rates else ()))
    loop = variant_parameters(params, {})
    out = []
    for key in keys:
        rate = _check(key, params)
        if key in CHOICES:
            out.append({"key": key, "group": key.split(".")[0],
                        "value": getattr(params.sampling, key.split(".", 1)[1]), "unit": "",
                        "choices": list(CHOICES[key]),
                        "meaning": "discretisation of the sampled controllers: backward "
                                   "(s -> (1 - 1/z)/T) or tustin (s -> (2/T)(z - 1)/(z + 1))"})
            continue
        record = parameter(key, params)
        value = rate if rate is not None else float(np.ravel(loop_values(loop, key, params))[0])
        out.append({
            "key": key, "group": key.split(".")[0], "value": value, "unit": record.unit,
            **_slider(value, record),
            "table_lower": record.lower, "table_upper": record.upper,
            "meaning": record.meaning,
        })
    return out


def check_values(values, config):
    """{key: error text} of the entries of ``values`` (key -> text) that do not parse."""
    errors = {}
    for key, text in values.items():
        try:
            _check(key, config)
            if key in CHOICES:
                if text not in CHOICES[key]:
                    raise ConfigError(f"{key}: must be one of "
                                      f"{' or '.join(map(repr, CHOICES[key]))}, got {text!r}")
                continue
            parse_value(key, text, config)
        except CasFreqError as exc:
            errors[key] = str(exc)
    return errors


def _bode(omega, response):
    """(magnitude [dB], unwrapped phase [deg]) lists of a response on ``omega`` [rad/s];
    non-finite values (above a sampled loop's Nyquist frequency) as None."""
    with np.errstate(divide="ignore", invalid="ignore"):
        magnitude = 20.0 * np.log10(np.abs(response))
        phase = np.degrees(np.unwrap(np.angle(response)))
    # the phase unwrapped from a start within -360..0 deg at the lowest frequency
    if phase.size and np.isfinite(phase[0]):
        phase -= 360.0 * math.floor((phase[0] + 360.0) / 360.0)
    return [_finite(v) for v in magnitude], [_finite(v) for v in phase]


#: A loop's margins the page shows (figures of :data:`cas_freq.core.figures.FIGURES` after the
#: loop's name).
MARGINS = ("crossover_rad_s", "phase_margin_deg", "delay_margin_s", "gain_margin_db",
           "phase_crossover_rad_s", "gain_margin_low_db", "phase_crossover_low_rad_s")

#: The columns of the page's margin table (view, figure, heading: the figure table's label and
#: unit, and its short name for the plots' labels): each loop's own margins, then those with
#: every other loop closed.
MARGIN_COLUMNS = [{"view": view, "name": name, "heading": (
    "every other loop closed: " if view == "loop_at_a_time" else "")
    + FIGURES[f"position_loop.{name}"].heading,
    "short": FIGURES[f"position_loop.{name}"].short_name}
    for view, names in (
        ("margins", ("crossover_rad_s", "phase_margin_deg", "gain_margin_db",
                     "gain_margin_low_db", "delay_margin_s")),
        ("loop_at_a_time", ("phase_margin_deg", "gain_margin_db", "crossover_rad_s")))
    for name in names]


def _margins(margins):
    """A loop's margins [SI, deg, dB] and their texts as ``analyze`` prints them, in the units
    the figure table shows them in (None for None)."""
    if margins is None:
        return None
    figures = {name: getattr(margins, name) for name in MARGINS}
    out = {name: _finite(value) for name, value in figures.items()}
    out["text"] = {name: number(FIGURES[f"position_loop.{name}"].shown(value), DIGITS)
                   for name, value in figures.items()}
    return out


def _bandwidth_line(requirements):
    """The bandwidth [rad/s] the config's analyze-kind requirements ask for at least (the
    largest of their minimums), or None."""
    bounds = [r.min for r in requirements
              if r.kind == "analyze" and r.metric == "closed_loop.bandwidth_rad_s"
              and r.min is not None]
    return max(bounds) if bounds else None


def _decimated(t, y):
    """{"t": times [s], "y": values}, at most ~:data:`STEP_SAMPLES` of them."""
    step = max(1, len(t) // STEP_SAMPLES)
    return {"t": [float(v) for v in t[::step]], "y": [_finite(v) for v in y[::step]]}


def limited_spans(t, flags):
    """[(start, end) [s], ...] of the runs of True in ``flags`` (full resolution: a short
    clamp is not lost to the curves' decimation)."""
    flags = np.asarray(flags, dtype=bool)
    if not flags.any():
        return []
    edges = np.flatnonzero(np.diff(np.concatenate([[False], flags, [False]]).astype(int)))
    starts, ends = edges[::2], edges[1::2] - 1
    return [(float(t[a]), float(t[b])) for a, b in zip(starts, ends, strict=True)]


def steps(loaded, analysis, amplitude, nonlinear=True):
    """The linear and (with ``nonlinear``) the nonlinear step at the output, in the output's
    shown unit (deg, or mm for a linear output); ``amplitude`` [rad or m]."""
    from cas_freq.report.data import linear_steps
    from cas_freq.studies.run import step_run

    unit = output_unit(loaded.params)
    out = {"amplitude": float(unit.from_si(amplitude)), "unit": unit.shown, "figures": None}
    if nonlinear and analysis.stable:
        run = step_run(loaded, amplitude)
        t = np.asarray(run.result.t)
        out["nonlinear"] = _decimated(t, unit.from_si(np.asarray(run.result.delta)))
        out["limited"] = {name: limited_spans(t, getattr(run.result, f"{name}_limited"))
                          for name in ("current", "voltage")}
        out["figures"] = {name: _finite(getattr(run.step, name)) for name in
                          ("rise_time_s", "overshoot_pct", "settling_time_s", "peak_time_s")}
        # as the step's title names them: the figure table's label, value and unit
        out["figure_texts"] = {name: f"{FIGURES[f'step.{name}'].label} " + number(
            FIGURES[f"step.{name}"].shown(value), 3, FIGURES[f"step.{name}"].shown_unit)
            for name, value in out["figures"].items()}
        t_end = float(t[-1])
    else:
        bandwidth = analysis.closed_loop.bandwidth_rad_s if analysis.closed_loop else None
        t_end = 20.0 / bandwidth if bandwidth else 0.05
    if analysis.stable:
        t = np.linspace(0.0, t_end, STEP_SAMPLES)
        (linear,) = linear_steps(loaded.params, [t], [amplitude], DEFAULT_PADE_ORDER)
        out["linear"] = _decimated(t, unit.from_si(linear))
    return out


def default_step(loaded):
    """The step the page starts with [rad or m]: the output's example (``5deg``... ``5mm``)."""
    return output_unit(loaded.params).example_step


def design_state(loaded, step_rad=None, nonlinear=True):
    """Everything the page draws for one loaded variant (JSON-ready dict).

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant
        The config variant with the page's values as overrides.
    step_rad : float, optional
        The step at the output [rad, or m for a linear output] (default
        :func:`default_step`).
    nonlinear : bool
        Also simulate the nonlinear step.

    Returns
    -------
    dict
    """
    from cas_freq.analysis import analyze
    from cas_freq.report.data import curves, loop_frequency_range
    from cas_freq.verify.evaluate import verdict_dict, verify_variant

    # every figure as analyze gives it, but the loaded variant's stable hinge-stiffness scan
    # (most of the time of a loaded variant; no requirement and nothing on the page uses it)
    analysis = analyze(loaded, hinge_range=False)
    found = curves(loaded.params, loop_frequency_range(analysis), CURVE_POINTS_PER_DECADE)
    omega = [float(w) for w in found.omega_rad_s]
    loops = []
    for described in found.described:
        magnitude, phase = _bode(found.omega_rad_s, found.loops[described.name])
        margins = getattr(analysis, described.name, None)
        loops.append({
            "name": described.name, "symbol": described.symbol, "words": described.words,
            "breaks_at": described.breaks_at, "magnitude_db": magnitude, "phase_deg": phase,
            "margins": _margins(margins),
            "loop_at_a_time": _margins(margins.loop_at_a_time if margins else None),
        })
    closed_magnitude, closed_phase = _bode(found.omega_rad_s, found.closed_loop)
    closed = analysis.closed_loop
    requirements = loaded.params.requirements
    analyze_kind = [r for r in requirements if r.kind == "analyze"]
    verdicts = (verify_variant(loaded, analyze_kind, known={"analyze": analysis})
                if analyze_kind else [])

    bandwidth = closed.bandwidth_rad_s if closed else None
    return json_ready({
        "config": loaded.params.name, "variant": loaded.variant,
        "overrides": [f"{key}={value}" for key, value in loaded.overrides],
        "stability": analysis.stability.verdict, "stable": analysis.stable,
        "omega_rad_s": omega, "loops": loops, "margin_columns": MARGIN_COLUMNS,
        "closed_loop": {
            "magnitude_db": closed_magnitude, "phase_deg": closed_phase,
            "bandwidth_rad_s": _finite(bandwidth),
            "bandwidth_text": number(bandwidth, DIGITS),
            "peak_db": _finite(closed.peak_db) if closed else None,
            "required_bandwidth_rad_s": _bandwidth_line(requirements),
        },
        "verdicts": [verdict_dict(v) for v in verdicts],
        "step": steps(loaded, analysis, default_step(loaded) if step_rad is None else step_rad,
                      nonlinear),
        "notes": list(analysis.notes),
    })


__all__ = ["CHOICES", "check_values", "controls", "default_step", "design_state", "limited_spans",
           "steps"]
