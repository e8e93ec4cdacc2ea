"""Nonlinear time-domain simulation of the full actuator loop of docs/model.md.

The loop: PID position controller (derivative on error or on measurement, feed-forward, clamp to
±i_max with anti-windup) -> delay tau_p -> PI current controller (clamp to ±v_max with
anti-windup) -> delay tau_c -> motor (i, omega, theta) -> fin angle delta = theta / N. The
numerics are in :mod:`~cas_freq.simulation.engine`: exact discretisation of the linear plant,
trapezoidal controllers, delay lines. numpy and scipy only (no python-control, no matplotlib).
With a load or drivetrain term ("Load and drivetrain" of the model) the plant is the loaded one
of :mod:`~cas_freq.simulation.mechanics` (load inertia, damping and hinge moment, a compliant
gear whose fin angle delta is a state of its own, efficiencies, backlash, Coulomb friction);
runs without any keep the unloaded plant and its numbers. The other drive architectures
(docs/model.md §13: a velocity loop, filters, output feedback) add their blocks between the
position controller and the current loop (:mod:`~cas_freq.simulation.architecture`, from the
declared structure). Sampled controllers (docs/model.md "Sampled controllers"): each loop at
its own rate, zero-order hold, discretised by the backward difference or Tustin, with the
filters after a sampled controller at its rate; :func:`loop_sampling` is the one place that
reads which loops are sampled.

Engines
-------
Two engines advance the same discrete loop: the compiled kernel
(:mod:`~cas_freq.simulation.kernel`, numba, parallel over runs; the default) and the numpy
reference (:class:`~cas_freq.simulation.engine.Engine`) it is tested against
(``tests/test_simulation_kernel.py``: the same trajectories to 1e-9 of the command). Choose with
``engine=`` or the environment variable ``CAS_FREQ_ENGINE=compiled|reference``; without numba
the reference runs, with a warning.

Time step
---------
The default step is the largest "round" step (1, 2, 2.5, 4, 5 x 10^k s, or that over n = 1..10)
of which both delays and the sampled controllers' periods are whole multiples, at most
``0.05 / omega_i`` with ``omega_i`` the current loop's crossover estimate (:func:`step_bound`)
and at most 20 us: 5 us for the shipped config (tau_c = 12 dt, tau_p = 80 dt, 25 kHz = 8 dt,
2.5 kHz = 80 dt). How it was established (``tests/test_simulation.py``: ``test_dt_convergence``,
and the study ``test_dt_convergence_study``, marked slow): for the 10 deg step of both shipped
variants, halving dt from 5 us to 2.5 us changes rise time, overshoot, peak time and the 2 % and
5 % settling times by at most 0.0004 % (the requirement is 0.5 %), and the changes shrink
fourfold per halving from 20 us down to 1.25 us (second order: exact plant, first-order-hold
delay lines with jumps kept on the grid, trapezoidal controllers, clamp instants located within
the step). At 5 us the 0.05 deg step matches the linear Padé-8 model to 1e-5 of the step (RMS).

Horizon
-------
Commands that settle (steps, ramps that stop, tables) run for ``t_end`` (default 0.1 s after the
command's last change). A run has settled when its fin angle stays within ±2 % of the command's
largest magnitude around the final command over the last half of the horizon (and after the
command's last change). If some run has not, the horizon doubles, continuing from where it
stopped, up to ``max_t_end`` (default 10 * t_end); the result says whether it was extended and
which runs settled.

Work budget
-----------
Before a batch starts, :func:`check_budget` estimates its work from the parameters (steps of
the first horizon, steps x runs, memory of the recorded signals, the delay lines and the step
indices) and refuses a batch beyond :data:`MAX_STEPS` steps, :data:`MAX_STEP_RUNS` steps x runs
or :data:`MAX_MEMORY_BYTES`, with the numbers in the message (a time constant far below the
step, a 1e-3 rad/s sine dwell, ...). The horizon's extension stops at the budget as it stops at
its 10 x cap (the run is then reported as not settled). The environment variable
``CAS_FREQ_BUDGET=N`` multiplies the three budgets by N.
"""

import dataclasses
import math
import os
import warnings

import numpy as np

