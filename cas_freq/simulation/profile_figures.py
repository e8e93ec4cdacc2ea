"""Figures of a simulated profile move (docs/model.md, "Profile moves").

Of the output angle delta following a :class:`~cas_freq.simulation.commands.Profile` of distance D
that starts at t0 and ends at t0 + T:

- tracking error: delta_cmd - delta over the move (t0 <= t <= t0 + T): its largest magnitude
  (and when, from t0) and its RMS [deg];
- overshoot: past the final value D, (peak - D) / D [%], as a step's (:mod:`step_figures`);
- arrival time: from t0 to the last time delta is outside ±2 % (±5 %) of D around D, as a
  step's settling time measured from the move's start;
- settling time: the same after the move's end, arrival - T, 0 when delta is inside the band
  from the move's end on;
- the largest |current| and |voltage|, and whether either limit was hit (over the whole run).

Where a definition is a step's, :func:`~cas_freq.simulation.step_figures.step_figures`
computes it.
"""

import dataclasses
import math

import numpy as np

from cas_freq.simulation.step_figures import step_figures


@dataclasses.dataclass(frozen=True)
class ProfileFigures:
    """Figures of one profile move.

    Attributes
    ----------
    distance_deg : float
        The move at the output [deg] (signed).
    peak_rate_deg_s : float
        The command's largest speed at the output [deg/s] (the velocity limit, or less for a
        triangular move).
    move_time_s : float
        How long the command moves [s].
    tracking_error_max_deg : float
        Largest |delta_cmd - delta| during the move [deg].
    tracking_error_max_time_s : float
        When it occurs, from the move's start [s].
    tracking_error_rms_deg : float
        RMS of delta_cmd - delta during the move [deg].
    overshoot_pct : float
        (peak - D) / D [%], >= 0.
    settling_time_s, settling_time_5pct_s : float
        From the move's end until delta stays within ±2 % / ±5 % of D [s] (0 if it already
        does; nan if it never does within the run).
    arrival_time_s, arrival_time_5pct_s : float
        The same from the move's start [s].
    final_error_deg : float
        delta_cmd - delta at the end of the run [deg].
    max_current_a, max_voltage_v : float
        Largest |i| [A] and |V| [V].
    current_limited, voltage_limited : bool
        Whether the current (voltage) limit was hit.
    """

    distance_deg: float
    peak_rate_deg_s: float
    move_time_s: float
    tracking_error_max_deg: float
    tracking_error_max_time_s: float
    tracking_error_rms_deg: float
    overshoot_pct: float
    settling_time_s: float
    settling_time_5pct_s: float
    arrival_time_s: float
    arrival_time_5pct_s: float
    final_error_deg: float
    max_current_a: float
    max_voltage_v: float
    current_limited: bool
    voltage_limited: bool


def _after_end(arrival, move_time):
    """Time from the move's end to ``arrival`` [s]: 0 if before it, nan stays nan."""
    return arrival if math.isnan(arrival) else max(0.0, arrival - move_time)


def profile_figures(result, profile):
    """Figures of a simulated move (:class:`~cas_freq.simulation.SimulationResult`).

    Parameters
    ----------
    result : SimulationResult
        A run whose command is ``profile``.
    profile : cas_freq.simulation.commands.Profile
        The move (one distance).

    Returns
    -------
    ProfileFigures
    """
    distance = float(profile.distance_rad)
    start, move_time = profile.start_s, profile.move_time_s
    t = np.asarray(result.t) - start
    step = step_figures(
        t, result.delta, distance, current=result.i, voltage=result.V,
        current_limited=result.current_limited, voltage_limited=result.voltage_limited,
    )
    during = (t >= 0.0) & (t <= move_time * (1 + 1e-12))
    error = np.degrees(np.asarray(result.command) - np.asarray(result.delta))
    moving = error[during]
    worst = int(np.argmax(np.abs(moving)))
    return ProfileFigures(
        distance_deg=math.degrees(distance),
        peak_rate_deg_s=math.degrees(float(profile.peak_rate_rad_s)),
        move_time_s=move_time,
        tracking_error_max_deg=float(abs(moving[worst])),
        tracking_error_max_time_s=float(t[during][worst]),
        tracking_error_rms_deg=float(np.sqrt(np.mean(moving**2))),
        overshoot_pct=step.overshoot_pct,
        settling_time_s=_after_end(step.settling_time_s, move_time),
        settling_time_5pct_s=_after_end(step.settling_time_5pct_s, move_time),
        arrival_time_s=step.settling_time_s,
        arrival_time_5pct_s=step.settling_time_5pct_s,
        final_error_deg=float(error[-1]),
        max_current_a=step.max_current_a,
        max_voltage_v=step.max_voltage_v,
        current_limited=step.current_limited,
        voltage_limited=step.voltage_limited,
    )
