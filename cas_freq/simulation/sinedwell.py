"""Sine-dwell frequency response of the nonlinear loop (numpy only; no python-control).

:func:`sine_dwell` runs the nonlinear simulator (:func:`~cas_freq.simulation.simulate_batch`)
in **one batch** over every (amplitude, frequency) pair, each run a :class:`Sine` command at the
output, and identifies the first harmonic of the output angle and of the command over whole
periods of the steady state. The ratio is the describing-function-like response
delta/delta_cmd at that amplitude: at small amplitude it is the linear closed loop T(jw) (with
the feed-forward the simulator applies, see below); once the current or voltage clamp is reached
it falls below it.

Feed-forward
------------
The simulator adds ``ff_v * theta_cmd' + ff_a * theta_cmd''`` to the current command
(docs/model.md); for a sine these are not zero. :meth:`cas_freq.model.ActuatorLoops.closed_loop`
has no feed-forward by default, so it is the small-amplitude reference only when
``ff_v = ff_a = 0``; with feed-forward the linear reference is ``T_ff = T * (1 + F/C_r)``
with ``F(s) = ff_v s + ff_a s^2`` and ``C_r`` the controller acting on the command
(:func:`linear_reference` computes both).

Settling and the fit
--------------------
Every run starts from rest with ``A sin(w t)`` (continuous angle, so no step-like transient).
The slowest closed-loop pole of the shipped config (about -12 rad/s) sits next to the PID
integral zero (-Ki/Kp = -11 rad/s), so its mode is weakly excited; the runs are not started
with a special phase, instead

- each run settles for ``max(periods_settle * T, min_settle_s)`` (defaults 3 periods and 30 ms)
  before its measurement window starts, and
- the least-squares fit ``a cos(wt) + b sin(wt) + c + d (t - t_mid)`` over the measurement
  window takes out an offset and a linear drift (what is left of the slow mode), which would
  otherwise leak into the first harmonic.

With sampled controllers the fit reads the output (and the command) at the position loop's
sampling instants, as the drive sees them: the sampled closed loop T(e^(j w T)) is output samples
per command sample (docs/model.md, section 14); the continuous output between the samples holds
the hold's aliases as well (about 3 deg more lag at half the Nyquist frequency of the QT-CAS's
2.5 kHz position loop).

For the base config at 0.05 deg and 50 rad/s (the slowest mode is the worst case there), the
fitted response changes by < 5e-4 dB and < 5e-4 deg between 2 and 6 settling periods.

All runs share one horizon, set by the slowest frequency: ``max_f(settle_f + periods_measure T_f)``.
Each run's measurement window is the largest whole number of its periods (at least
``periods_measure``) that ends at the horizon and starts after its own settling time, so the
faster runs get more settling and more periods for free. The cost is the horizon: the simulator
advances all runs together, so the run time grows with ``1 / min(frequency)`` and hardly with
the number of runs (about 6 s for 50 rad/s with the defaults at dt = 5 us).

Samples are recorded every ``record_every`` steps (at least ``samples_per_period`` samples per
period of the fastest frequency) to bound memory; the limit flags are those of the recorded
samples inside the measurement window (the steady state), so a clamp shorter than the recording
interval can be missed.
"""

import dataclasses
import math

import numpy as np

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.formulas import HALF_POWER
from cas_freq.core.parameters import LoopParameters
from cas_freq.model import ActuatorLoops
from cas_freq.simulation.commands import Sine
from cas_freq.simulation.simulator import budget_runs, loop_sampling, loop_time_step, simulate_batch

#: Half-power level [dB]: 20 log10(1/sqrt(2)) = -3.0103 dB.
HALF_POWER_DB = 20.0 * math.log10(HALF_POWER)
#: Fewest simulation steps per period of a dwell frequency: faster sines are refused (the
#: command and the response would be sampled too coarsely to trust their first harmonic).
MIN_STEPS_PER_PERIOD = 20

#: Default settling periods and the shortest settling time [s].
DEFAULT_PERIODS_SETTLE = 3
DEFAULT_MIN_SETTLE_S = 0.03
#: Default number of whole periods in the measurement window (at least).
DEFAULT_PERIODS_MEASURE = 2
#: Default recorded samples per period of the fastest frequency (at least).
DEFAULT_SAMPLES_PER_PERIOD = 64