from cas_freq.core.exceptions import ConfigError, ModelError
from cas_freq.core.filters_config import COMMAND_POINT
from cas_freq.core.jit import ENGINE_ENV, ENGINES, engine_name, use_compiled  # noqa: F401 (re-exported)
from cas_freq.core.parameters import LoopParameters
from cas_freq.core.threads import result_of, worker_threads
from cas_freq.model.structure import build
from cas_freq.simulation.architecture import LOOPS
from cas_freq.simulation.commands import Step
from cas_freq.simulation.controllers import METHODS
from cas_freq.simulation.engine import (
    LOAD_SIGNALS,
    SIGNALS,
    CommandSet,
    Engine,
)
from cas_freq.simulation.figure_kernel import settled_runs, step_figures_batch
from cas_freq.simulation.recording import Recording, RecordingBuffers  # noqa: F401 (re-exported)
from cas_freq.simulation.second_order import fit_second_order
from cas_freq.simulation.shaping import ShapedCommands

#: Largest default step [s].
MAX_DEFAULT_STEP_S = 20e-6
#: Default step bound relative to the current loop's speed: dt <= this / omega_i.
STEP_PER_CURRENT_LOOP = 0.05
#: Default simulated time after a settling command's last change [s].
DEFAULT_HORIZON_S = 0.1
#: Settling band used for the horizon, relative to the command's largest magnitude.
SETTLE_BAND = 0.02

#: Budget of one batch: steps of its horizon (10 s simulated at 5 us; about a minute for
#: one run).
MAX_STEPS = 2_000_000
#: Budget of one batch: steps x runs (about two minutes at the engine's 1.5e6 to 2e6 step-runs
#: per second on large batches).
MAX_STEP_RUNS = 200_000_000
#: Budget of one batch: estimated memory [bytes] (2 GiB).
MAX_MEMORY_BYTES = 2 * 2**30
#: Environment variable: a factor (> 0) on the three budgets.
BUDGET_ENV = "CAS_FREQ_BUDGET"
#: Estimated bytes per recorded sample and run (7 float and 2 bool signals, held up to about
#: three times while a horizon is assembled and transposed).
_BYTES_PER_SAMPLE = 200
#: Bytes per step of the step indices of one advance (int64 index and bool mask).
_BYTES_PER_STEP = 9
#: Bytes per delay-line slot and run (two lines, left and right buffers of float64).
_BYTES_PER_SLOT = 32


@dataclasses.dataclass(frozen=True, eq=False)
class _Signals:
    """The fields a run and a batch share (see :class:`SimulationResult`)."""

    t: np.ndarray
    delta: np.ndarray
    theta: np.ndarray
    omega: np.ndarray
    i: np.ndarray
    V: np.ndarray
    command: np.ndarray
    current_command: np.ndarray
    position_integral: np.ndarray
    current_limited: np.ndarray
    voltage_limited: np.ndarray
    dt_s: float
    t_end_s: float
    extended: bool
    settled: object
    current_rate_hz: float | None
    position_rate_hz: float | None
    omega_L: np.ndarray | None = None
    velocity_rate_hz: float | None = None
    sampling_method: str | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class SimulationResult(_Signals):
    """One run: every signal sampled at ``t``.

    Attributes
    ----------
    t : numpy.ndarray
        Sample times [s].
    delta, theta : numpy.ndarray
        Fin angle [rad] and motor angle [rad] (theta = N * delta for a rigid gear; a
        compliant gear's fin angle is its own state, docs/model.md "Load and drivetrain").
    omega, i : numpy.ndarray
        Motor speed [rad/s] and current [A].
    V : numpy.ndarray
        Voltage at the motor terminals (the current controller's output delayed by tau_c) [V].
    command : numpy.ndarray
        Fin-angle command [rad], as given (before any filter at ``position_command``).
    current_command : numpy.ndarray
        Current command at the current controller (delayed by tau_p) [A].
    position_integral : numpy.ndarray
        Integral term Ki * int(e) of the position controller [A].
    current_limited, voltage_limited : numpy.ndarray of bool
        Where the position (current) controller's output was clamped to ±i_max (±v_max).
    dt_s : float
        Integration step [s].
    t_end_s : float
        Simulated horizon [s].
    extended : bool
        True if the horizon was extended because some run had not settled.
    settled : bool or None
        Whether this run settled (None for commands that do not settle, e.g. a sine).
    current_rate_hz, position_rate_hz : float or None
        Rates of sampled controllers; None for continuous ones.
    omega_L : numpy.ndarray or None
        Fin rate [rad/s] where some run of the batch is loaded (omega / N for a rigid gear),
        else None.
    velocity_rate_hz : float or None
        Rate of a sampled velocity controller; None for a continuous one (or none).
    sampling_method : str or None
        The sampled controllers' discretisation ("backward", "tustin"); None if every
        controller is continuous.
    """


_ARRAYS = tuple(f.name for f in dataclasses.fields(_Signals))[1:11]


