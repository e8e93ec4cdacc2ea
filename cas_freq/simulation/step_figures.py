"""Step figures of a sampled step response (docs/model.md, "Definitions of the figures").

Of the output angle delta in response to a step of delta_cmd:

- rise time: from the first time the response reaches 10 % of the final value to the first time
  it reaches 90 % (both interpolated linearly between samples);
- overshoot: (peak - final) / final [%] (0 if the response never exceeds the final value), the
  peak refined by a parabola through the largest sample and its neighbours;
- settling time: the last time the response is outside ±2 % (±5 %) of the final value, taken
  where it crosses into the band (interpolated);
- the largest |current| and |voltage|, and whether either limit was hit.

The final value is the step size by default: with integral action the loop settles on the
command exactly (docs/model.md's T(0) = 1). A response that diverged (:func:`diverged`) has
none of these figures (NaN).
"""

import dataclasses
import math

import numpy as np

#: A step response beyond this many times its final value has diverged (a loop that is not
#: stable, or one the limits let run away): no response of a loop that holds comes near it.
DIVERGED = 1e6


def diverged(t, response, final):
    """The first time [s] at which ``response`` is not finite or beyond :data:`DIVERGED` times
    ``final`` in magnitude, or None where it never is.

    Parameters
    ----------
    t : array_like
        Sample times [s].
    response : array_like
        The response (the unit of ``final``).
    final : float
        Its final value, nonzero.
    """
    y = np.asarray(response, dtype=float)
    with np.errstate(invalid="ignore"):
        out = np.flatnonzero(~(np.abs(y) <= DIVERGED * abs(final)))
    return float(np.asarray(t, dtype=float)[out[0]]) if out.size else None


@dataclasses.dataclass(frozen=True)
class StepFigures:
    """Figures of one step response.

    Attributes
    ----------
    amplitude_deg : float
        Step size at the output [deg].
    rise_time_s : float
        10 % -> 90 % rise time [s] (nan if the response never reaches 90 %).
    overshoot_pct : float
        (peak - final) / final [%], >= 0.
    settling_time_s, settling_time_5pct_s : float
        Last time outside ±2 % / ±5 % of the final value [s] (nan if not settled by the end).
    peak_time_s : float
        Time of the largest response [s].
    max_current_a, max_voltage_v : float or None
        Largest |i| [A] and |V| [V] (None if not given).
    current_limited, voltage_limited : bool or None
        Whether the current (voltage) limit was hit (None if not known).
    """

    amplitude_deg: float
    rise_time_s: float
    overshoot_pct: float
    settling_time_s: float
    settling_time_5pct_s: float
    peak_time_s: float
    max_current_a: float | None = None
    max_voltage_v: float | None = None
    current_limited: bool | None = None
    voltage_limited: bool | None = None


def _first_crossing(t, y, level):
    """First time y reaches ``level`` from below (interpolated); nan if never."""
    above = np.flatnonzero(y >= level)
    if above.size == 0:
        return math.nan
    k = above[0]
    if k == 0:
        return float(t[0])
    return float(t[k - 1] + (level - y[k - 1]) / (y[k] - y[k - 1]) * (t[k] - t[k - 1]))


def settling_time(t, y, band):
    """Last time the normalised response ``y`` (final value 1) is outside ``1 ± band`` [s].

    Taken where it crosses into the band after its last sample outside (interpolated); 0 if it
    never leaves the band after ``t[0]``, nan if it is outside at the last sample.
    """
    outside = np.flatnonzero(np.abs(y - 1.0) > band)
    if outside.size == 0:
        return float(t[0])
    k = outside[-1]
    if k == y.size - 1:
        return math.nan
    edge = 1.0 + band if y[k] > 1.0 else 1.0 - band
    return float(t[k] + (edge - y[k]) / (y[k + 1] - y[k]) * (t[k + 1] - t[k]))


def _peak(t, y):
    k = int(np.argmax(y))
    if 0 < k < y.size - 1 and np.isclose(t[k + 1] - t[k], t[k] - t[k - 1], rtol=1e-6):
        a, b, c = y[k - 1], y[k], y[k + 1]
        curvature = a - 2 * b + c
        if curvature < 0:
            shift = 0.5 * (a - c) / curvature
            step = t[k + 1] - t[k]
            return float(t[k] + shift * step), float(b - 0.25 * (a - c) * shift)
    return float(t[k]), float(y[k])


def step_figures(
    t, response, step, *, final_value=None, current=None, voltage=None,
    current_limited=None, voltage_limited=None,
):
    """Step figures of a response to a step applied at ``t = 0``.

    Parameters
    ----------
    t : array_like
        Sample times [s], increasing (the step at 0).
    response : array_like
        Output angle [rad] (any unit, as long as ``step`` and ``final_value`` use it too).
    step : float
        Step size [rad], nonzero.
    final_value : float, optional
        Value the response settles on; default ``step``.
    current, voltage : array_like, optional
        Motor current [A] and voltage [V] over the run.
    current_limited, voltage_limited : array_like of bool, optional
        Where each limit was active.

    Returns
    -------
    StepFigures
    """
    t = np.asarray(t, dtype=float)
    final = float(step if final_value is None else final_value)
    if final == 0 or not math.isfinite(final):
        raise ValueError(f"step figures: final value must be finite and nonzero, got {final!r}")
    y = np.asarray(response, dtype=float) / final
    if diverged(t, y, 1.0) is not None:  # no figures of a run that diverged
        nan = math.nan
        return StepFigures(
            amplitude_deg=math.degrees(step), rise_time_s=nan, overshoot_pct=nan,
            settling_time_s=nan, settling_time_5pct_s=nan, peak_time_s=nan,
            max_current_a=None if current is None else nan,
            max_voltage_v=None if voltage is None else nan,
            current_limited=None if current_limited is None else bool(np.any(current_limited)),
            voltage_limited=None if voltage_limited is None else bool(np.any(voltage_limited)),
        )
    peak_time, peak = _peak(t, y)
    return StepFigures(
        amplitude_deg=math.degrees(step),
        rise_time_s=_first_crossing(t, y, 0.9) - _first_crossing(t, y, 0.1),
        overshoot_pct=max(0.0, 100.0 * (peak - 1.0)),
        settling_time_s=settling_time(t, y, 0.02),
        settling_time_5pct_s=settling_time(t, y, 0.05),
        peak_time_s=peak_time,
        max_current_a=None if current is None else float(np.max(np.abs(current))),
        max_voltage_v=None if voltage is None else float(np.max(np.abs(voltage))),
        current_limited=None if current_limited is None else bool(np.any(current_limited)),
        voltage_limited=None if voltage_limited is None else bool(np.any(voltage_limited)),
    )


def simulation_step_figures(result, step=None):
    """Step figures of a simulated step (:class:`~cas_freq.simulation.SimulationResult`).

    Parameters
    ----------
    result : SimulationResult
        A run whose command is a step at t = 0.
    step : float, optional
        Step size at the output [rad]; default the command's final value.

    Returns
    -------
    StepFigures
    """
    step = float(result.command[-1]) if step is None else step
    return step_figures(
        result.t, result.delta, step, current=result.i, voltage=result.V,
        current_limited=result.current_limited, voltage_limited=result.voltage_limited,
    )