#: The sine-dwell grid derived from a loop (:func:`dwell_frequencies`, the default of
#: ``cas-freq sinedwell``, ``report``, ``compare`` and of a sine-dwell requirement): this many
#: log-spaced points over DWELL_SPAN x the linear bandwidth omega_BW of T.
DWELL_POINTS = 16
DWELL_SPAN = (0.1, 5.0)
#: The grid of a loop with neither a bandwidth nor a position-loop crossover [rad/s].
FALLBACK_FREQUENCIES_RAD_S = tuple(float(w) for w in np.geomspace(100.0, 5000.0, DWELL_POINTS))


@dataclasses.dataclass(frozen=True, eq=False)
class SineDwellResult:
    """Sine-dwell response per amplitude (rows) and frequency (columns).

    Attributes
    ----------
    amplitudes_rad : numpy.ndarray
        Command amplitudes at the output [rad], shape (n_a,).
    frequencies_rad_s : numpy.ndarray
        Frequencies [rad/s], shape (n_f,), increasing.
    magnitude_db : numpy.ndarray
        |first harmonic of delta / first harmonic of the command| [dB], shape (n_a, n_f).
    phase_deg : numpy.ndarray
        Phase of that ratio [deg], unwrapped along frequency (first column in (-180, 180]).
    current_limited, voltage_limited : numpy.ndarray of bool
        Whether the current-command (voltage) clamp was active at some recorded sample of the
        measurement window, shape (n_a, n_f).
    limit_hit : numpy.ndarray of bool
        ``current_limited | voltage_limited``.
    bandwidth_rad_s : tuple of (float or None)
        Per amplitude, the first downward crossing of -3.0103 dB (log-magnitude interpolated
        linearly in log-frequency between the two grid points straddling it); None if the
        magnitude does not cross it inside the grid.
    settle_s : numpy.ndarray
        Settling time of each frequency [s], shape (n_f,).
    periods_measured : numpy.ndarray of int
        Whole periods in each frequency's measurement window, shape (n_f,).
    dt_s, t_end_s : float
        Simulation step and common horizon [s].
    record_every : int
        Recorded every n-th step.
    """

    amplitudes_rad: np.ndarray
    frequencies_rad_s: np.ndarray
    magnitude_db: np.ndarray
    phase_deg: np.ndarray
    current_limited: np.ndarray
    voltage_limited: np.ndarray
    limit_hit: np.ndarray
    bandwidth_rad_s: tuple
    settle_s: np.ndarray
    periods_measured: np.ndarray
    dt_s: float
    t_end_s: float
    record_every: int

    @property
    def amplitudes_deg(self):
        """Amplitudes at the output [deg]."""
        return np.degrees(self.amplitudes_rad)

    @property
    def bandwidth_bounds(self):
        """Per amplitude, what the grid says of a bandwidth it does not hold
        (:func:`bandwidth_bound`): None where ``bandwidth_rad_s`` has the value."""
        return tuple(None if value is not None else
                     bandwidth_bound(self.frequencies_rad_s, row)
                     for value, row in zip(self.bandwidth_rad_s, self.magnitude_db, strict=True))


def _single(params):
    if isinstance(params, LoopParameters):
        if params.n_runs != 1:
            raise ConfigError(f"sine_dwell: one actuator expected, got {params.n_runs} runs")
        return params
    return LoopParameters.from_config(params)


def _repeat(params, n):
    """Each run of ``params`` ``n`` times in a row."""
    return params.take(np.repeat(np.arange(params.n_runs), n))


def _positive_1d(values, name):
    array = np.atleast_1d(np.asarray(values, dtype=float))
    if array.ndim != 1 or array.size == 0 or not (np.isfinite(array).all() and (array > 0).all()):
        raise ConfigError(f"sine_dwell: {name}: need a 1-D array of finite values > 0")
    return array


def first_harmonic(t, x, omega):
    """Complex amplitude X of ``x ~ Re(X exp(j omega t)) + c + d (t - t_mid)`` (least squares).

    Parameters
    ----------
    t : numpy.ndarray
        Times [s] (ideally a whole number of periods).
    x : numpy.ndarray
        Samples, shape (..., len(t)).
    omega : float
        Frequency [rad/s].

    Returns
    -------
    complex or numpy.ndarray of complex
        ``a - j b`` for ``x = a cos(omega t) + b sin(omega t) + ...``.
    """
    t = np.asarray(t, dtype=float)
    basis = np.column_stack(
        [np.cos(omega * t), np.sin(omega * t), np.ones_like(t), t - 0.5 * (t[0] + t[-1])]
    )
    x = np.asarray(x, dtype=float)
    coefficients = np.linalg.lstsq(basis, x.reshape(-1, t.size).T, rcond=None)[0]
    result = coefficients[0] - 1j * coefficients[1]
    return result.reshape(x.shape[:-1]) if x.ndim > 1 else complex(result[0])