@dataclasses.dataclass(frozen=True, eq=False)
class BatchResult(_Signals):
    """Every run of a batch: the fields of :class:`SimulationResult`, each signal of shape
    (n_runs, n_samples) and ``settled`` a bool array (n_runs,) or None; :meth:`run` gives one
    run.

    ``t_end_runs`` (n_runs,) [s], for settling commands, is the horizon each run would have had
    alone: the first horizon of the doubling sequence at which it had settled (or the last).
    :meth:`run` cuts the run there, so a run's figures do not depend on the other runs of the
    batch. ``first_t_end_s`` is the first horizon of that sequence [s].
    """

    t_end_runs: np.ndarray | None = None
    first_t_end_s: float | None = None

    def __len__(self):
        return self.delta.shape[0]

    def sizes(self):
        """Samples of each run cut at its own horizon (:meth:`run`), shape (n_runs,)."""
        if self.t_end_runs is None:
            return np.full(len(self), self.t.size)
        return np.searchsorted(self.t, self.t_end_runs + 0.5 * self.dt_s, side="right")

    def run(self, index):
        """Run ``index`` as a :class:`SimulationResult`."""
        t, t_end, extended = self.t, self.t_end_s, self.extended
        keep = slice(None)
        if self.t_end_runs is not None:
            t_end = float(self.t_end_runs[index])
            keep = slice(0, int(np.searchsorted(t, t_end + 0.5 * self.dt_s, side="right")))
            t = t[keep]
            extended = t_end > self.first_t_end_s * (1 + 1e-12)
        fields = {name: None if getattr(self, name) is None else getattr(self, name)[index][keep]
                  for name in _ARRAYS}
        settled = None if self.settled is None else bool(self.settled[index])
        omega_l = None if self.omega_L is None else self.omega_L[index][keep]
        return SimulationResult(
            t=t, **fields, dt_s=self.dt_s, t_end_s=t_end, extended=extended,
            settled=settled, current_rate_hz=self.current_rate_hz,
            position_rate_hz=self.position_rate_hz, omega_L=omega_l,
            velocity_rate_hz=self.velocity_rate_hz, sampling_method=self.sampling_method,
        )


def budget_factor():
    """The factor on the work budget: ``$CAS_FREQ_BUDGET`` (default 1)."""
    text = os.environ.get(BUDGET_ENV, "").strip()
    if not text:
        return 1.0
    try:
        factor = float(text)
    except ValueError:
        factor = math.nan
    if not (math.isfinite(factor) and factor > 0):
        raise ConfigError(f"{BUDGET_ENV}: expected a number > 0 (a factor on the simulation "
                          f"budget), got {text!r}")
    return factor


def memory_estimate(n_runs, steps, record_every=1, max_delay_s=0.0, dt=1.0):
    """Estimated peak memory [bytes] of a batch of ``n_runs`` over ``steps`` steps."""
    samples = steps // record_every + 1
    slots = int(max_delay_s / dt) + 3 if max_delay_s > 0 else 3
    return (_BYTES_PER_SAMPLE * samples * n_runs + _BYTES_PER_STEP * steps
            + _BYTES_PER_SLOT * slots * n_runs)


def _gib(value):
    return f"{value / 2**30:.3g} GiB"


class BudgetError(ConfigError):
    """A batch beyond the work budget (:func:`check_budget`); a :class:`ConfigError`.

    Attributes
    ----------
    horizon_s : float
        The batch's first horizon [s].
    factor_needed : float
        The least ``CAS_FREQ_BUDGET`` that admits the batch.
    """

    def __init__(self, message, horizon_s, factor_needed):
        super().__init__(message)
        self.horizon_s = horizon_s
        self.factor_needed = factor_needed


def check_budget(n_runs, steps, dt, record_every=1, max_delay_s=0.0):
    """Refuse a batch whose estimated work exceeds the budget (module notes).

    Raises
    ------
    BudgetError
        Naming the steps, the step, the horizon, the runs, the memory estimate and the budget.
    """
    factor = budget_factor()
    memory = memory_estimate(n_runs, steps, record_every, max_delay_s, dt)
    needed = max(steps / MAX_STEPS, steps * n_runs / MAX_STEP_RUNS, memory / MAX_MEMORY_BYTES)
    if needed <= factor:
        return
    raise BudgetError(
        f"simulation too large: {steps:.3g} steps of {dt:.3g} s (horizon {steps * dt:.3g} s) x "
        f"{n_runs} run(s) = {steps * n_runs:.3g} step-runs, about {_gib(memory)}; the budget "
        f"is {MAX_STEPS * factor:.3g} steps, {MAX_STEP_RUNS * factor:.3g} step-runs and "
        f"{_gib(MAX_MEMORY_BYTES * factor)} (set {BUDGET_ENV}=N for N times more)",
        steps * dt, needed,
    )


def budget_steps(n_runs, dt, record_every=1, max_delay_s=0.0):
    """The most steps a batch may run within the budget (the cap of an extended horizon)."""
    factor = budget_factor()
    fixed = memory_estimate(n_runs, 0, 1, max_delay_s, dt) - _BYTES_PER_SAMPLE * n_runs
    per_step = _BYTES_PER_SAMPLE * n_runs / record_every + _BYTES_PER_STEP
    by_memory = (MAX_MEMORY_BYTES * factor - fixed) / per_step - 1
    return int(max(0.0, min(MAX_STEPS * factor, MAX_STEP_RUNS * factor / n_runs, by_memory)))


def budget_runs(steps, dt, record_every=1, max_delay_s=0.0):
    """The most runs a batch of ``steps`` steps may hold within the budget (at least 0)."""
    factor = budget_factor()
    per_run = memory_estimate(1, steps, record_every, max_delay_s, dt) - _BYTES_PER_STEP * steps
    by_memory = (MAX_MEMORY_BYTES * factor - _BYTES_PER_STEP * steps) / per_run
    return int(max(0.0, min(MAX_STEP_RUNS * factor / max(steps, 1), by_memory)))


def engine_class(requested=None):
    """The engine class for ``requested`` (:func:`engine_name`), with its fallback.

    The compiled engine needs numba; where numba does not import, the reference engine runs
    instead, with a warning saying so (the same trajectories, about 50 times slower).
    """
    if engine_name(requested) == "reference":
        return Engine
    try:
        from cas_freq.simulation.compiled import CompiledEngine
    except ImportError as exc:
        warnings.warn(f"simulation: the compiled engine is unavailable ({exc}); running the "
                      f"numpy reference engine instead (set {ENGINE_ENV}=reference to choose "
                      "it)", stacklevel=3)
        return Engine
    return CompiledEngine


def _whole(x, dt):
    return abs(x / dt - round(x / dt)) <= 1e-6


def _nice_floor(x):
    """Largest 1, 2, 2.5, 4 or 5 times a power of ten that is <= x."""
    k = math.floor(math.log10(x))
    values = [m / 10.0**-k if k < 0 else m * 10.0**k for m in (1.0, 2.0, 2.5, 4.0, 5.0)]
    return max(v for v in values if v <= x * (1 + 1e-12))


def step_bound(params):
    """Largest default step for a batch [s]: 0.05 / omega_i, at most 20 us.

    ``omega_i = max(ci_Kp / L, sqrt(ci_Ki / L))`` estimates the current loop's crossover, the
    fastest closed dynamics (8680 rad/s for the shipped config: bound 5.76 us). The plant is
    integrated exactly at any step; the bound keeps the controllers' updates fine against the
    loop they close.
    """
    omega = np.max(np.maximum(params.ci_Kp / params.L, np.sqrt(params.ci_Ki / params.L)))
    return min(MAX_DEFAULT_STEP_S, STEP_PER_CURRENT_LOOP / omega) if omega > 0 else (
        MAX_DEFAULT_STEP_S
    )


def loop_time_step(p, periods_s=()):
    """The default time step of runs ``p``: :func:`default_time_step` of every loop's delay and
    the controllers' periods (``periods_s`` and those the runs declare, :func:`loop_sampling`),
    at most :func:`step_bound`."""
    declared = [1.0 / rate for rate in loop_sampling(p)[0].values() if rate]
    return default_time_step([*p.tau_c, *p.tau_p, *p.tau_v], [*periods_s, *declared],
                             step_bound(p))