def crossing_bandwidth(frequencies_rad_s, magnitude_db, level_db=HALF_POWER_DB):
    """First downward crossing of ``level_db``, interpolated in (log w, dB); None if none.

    The magnitude is taken relative to T(0) = 1 (0 dB; the position loop has integral action).
    A crossing needs a grid point at or above the level followed by one below it.
    """
    w = np.asarray(frequencies_rad_s, dtype=float)
    m = np.asarray(magnitude_db, dtype=float)
    below = np.flatnonzero(m < level_db)
    if not below.size or below[0] == 0:
        return None
    k = below[0]
    x0, x1 = math.log(w[k - 1]), math.log(w[k])
    fraction = (level_db - m[k - 1]) / (m[k] - m[k - 1])
    return float(math.exp(x0 + fraction * (x1 - x0)))


def bandwidth_bound(frequencies_rad_s, magnitude_db, level_db=HALF_POWER_DB):
    """What a grid without a crossing of ``level_db`` proves about the bandwidth.

    Returns
    -------
    (str, float) or None
        ``(">", w_max)`` when no grid point is below the level (the response is still above it
        at the grid's top, so the bandwidth lies above ``w_max`` [rad/s]); ``("<", w_min)``
        when the first point is already below it (the crossing from T(0) = 1 lies below the
        grid); None when the grid holds a crossing (:func:`crossing_bandwidth`) or has no
        finite magnitude.
    """
    w = np.asarray(frequencies_rad_s, dtype=float)
    m = np.asarray(magnitude_db, dtype=float)
    if not np.isfinite(m).all():
        return None
    if not (m < level_db).any():
        return (">", float(w[-1]))
    if m[0] < level_db:
        return ("<", float(w[0]))
    return None


def bandwidth_text(value, bound, unit=""):
    """A bandwidth as text: the value to 4 significant digits, ``"> 5000"`` / ``"< 100"`` for a
    bound (:func:`bandwidth_bound`), "—" for neither."""
    suffix = f" {unit}" if unit else ""
    if value is not None and math.isfinite(value):
        return f"{value:.4g}{suffix}"
    if bound is not None:
        return f"{bound[0]} {bound[1]:.4g}{suffix}"
    return "—"


def bound_meets(bound, minimum=None, maximum=None):
    """Whether a figure known only as a bound ``(relation, edge)`` meets ``minimum <= value <=
    maximum``: True or False when the bound proves it, None when it cannot decide.

    ``(">", 400)`` meets ``>= 300`` (every value above 400 does) and cannot decide ``>= 500``;
    ``("<", 100)`` violates ``>= 300``.
    """
    relation, edge = bound
    verdicts = []
    for limit, lower in ((minimum, True), (maximum, False)):
        if limit is None:
            continue
        if relation == ">":
            verdicts.append(True if lower and edge >= limit else
                            False if not lower and edge >= limit else None)
        else:
            verdicts.append(False if lower and edge <= limit else
                            True if not lower and edge <= limit else None)
    if False in verdicts:
        return False
    if None in verdicts:
        return None
    return True


def dwell_frequencies(analysis):
    """Default sine-dwell grid of a variant [rad/s]: DWELL_POINTS log-spaced over DWELL_SPAN x
    the linear bandwidth of T (4 significant digits); around the position loop's gain
    crossover when the loop has no bandwidth (unstable); FALLBACK_FREQUENCIES_RAD_S when it has
    neither.

    Parameters
    ----------
    analysis : cas_freq.analysis.Analysis
        The variant's exact-delay analysis.

    Returns
    -------
    tuple of float
    """
    cl = analysis.closed_loop
    centre = None if cl is None else cl.bandwidth_rad_s
    if centre is None:
        centre = analysis.position_loop.crossover_rad_s
    if centre is None or not math.isfinite(centre) or centre <= 0:
        return FALLBACK_FREQUENCIES_RAD_S
    grid = np.geomspace(DWELL_SPAN[0] * centre, DWELL_SPAN[1] * centre, DWELL_POINTS)
    return tuple(float(f"{w:.4g}") for w in grid)