def loop_sampling(params, current_rate_hz=None, position_rate_hz=None, velocity_rate_hz=None):
    """Which loops of the runs ``params`` are sampled, at which rates, and by which method.

    The one place the simulator reads this: the runs' declaration (the static fields
    ``sample_rates``, pairs of loop name and rate [Hz], and ``sampling_method`` of
    :class:`~cas_freq.core.parameters.LoopParameters`) where it declares some sampled loop, else
    the rates given (the callers' ``simulation.rates_hz``: current and position loops). Rates
    given beside a declaration must agree with it.

    Returns
    -------
    tuple
        {loop name: rate [Hz] or None (continuous)} for every loop of
        :data:`~cas_freq.simulation.architecture.LOOPS`, and the method ("backward" or
        "tustin").
    """
    declared = dict(getattr(params, "sample_rates", ()) or ())
    given = {"current_loop": current_rate_hz, "velocity_loop": velocity_rate_hz,
             "position_loop": position_rate_hz}
    given = {name: rate for name, rate in given.items() if rate is not None}
    if declared:
        differ = [name for name, rate in given.items() if declared.get(name) != rate]
        if differ:
            name = differ[0]
            raise ConfigError(f"{name}: a simulation rate of {given[name]!r} Hz against the "
                              f"sampling the runs declare ({declared.get(name)!r} Hz); give "
                              "the rates once")
    rates = declared or given
    unknown = sorted(set(rates) - set(LOOPS))
    if unknown:
        raise ConfigError(f"sample_rates: unknown loop {unknown[0]!r} (the loops: "
                          f"{', '.join(LOOPS)})")
    if rates.get("velocity_loop") is not None and not params.cascade:
        raise ConfigError(f"velocity_loop: a sample rate ({rates['velocity_loop']!r} Hz) for a "
                          "drive without a velocity loop (its loops: current_loop, "
                          "position_loop)")
    method = getattr(params, "sampling_method", None) or "backward"
    if method not in METHODS:
        raise ConfigError(f"sampling_method: expected one of {', '.join(METHODS)}, got "
                          f"{method!r}")
    return {name: rates.get(name) for name in LOOPS}, method


def default_time_step(delays_s, periods_s=(), max_step_s=5e-6):
    """Largest step <= ``max_step_s`` of which every delay and period is a whole multiple.

    Candidates are ``s / n`` (n = 1..10) with ``s`` the largest 1, 2, 2.5, 4 or 5 times a power
    of ten not above ``max_step_s``.

    Parameters
    ----------
    delays_s, periods_s : iterable of float
        Transport delays and sampled-controller periods [s].
    max_step_s : float
        Largest acceptable step [s] (:func:`step_bound` in :func:`simulate_batch`).

    Returns
    -------
    float
        The step [s]; ``s`` if no candidate fits (delays are then interpolated).
    """
    if not (max_step_s > 0 and math.isfinite(max_step_s)):
        raise ModelError(f"simulation: no usable time step (bound {max_step_s!r} s; the current "
                         "loop is too fast for a numerical simulation)")
    top = _nice_floor(max_step_s)
    values = [float(v) for v in (*delays_s, *periods_s) if v > 0]
    for n in range(1, 11):
        dt = top / n
        if all(_whole(v, dt) for v in values):
            return dt
    return top


def _as_parameters(params):
    if not isinstance(params, LoopParameters):
        params = (LoopParameters.from_configs(params) if isinstance(params, (list, tuple))
                  else LoopParameters.from_config(params))
    return params


def _period_steps(rate_hz, dt, name):
    if rate_hz is None:
        return None
    if not rate_hz > 0:
        raise ConfigError(f"{name}: must be > 0 Hz, got {rate_hz!r}")
    if not _whole(1.0 / rate_hz, dt):
        raise ModelError(f"{name}: period 1/{rate_hz:g} Hz is not a whole number of dt = {dt:g} s")
    return int(round(1.0 / (rate_hz * dt)))


def _command_list(commands, n_runs):
    if isinstance(commands, (list, tuple)):
        if len(commands) != n_runs:
            raise ConfigError(f"commands: got {len(commands)} for {n_runs} runs")
        return list(commands)
    return None


def _settling_facts(commands, n_runs):
    """(settles, time of the last command change [s], final command per run [rad])."""
    listed = _command_list(commands, n_runs)
    items = listed if listed is not None else [commands]
    if not all(c.settles for c in items):
        return False, None, None
    end = max(getattr(c, "duration_s", None) or getattr(c, "stop_s", None)
              or getattr(c, "start_s", 0.0) for c in items)
    finals = [np.broadcast_to(c.final_rad(), (1,) if listed else (n_runs,)) for c in items]
    return True, float(end), np.concatenate(finals) if listed else finals[0]


def _kept_signals(names, asked):
    """The recorded signals of ``names``: those ``asked`` (None: all) and the output's."""
    if asked is None:
        return set(names)
    asked = set(asked)
    unknown = sorted(asked - set(SIGNALS))
    if unknown:
        raise ConfigError(f"signals: unknown signal {unknown[0]!r} (the signals: "
                          f"{', '.join(SIGNALS)})")
    return (asked | {"theta", "theta_cmd"} | set(LOAD_SIGNALS)) & set(names)


def _settled(t, delta, command, final, t_from, compiled=False):
    """Per run: delta within the band around ``final`` for every sample at t >= t_from.

    ``delta`` and ``command`` are (n_runs, n_samples) [rad], ``final`` (n_runs,) [rad];
    ``compiled``: by :func:`~cas_freq.simulation.figure_kernel.settled_runs` (the same
    verdicts, scanning each run back from its end), else in numpy.
    """
    if compiled:
        start = int(np.searchsorted(t, t_from, side="left"))
        return settled_runs(np.ascontiguousarray(delta, dtype=float),
                            np.ascontiguousarray(command, dtype=float),
                            np.ascontiguousarray(final, dtype=float), start, SETTLE_BAND)
    window = t >= t_from
    if not window.any():
        return np.zeros(delta.shape[0], dtype=bool)
    band = SETTLE_BAND * np.max(np.abs(command), axis=1)
    return np.all(np.abs(delta[:, window] - final[:, None]) <= band[:, None], axis=1)


def _advance(engine, recording, done, target, record_every, progress):
    """Advance the engine from step ``done`` to ``target``, reporting progress in pieces."""
    pieces = 50 if progress else 1
    size = max(1, -(-(target - done) // pieces))
    for start in range(done, target, size):
        stop = min(start + size, target)
        recording.advance(engine, stop - start, record_every)
        if progress:
            progress(stop, target)


def simulate_batch(
    params, commands, *, dt=None, t_end=None, max_t_end=None, extend=True,
    current_rate_hz=None, position_rate_hz=None, record_every=1, progress=None, engine=None,
    buffers=None, velocity_rate_hz=None, signals=None, stop_settled=False,
):
    """Simulate a batch of runs at once.

    Parameters
    ----------
    params : LoopParameters, ActuatorConfig or sequence of ActuatorConfig
        The runs' parameters (n_runs = their common length).
    commands : command or sequence of commands
        :mod:`~cas_freq.simulation.commands` objects: one whose parameters broadcast to
        (n_runs,), or one per run.
    dt : float, optional
        Step [s]; default :func:`default_time_step` of the delays and controller periods,
        at most :func:`step_bound` (5 us for the shipped config).
    t_end : float, optional
        Horizon [s]; default 0.1 s after a settling command's last change, the sweep's end for
        a chirp. Required for commands without an end (sine, endless ramp).
    max_t_end : float, optional
        Cap of the extended horizon [s]; default 10 * t_end.
    extend : bool
        Extend the horizon of settling commands until every run has settled (or the cap).
    current_rate_hz, position_rate_hz : float, optional
        Sample rates of sampled controllers (e.g. 25e3 and 2.5e3) [Hz]; continuous if None.
        Runs that declare their sampling (``sample_rates``) take it from there
        (:func:`loop_sampling`).
    record_every : int
        Keep every n-th step's sample (memory: 10 float arrays of n_runs x n_samples).
    progress : callable, optional
        Called as ``progress(steps_done, steps_planned)`` about 50 times per horizon (the plan
        grows when the horizon is extended).
    engine : {"compiled", "reference"}, optional
        The compiled kernel (:mod:`~cas_freq.simulation.kernel`, numba) or the numpy reference
        (:class:`~cas_freq.simulation.engine.Engine`); the same trajectories to 1e-9 of the
        command. Default ``$CAS_FREQ_ENGINE``, else compiled when numba imports
        (:func:`engine_class`).
    buffers : RecordingBuffers, optional
        Memory kept between batches to record into (a study's chunks); the result's signals
        are then views into it, valid until the next batch recorded into it.
    velocity_rate_hz : float, optional
        Sample rate of a sampled velocity controller [Hz] (a cascade); continuous if None.
    signals : iterable of str, optional
        The signals to record, names of :data:`~cas_freq.simulation.engine.SIGNALS`
        (``theta``, ``omega``, ``i``, ``V``, ``theta_cmd``, ``current_command``,
        ``position_integral``, ``current_limited``, ``voltage_limited``); the result's other
        signals are None. ``theta`` and ``theta_cmd`` (the output and its command) are always
        recorded. Default: every signal. Recording costs about 40 % of the compiled kernel's
        time when every signal is kept.
    stop_settled : bool
        Stop each run of a settling command at the first horizon at which it has settled
        (its ``t_end_runs``, where it would have stopped alone) while the batch goes on for the
        others; its samples after that are NaN (the flags False). :meth:`BatchResult.run` and
        everything computed from it are unchanged; the batch saves the steps of the runs that
        settled before its slowest, and their ``settled`` is True.

    Returns
    -------
    BatchResult
    """
    p = _as_parameters(params)
    n = p.n_runs
    rates, method = loop_sampling(p, current_rate_hz, position_rate_hz, velocity_rate_hz)
    if dt is None:
        dt = loop_time_step(p, [1.0 / rate for rate in rates.values() if rate])
    if not (isinstance(dt, (int, float)) and dt > 0 and math.isfinite(dt)):
        raise ConfigError(f"dt: must be a finite time > 0 s, got {dt!r}")
    if not (isinstance(record_every, int) and record_every >= 1):
        raise ConfigError(f"record_every: must be an integer >= 1, got {record_every!r}")
    every = {name: _period_steps(rate, dt, f"{name} rate ({name.split('_')[0]}_rate_hz)")
             for name, rate in rates.items()}
    sampled = any(every.values())
    _command_list(commands, n)
    settles, last_change, final = _settling_facts(commands, n)
    if t_end is None:
        duration = getattr(commands, "duration_s", None) if not settles else None
        if settles:
            t_end = last_change + DEFAULT_HORIZON_S
        elif duration is not None:
            t_end = getattr(commands, "start_s", 0.0) + duration
        else:
            raise ConfigError("t_end: required for a command that does not end (sine, ramp)")
    if not t_end > 0:
        raise ConfigError(f"t_end: must be > 0 s, got {t_end!r}")
    if not math.isfinite(t_end):
        raise ConfigError(f"t_end: must be finite, got {t_end!r}")
    cap = 10.0 * t_end if max_t_end is None else max(max_t_end, t_end)
    max_delay = float(max(np.max(p.tau_c), np.max(p.tau_p), np.max(p.tau_v), 0.0))
    check_budget(n, int(round(t_end / dt)), dt, record_every, max_delay)
    cap = min(cap, max(t_end, budget_steps(n, dt, record_every, max_delay) * dt))

    given = command_set = CommandSet(commands, p.ratio)
    shaped = any(item.at == COMMAND_POINT for item in p.filters)
    if shaped:  # the loops read the command through the filters before every loop
        structure = build(p)
        command_set = ShapedCommands(given, structure.command, dt,
                                     every.get(structure.loops[-1].name), method)
    engine = engine_class(engine)(p, command_set, dt, every, method)
    names = engine.signals  # SIGNALS, and LOAD_SIGNALS where some run is loaded
    kept = _kept_signals(names, signals)
    engine.record_only(kept)
    first = dict(zip(names, engine.start(), strict=True))
    # every signal (n_runs, n_samples): the engines record run by run
    columns = [1 + int(round(end / dt)) // record_every + 1 for end in (t_end, cap)]
    # where the horizon can extend, the buffers are sized for its cap from the start: the
    # operating system maps their pages as they are first written (the cap is within the
    # memory budget), so the unused columns cost nothing and no extension copies the samples
    recording = Recording(names, n, columns[1] if extend and settles else columns[0], buffers,
                          limit=columns[1])
    recording.append([0.0], {name: value[:, None] for name, value in first.items()})
    steps_done, horizon = 0, t_end
    extended = False
    run_end = np.full(n, np.nan)
    stopped = np.zeros(n, dtype=bool)
    while True:
        target = int(round(horizon / dt))
        previous = recording.size  # the stopped runs' samples end before this column
        _advance(engine, recording, steps_done, target, record_every, progress)
        recording.blank(stopped, previous, kept)
        steps_done = target
        t, signals = recording.signals()
        ratio = p.ratio[:, None]
        delta = signals["theta"] / ratio
        omega_l = None
        if "delta" in signals:  # a compliant gear's fin angle is a state of its own
            compliant = np.asarray(p.compliant, dtype=bool)[:, None]
            delta = np.where(compliant, signals["delta"], delta)
            omega_l = np.where(compliant, signals["omega_L"], signals["omega"] / ratio)
        command = signals["theta_cmd"] / ratio
        if shaped:  # the command as given, not as the filters before the loops shaped it
            command = np.broadcast_to(given.fin(t)[0].T, delta.shape)
        settled = None
        if settles:
            settled = _settled(t, delta, command, final, max(0.5 * horizon, last_change),
                               compiled=not isinstance(engine, Engine)) | stopped
            newly = settled & np.isnan(run_end)
            run_end[newly] = steps_done * dt
            if stop_settled:
                engine.stop(newly)
                stopped |= newly
        if not (extend and settles) or settled.all() or horizon >= cap * (1 - 1e-12):
            break
        horizon = min(2.0 * horizon, cap)
        extended = True
    signals = {name: signals[name] if name in kept else None for name in names}
    return BatchResult(
        t=t, delta=delta, theta=signals["theta"], omega=signals["omega"], i=signals["i"],
        V=signals["V"], command=command, current_command=signals["current_command"],
        position_integral=signals["position_integral"],
        current_limited=signals["current_limited"], voltage_limited=signals["voltage_limited"],
        dt_s=float(dt), t_end_s=float(steps_done * dt), extended=extended, settled=settled,
        current_rate_hz=rates["current_loop"], position_rate_hz=rates["position_loop"],
        t_end_runs=np.where(np.isnan(run_end), steps_done * dt, run_end) if settles else None,
        first_t_end_s=float(int(round(t_end / dt)) * dt), omega_L=omega_l,
        velocity_rate_hz=rates["velocity_loop"], sampling_method=method if sampled else None,
    )


def simulate(params, command, **options):
    """Simulate one run; see :func:`simulate_batch` for the options.

    Parameters
    ----------
    params : ActuatorConfig or LoopParameters
        One actuator (LoopParameters with n_runs = 1).
    command : command object
        A :mod:`~cas_freq.simulation.commands` object with scalar parameters.

    Returns
    -------
    SimulationResult
    """
    p = _as_parameters(params)
    if p.n_runs != 1:
        raise ConfigError(f"simulate: one run expected, got {p.n_runs}; use simulate_batch")
    return simulate_batch(p, command, **options).run(0)


def prepare_kernels(params):
    """Have the compiled simulation kernels in this process: batches of ``params`` (an
    ActuatorConfig) without a load and with a load spring, of one run and of two (the serial
    and the parallel kernel), a few steps each, a step fit and the step figures of a batch
    (the kernels' signatures of steps, figures and fits); nothing with the reference engine.
    The simulation kernels take the architecture, the sampling and the load as data
    (:mod:`cas_freq.simulation.kernel`), so any one config prepares them for every other.

    For a process about to fork workers that simulate (``cas-freq report``'s load envelope):
    on a first run (no kernel in numba's cache) the report's process and the worker compiled
    the same kernels at once, ~25 s of CPU each (the first report took 74 s against ~15 s
    warm); compiled here once, the forked workers inherit them. In later runs this
    loads them from the cache (~0.4 s), as the process would anyway.

    The work runs in a new thread, waited for before this returns, except after an interrupt
    (Ctrl-C), raised at once (:func:`cas_freq.core.threads.worker_threads`,
    :func:`cas_freq.core.threads.result_of`). numba's compiler recurses deeply, and where the caller
    is itself deep in a call stack (pytest, a notebook) CPython 3.11 can keep crossing a
    boundary of its frame-stack chunks, mapping and unmapping one at every crossing: compiling
    for one test took 22.8 s of user and 15.6 s of system time there against 20.8 s and 1.7 s
    in a new thread, which starts a stack of its own (``strace -c``: 1.2 million mmap/munmap
    calls).
    """
    if not use_compiled():
        return
    with worker_threads(1, "cas_freq-prepare-kernels") as thread:
        result_of(thread.submit(_prepare_kernels, params))  # its failure raised again here


def _prepare_kernels(params):
    """The work of :func:`prepare_kernels`, in its thread."""
    runs = LoopParameters.from_configs([params]).take([0, 0])
    unloaded = dict(F_c=0.0, eta=1.0, eta_b=1.0, K_g=0.0, c_g=0.0, backlash=0.0, J_L=0.0,
                    b_L=0.0, K_h=0.0, tau_h=0.0)  # LoopParameters.loaded is then False
    # a batch without a load and one with (the same simulation kernels; the loaded batch's
    # recordings hold the fin's rows for the figure kernels)
    for load in (unloaded, {"K_h": 1.0}):
        batch = dataclasses.replace(runs, **{key: np.full(2, value) for key, value in load.items()})
        for runs_of_batch in (batch.take([0]), batch):  # the serial and the parallel kernel
            simulate_batch(runs_of_batch, Step(1e-3), t_end=1e-4, extend=False)
    t = np.linspace(0.0, 0.1, 101)
    fit_second_order(t, 1.0 - np.exp(-50.0 * t), 1.0)
    # the step figures of a batch (studies.steps.chunk_step_figures): its recorded signals
    # are the whole buffers (C-contiguous) or views of their first columns

    y, flags = np.ones((2, t.size)), np.zeros((2, t.size), dtype=bool)
    sizes = np.full(2, t.size - 1)
    for cut in (slice(None), slice(0, t.size - 1)):
        step_figures_batch(t, y, sizes, 1.0, y[:, cut], y[:, cut], flags[:, cut], flags[:, cut])