def sine_dwell(
    params,
    amplitudes_rad,
    frequencies_rad_s,
    *,
    periods_settle=DEFAULT_PERIODS_SETTLE,
    periods_measure=DEFAULT_PERIODS_MEASURE,
    min_settle_s=DEFAULT_MIN_SETTLE_S,
    samples_per_period=DEFAULT_SAMPLES_PER_PERIOD,
    dt=None,
    current_rate_hz=None,
    position_rate_hz=None,
    progress=None,
):
    """Sine-dwell response of the nonlinear loop at every amplitude x frequency (one batch).

    Parameters
    ----------
    params : ActuatorConfig or LoopParameters
        One actuator (LoopParameters with n_runs = 1).
    amplitudes_rad : array_like
        Command amplitudes at the output [rad], > 0.
    frequencies_rad_s : array_like
        Frequencies [rad/s], > 0 (sorted increasing in the result).
    periods_settle : float
        Settling periods before measuring (with ``min_settle_s``: settle =
        max(periods_settle * T, min_settle_s)); see the module notes.
    periods_measure : int
        Least number of whole periods in the measurement window.
    min_settle_s : float
        Shortest settling time [s].
    samples_per_period : int
        Least recorded samples per period of the fastest frequency.
    dt : float, optional
        Simulation step [s]; default that of :func:`simulate_batch` (5 us for the shipped config).
    current_rate_hz, position_rate_hz : float, optional
        Sample rates of sampled controllers [Hz]; continuous controllers if None.
    progress : callable, optional
        ``progress(steps_done, steps_planned)``, passed to :func:`simulate_batch`.

    Returns
    -------
    SineDwellResult
    """
    p = _single(params)
    amplitudes = _positive_1d(amplitudes_rad, "amplitudes_rad")
    frequencies = np.sort(_positive_1d(frequencies_rad_s, "frequencies_rad_s"))
    n_a, n_f = amplitudes.size, frequencies.size
    amplitude_grid, frequency_index = np.meshgrid(amplitudes, np.arange(n_f), indexing="ij")
    dwell = _dwell(
        _repeat(p, n_a * n_f), amplitude_grid.ravel(), frequency_index.ravel(), frequencies,
        periods_settle=periods_settle, periods_measure=periods_measure,
        min_settle_s=min_settle_s, samples_per_period=samples_per_period, dt=dt,
        current_rate_hz=current_rate_hz, position_rate_hz=position_rate_hz, progress=progress,
    )
    response = dwell.response.reshape(n_a, n_f)
    magnitude = 20.0 * np.log10(np.abs(response))
    phase = np.unwrap(np.angle(response), axis=1)
    phase -= 2.0 * np.pi * np.round(phase[:, :1] / (2.0 * np.pi) - 1e-12)
    bandwidth = tuple(crossing_bandwidth(frequencies, row) for row in magnitude)
    current_limited = dwell.current_limited.reshape(n_a, n_f)
    voltage_limited = dwell.voltage_limited.reshape(n_a, n_f)
    limit_hit = current_limited | voltage_limited
    for array in (magnitude, phase, current_limited, voltage_limited, limit_hit):
        array.setflags(write=False)
    return SineDwellResult(
        amplitudes_rad=amplitudes, frequencies_rad_s=frequencies, magnitude_db=magnitude,
        phase_deg=np.degrees(phase), current_limited=current_limited,
        voltage_limited=voltage_limited, limit_hit=limit_hit, bandwidth_rad_s=bandwidth,
        settle_s=dwell.settle_s, periods_measured=dwell.periods_measured, dt_s=dwell.dt_s,
        t_end_s=dwell.t_end_s, record_every=dwell.record_every,
    )


@dataclasses.dataclass(frozen=True, eq=False)
class _Dwell:
    """First harmonics of a batch of sine runs (see :func:`_dwell`)."""

    response: np.ndarray
    current_limited: np.ndarray
    voltage_limited: np.ndarray
    settle_s: np.ndarray
    periods_measured: np.ndarray
    dt_s: float
    t_end_s: float
    record_every: int


def _dwell(runs, amplitudes, frequency_index, frequencies, *, periods_settle, periods_measure,
           min_settle_s, samples_per_period, dt, current_rate_hz, position_rate_hz, progress):
    """Simulate sine runs in one batch and take each one's first harmonic.

    Run r is ``amplitudes[r] * sin(frequencies[frequency_index[r]] * t)`` on actuator
    ``runs.run(r)``; every run shares the horizon of the lowest frequency (module notes).
    """
    if not (isinstance(periods_measure, (int, np.integer)) and periods_measure >= 1):
        raise ConfigError(f"sine_dwell: periods_measure: need an integer >= 1, got "
                          f"{periods_measure!r}")
    if not (periods_settle >= 0 and min_settle_s >= 0):
        raise ConfigError("sine_dwell: periods_settle and min_settle_s must be >= 0")
    if not (isinstance(samples_per_period, (int, np.integer)) and samples_per_period >= 4):
        raise ConfigError("sine_dwell: samples_per_period: need an integer >= 4")
    periods = 2.0 * math.pi / frequencies
    settle = np.maximum(periods_settle * periods, min_settle_s)
    t_end = float(np.max(settle + periods_measure * periods))
    if dt is None:
        periods_c = [1.0 / rate for rate in (current_rate_hz, position_rate_hz) if rate]
        dt = loop_time_step(runs, periods_c)
    fastest = 2.0 * math.pi / (MIN_STEPS_PER_PERIOD * dt)
    if frequencies.max() > fastest:
        raise ConfigError(
            f"frequencies: {frequencies.max():g} rad/s is too fast for the simulation step "
            f"{dt * 1e6:g} us; at most {fastest:.5g} rad/s ({MIN_STEPS_PER_PERIOD} steps per "
            "period)"
        )
    record_every = max(1, int(periods.min() / (samples_per_period * dt)))
    stride = 1
    sampled_at = loop_sampling(runs, current_rate_hz, position_rate_hz)[0]["position_loop"]
    if sampled_at:  # sampled: the output as the drive sees it, at its position samples
        steps = max(1, int(round(1.0 / (sampled_at * dt))))
        record_every = max(k for k in range(1, min(record_every, steps) + 1) if steps % k == 0)
        stride = steps // record_every
    batch = simulate_batch(
        runs, Sine(amplitudes, frequencies[frequency_index]), t_end=t_end, dt=dt,
        record_every=record_every, current_rate_hz=current_rate_hz,
        position_rate_hz=position_rate_hz, progress=progress,
        signals=("theta", "theta_cmd", "current_limited", "voltage_limited"),  # what it reads
    )
    t = batch.t
    response = np.empty(runs.n_runs, dtype=complex)
    current_limited = np.empty(runs.n_runs, dtype=bool)
    voltage_limited = np.empty(runs.n_runs, dtype=bool)
    measured = np.empty(frequencies.size, dtype=int)
    half_sample = 0.5 * record_every * batch.dt_s
    for j, (w, period) in enumerate(zip(frequencies, periods, strict=True)):
        count = max(periods_measure, int(math.floor((batch.t_end_s - settle[j]) / period + 1e-9)))
        measured[j] = count
        window = (t >= batch.t_end_s - count * period - half_sample) & (
            t < batch.t_end_s - half_sample
        ) & (np.arange(t.size) % stride == 0)
        rows = frequency_index == j
        response[rows] = first_harmonic(t[window], batch.delta[rows][:, window], w) / (
            first_harmonic(t[window], batch.command[rows][:, window], w)
        )
        current_limited[rows] = batch.current_limited[rows][:, window].any(axis=-1)
        voltage_limited[rows] = batch.voltage_limited[rows][:, window].any(axis=-1)
    settle.setflags(write=False)
    measured.setflags(write=False)
    return _Dwell(response, current_limited, voltage_limited, settle, measured,
                  float(batch.dt_s), float(batch.t_end_s), record_every)


def sine_dwell_bandwidths(params, amplitude_rad, frequencies_rad_s, *, chunk_size=64,
                          current_rate_hz=None, position_rate_hz=None, progress=None,
                          **options):
    """Sine-dwell bandwidth of many actuators at one amplitude (for sweeps and Monte Carlo).

    Each actuator is dwelt at every frequency as :func:`sine_dwell` does for one (same settling,
    windows and fit), in batches of ``chunk_size`` actuators (``chunk_size * n_f`` runs at a
    time). The default step of a batch is the finest any of its actuators needs; for actuators
    with the same current loop and delays (the usual sweep of position gains or motor
    constants) it is :func:`sine_dwell`'s, and the results are the same.

    Parameters
    ----------
    params : LoopParameters
        The actuators (n_runs of them).
    amplitude_rad : float
        Command amplitude at the output [rad], > 0.
    frequencies_rad_s : array_like
        Frequencies [rad/s].
    chunk_size : int
        Actuators simulated together.
    current_rate_hz, position_rate_hz : float, optional
        Sampled-controller rates [Hz].
    progress : callable, optional
        ``progress(actuators_done, n_runs)`` after each chunk.
    **options
        ``periods_settle``, ``periods_measure``, ``min_settle_s``, ``samples_per_period``,
        ``dt`` as for :func:`sine_dwell`.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        Bandwidth [rad/s] per actuator (NaN without a crossing in the grid), magnitude [dB]
        (n_runs, n_f), and whether a limit acted (n_runs, n_f).
    """
    amplitude = float(_positive_1d(amplitude_rad, "amplitude_rad")[0])
    frequencies = np.sort(_positive_1d(frequencies_rad_s, "frequencies_rad_s"))
    settings = {"periods_settle": DEFAULT_PERIODS_SETTLE, "periods_measure":
                DEFAULT_PERIODS_MEASURE, "min_settle_s": DEFAULT_MIN_SETTLE_S,
                "samples_per_period": DEFAULT_SAMPLES_PER_PERIOD, "dt": None, **options}
    n, n_f = params.n_runs, frequencies.size
    chunk_size = min(chunk_size, _chunk_within_budget(params, frequencies, settings, n_f,
                                                      current_rate_hz, position_rate_hz))
    bandwidth = np.full(n, np.nan)
    magnitude = np.empty((n, n_f))
    limited = np.empty((n, n_f), dtype=bool)
    for start in range(0, n, chunk_size):
        stop = min(start + chunk_size, n)
        chunk = params.take(slice(start, stop))
        dwell = _dwell(
            _repeat(chunk, n_f), np.full((stop - start) * n_f, amplitude),
            np.tile(np.arange(n_f), stop - start), frequencies, current_rate_hz=current_rate_hz,
            position_rate_hz=position_rate_hz, progress=None, **settings,
        )
        block = 20.0 * np.log10(np.abs(dwell.response.reshape(stop - start, n_f)))
        magnitude[start:stop] = block
        limited[start:stop] = (dwell.current_limited | dwell.voltage_limited).reshape(-1, n_f)
        for row, values in enumerate(block):
            value = crossing_bandwidth(frequencies, values)
            bandwidth[start + row] = np.nan if value is None else value
        if progress:
            progress(stop, n)
    return bandwidth, magnitude, limited


def _chunk_within_budget(params, frequencies, settings, n_f, current_rate_hz,
                         position_rate_hz):
    """Actuators per batch that keep a batch of ``n_f`` runs each within the simulator's budget
    (:func:`~cas_freq.simulation.simulator.check_budget`); at least 1 (a single actuator beyond
    the budget is then refused by the batch itself)."""
    periods = 2.0 * math.pi / frequencies
    settle = np.maximum(settings["periods_settle"] * periods, settings["min_settle_s"])
    t_end = float(np.max(settle + settings["periods_measure"] * periods))
    dt = settings["dt"]
    if dt is None:
        periods_c = [1.0 / rate for rate in (current_rate_hz, position_rate_hz) if rate]
        dt = loop_time_step(params, periods_c)
    record_every = max(1, int(periods.min() / (settings["samples_per_period"] * dt)))
    max_delay = float(max(np.max(params.tau_c), np.max(params.tau_p), np.max(params.tau_v), 0.0))
    runs = budget_runs(int(round(t_end / dt)), dt, record_every, max_delay)
    return max(1, runs // n_f)


def limit_onset_amplitude(result):
    """Smallest amplitude [rad] at which any limit is hit at any frequency; None if never."""
    hit = np.asarray(result.limit_hit).any(axis=1)
    if not hit.any():
        return None
    return float(np.min(np.asarray(result.amplitudes_rad)[hit]))


def linear_reference(params, omega, feedforward=True):
    """Exact-delay linear response delta/delta_cmd at ``omega`` [rad/s] (numpy only).

    :meth:`ActuatorLoops.closed_loop` with or without the feed-forward
    ``F(s) = ff_v s + ff_a s^2`` (motor-angle units, as the simulator applies it): the
    small-amplitude limit of :func:`sine_dwell`.
    """
    s = 1j * np.asarray(omega, dtype=float)
    return ActuatorLoops(params).closed_loop(s, feedforward=feedforward)
