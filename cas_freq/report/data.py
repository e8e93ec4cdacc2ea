"""Everything a report shows about one variant, computed once (no matplotlib).

:func:`gather_variant` runs the frequency analysis (exact delays, with the Padé-vs-exact table),
evaluates the loops on a plotting grid, runs **one** sine-dwell batch (which also simulates the
nonlinear step of every amplitude, :func:`cas_freq.studies.run.sinedwell_run`), and the
linear step of the Padé model. :func:`variant_results` turns it into the JSON of
``results.json``: the same dicts as ``analyze --json``, ``simulate --json``,
``sinedwell --json`` and ``verify`` (the requirement verdicts).
"""

import dataclasses
import math
from pathlib import Path

import numpy as np

from cas_freq.analysis import analyze, to_dict
from cas_freq.analysis.frequency import frequency_grid
from cas_freq.analysis.systems import closed_loop_matrices, closed_loop_zeros
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.figures import FIGURES
from cas_freq.core.fileio import json_ready
from cas_freq.core.threads import one_blas_thread
from cas_freq.model import ActuatorLoops, parts
from cas_freq.model.loops import Selector
from cas_freq.model.sampled import drive_responses
from cas_freq.model.structure import build

# the sine-dwell grid rule, one for every command (re-exported)
from cas_freq.simulation.sinedwell import (  # noqa: F401
    DWELL_POINTS,
    DWELL_SPAN,
    bandwidth_text,
    dwell_frequencies,
)
from cas_freq.simulation.step_figures import step_figures
from cas_freq.studies.run import sinedwell_run, sinedwell_run_dict, step_run_dict
from cas_freq.verify import verdict_dict, verify_variant

#: Default sine-dwell amplitudes at the output [deg]: small signal (no limit acts), two
#: intermediate sizes, and a 10 deg step (ARL-TR-9136's bench step). The smallest and the
#: largest are also the step responses the report shows.
DEFAULT_AMPLITUDES_DEG = (0.5, 2.0, 5.0, 10.0)

#: Padé order of the linear step response and of the Padé-vs-exact table.
DEFAULT_PADE_ORDER = 10


@dataclasses.dataclass(frozen=True)
class ReportSettings:
    """What a report computes.

    Attributes
    ----------
    amplitudes_rad : tuple of float
        Sine-dwell and step amplitudes at the output [rad], >= 1 value; the smallest and the
        largest are the step responses shown.
    frequencies_rad_s : tuple of float or None
        Sine-dwell frequencies [rad/s]; None (default): per variant from its loops
        (:func:`dwell_frequencies`, 0.1..5 × the linear ω_BW).
    pade_order : int
        Padé order of the linear step and the highest order of the Padé-vs-exact table.
    curve_range_rad_s : (float, float) or None
        Range of the Bode, Nichols and closed-loop plots [rad/s]; None (default): from each
        variant's loops (:func:`loop_frequency_range`), so that every crossover and peak the
        tables report is drawn.
    curve_points_per_decade : int
        Density of the plotting grid [1/decade] (densified where the delays turn the phase).
    """

    amplitudes_rad: tuple = tuple(math.radians(a) for a in DEFAULT_AMPLITUDES_DEG)
    frequencies_rad_s: tuple | None = None
    pade_order: int = DEFAULT_PADE_ORDER
    curve_range_rad_s: tuple | None = None
    curve_points_per_decade: int = 100

    def __post_init__(self):
        amplitudes = tuple(sorted({float(a) for a in self.amplitudes_rad}))
        if not amplitudes or not all(0 < a <= math.pi / 2 for a in amplitudes):
            raise CasFreqError(
                f"report amplitudes: need at least one amplitude in (0, 90] deg, got "
                f"{[math.degrees(a) for a in self.amplitudes_rad]} deg"
            )
        object.__setattr__(self, "amplitudes_rad", amplitudes)
        if self.frequencies_rad_s is None:
            return
        frequencies = tuple(sorted({float(w) for w in self.frequencies_rad_s}))
        if len(frequencies) < 2 or not all(0 < w < math.inf for w in frequencies):
            raise CasFreqError(
                f"report frequencies: need at least two finite frequencies > 0 rad/s, got "
                f"{list(self.frequencies_rad_s)}"
            )
        object.__setattr__(self, "frequencies_rad_s", frequencies)

    @property
    def frequencies_text(self):
        """The sine-dwell grid as the report states it."""
        w = self.frequencies_rad_s
        if w is None:
            return (f"{DWELL_POINTS} log-spaced points over {DWELL_SPAN[0]:g}..{DWELL_SPAN[1]:g} "
                    "× each variant's linear ω_BW")
        return f"{len(w)} points over {w[0]:.4g}..{w[-1]:.4g} rad/s"

    def to_dict(self):
        """JSON-ready description (amplitudes in deg, as everywhere on output)."""
        return json_ready({
            "amplitudes_deg": [math.degrees(a) for a in self.amplitudes_rad],
            "sinedwell_frequencies_rad_s": (None if self.frequencies_rad_s is None
                                            else list(self.frequencies_rad_s)),
            "pade_order": self.pade_order,
            "curve_range_rad_s": (None if self.curve_range_rad_s is None
                                  else list(self.curve_range_rad_s)),
            "curve_points_per_decade": self.curve_points_per_decade,
            "delay_model": "exact delays for every frequency response; Padé order "
            f"{self.pade_order} for the linear step response",
        })


@dataclasses.dataclass(frozen=True)
class CurveLoop:
    """One loop of the structure as the figures name it: the names of its
    :class:`cas_freq.model.structure.Loop` (which declares them), without its blocks.

    Attributes
    ----------
    name : str
        Its figures' prefix (``"velocity_loop"``).
    symbol : str
        ``"L_v"``.
    words : str
        ``"velocity loop"``.
    breaks_at : str
        Where it is broken, in words (``"the current command"``).
    break_symbol : str
        The same in a word (``"i_cmd"``).
    """

    name: str
    symbol: str
    words: str
    breaks_at: str
    break_symbol: str

    @classmethod
    def of(cls, loop):
        """The names of a :class:`cas_freq.model.structure.Loop`."""
        return cls(loop.name, loop.symbol, loop.label, loop.breaks_at, loop.break_symbol)

    @property
    def title(self):
        """``"L_v (velocity loop, broken at i_cmd)"``."""
        return f"{self.symbol} ({self.words}, broken at {self.break_symbol})"

    @property
    def break_point(self):
        """``"velocity loop, broken at the current command"``."""
        return f"{self.words}, broken at {self.breaks_at}"


@dataclasses.dataclass(frozen=True, eq=False)
class Curves:
    """Exact-delay frequency responses on a plotting grid (complex, shape (n,)).

    Attributes
    ----------
    omega_rad_s : numpy.ndarray
        The grid [rad/s].
    loops : dict of str to numpy.ndarray
        Every loop of the structure by name, innermost first, broken at its controller's
        output with the loops inside closed and those outside open.
    loop_at_a_time : dict of str to numpy.ndarray
        The inner loops with every other loop closed, where that differs from ``loops`` (the
        outermost's is its own response, not repeated).
    sensitivity, closed_loop : numpy.ndarray
        S = 1/(1 + L_p) and T.
    described : tuple of CurveLoop
        The loops' names, symbols and break points, innermost first (the structure's).
    """

    omega_rad_s: np.ndarray
    loops: dict
    loop_at_a_time: dict
    sensitivity: np.ndarray
    closed_loop: np.ndarray
    described: tuple

    @property
    def current_loop(self):
        """L_i [-]."""
        return self.loops["current_loop"]

    @property
    def position_loop(self):
        """L_p [-]."""
        return self.loops["position_loop"]

    def outermost_first(self):
        """The loops' :class:`CurveLoop`, outermost first."""
        return tuple(reversed(self.described))


def described_loops(params):
    """The :class:`CurveLoop` of every loop of ``params``' structure, innermost first."""
    return tuple(CurveLoop.of(loop) for loop in build(parts.one_variant(params)).loops)


@dataclasses.dataclass(frozen=True, eq=False)
class VariantData:
    """Everything the report shows about one variant.

    Attributes
    ----------
    loaded : cas_freq.config.LoadedVariant
    label : str
        ``config / variant`` as titles show it.
    analysis : cas_freq.analysis.Analysis
        Exact-delay figures, with the Padé-vs-exact table.
    curves : Curves
    dwell : cas_freq.studies.run.SineDwellRun or None
        Sine-dwell per amplitude and the nonlinear step of each amplitude (None in the
        frequency-domain part, :func:`gather_frequency`).
    linear_steps : tuple of numpy.ndarray
        Linear (Padé) output-angle step response [rad] on each step's time grid, same order as
        ``dwell.steps``.
    linear_step_figures : tuple of StepFigures
        Step figures of those linear responses.
    curve_range_rad_s : (float, float)
        Range of the frequency-response figures [rad/s].
    pade_order : int
        Padé order of the linear step responses and of the Padé-vs-exact table.
    verdicts : tuple of dict or None
        Requirement verdicts of this variant; None when they were not evaluated.
    closed_loop_zeros : numpy.ndarray or None
        Zeros of T [rad/s] with Padé delays of the stability verdict's order
        (:func:`cas_freq.analysis.systems.closed_loop_zeros`), computed with the time-domain part
        (None before it).
    """

    loaded: object
    label: str
    analysis: object
    curves: Curves
    dwell: object
    linear_steps: tuple
    linear_step_figures: tuple
    curve_range_rad_s: tuple
    pade_order: int
    verdicts: tuple | None
    closed_loop_zeros: np.ndarray | None = None

    @property
    def small_index(self):
        """Index of the smallest amplitude in ``dwell.steps``."""
        return 0

    @property
    def large_index(self):
        """Index of the largest amplitude in ``dwell.steps``."""
        return len(self.dwell.steps) - 1

    @property
    def reference(self):
        """The config's ``reference:`` section (measured or published results), or None."""
        return getattr(self.loaded.params, "reference", None)

    @property
    def reference_index(self):
        """Index in ``dwell.steps`` of the step compared with the reference step: the amplitude
        nearest (in ratio) the reference's ``step_amplitude``, else the largest."""
        reference = self.reference
        if reference is None or reference.step_amplitude is None:
            return self.large_index
        target = math.log(reference.step_amplitude)
        distances = [abs(math.log(math.radians(run.step.amplitude_deg)) - target)
                     for run in self.dwell.steps]
        return distances.index(min(distances))

    @property
    def requirements(self):
        """The config's requirements (empty if it has none)."""
        return tuple(getattr(self.loaded.params, "requirements", ()) or ())


def variant_label(loaded):
    """``config / variant`` (with the ``--set`` overrides, if any)."""
    label = f"{loaded.params.name} / {loaded.variant}"
    if loaded.overrides:
        label += " with " + ", ".join(f"{k}={v}" for k, v in loaded.overrides)
    return label


def curves(params, frequency_range_rad_s, points_per_decade):
    """Exact-delay responses of every loop (both views) and of T on a plotting grid.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
    frequency_range_rad_s : (float, float)
        [rad/s].
    points_per_decade : int
        [1/decade].

    Returns
    -------
    Curves
    """
    loops = ActuatorLoops(params)
    omega = frequency_grid(*frequency_range_rad_s, points_per_decade, loops.total_delay)
    found = drive_responses(Selector(loops.params)(), 1j * omega, loop_at_a_time=True)
    outermost = list(found.loops)[-1]
    with np.errstate(invalid="ignore"):  # NaN above a sampled loop's Nyquist frequency
        sensitivity = 1.0 / (1.0 + found.loops[outermost])
    # the inner loops with every other loop closed, where that differs from the cascade view
    # (it does not where the loops outside have no gain)
    return Curves(omega, dict(found.loops),
                  {name: values for name, values in found.loop_at_a_time.items()
                   if name != outermost
                   and not np.all(np.isnan(values))
                   and not np.allclose(values, found.loops[name], rtol=1e-12, atol=0.0,
                                       equal_nan=True)},
                  sensitivity, found.closed_loop,
                  described_loops(loops.params))


#: Plot range when a loop has no figure to centre on [rad/s].
FALLBACK_CURVE_RANGE_RAD_S = (1.0, 2.0e4)


def loop_frequency_range(analysis, margin=3.0):
    """Plot range [rad/s] that holds every headline frequency the report's tables give.

    The gain crossovers of every loop (both views), the headline phase crossovers (upper and
    lower gain margins), the sensitivity peaks and the closed-loop bandwidth, peak and −90°
    point, widened by ``margin`` on each side and rounded out to whole decades, within the
    analysed range.
    """
    frequencies = []
    loops = [analysis.current_loop, analysis.velocity_loop, analysis.position_loop]
    loops += [loop.loop_at_a_time for loop in loops[:2] if loop is not None]
    for loop in loops:
        if loop is None:
            continue
        frequencies += [loop.crossover_rad_s, loop.phase_crossover_rad_s,
                        loop.phase_crossover_low_rad_s, loop.sensitivity_peak_rad_s]
        frequencies += [c.frequency_rad_s for c in loop.gain_crossovers]
    cl = analysis.closed_loop
    if cl is not None:
        frequencies += [cl.bandwidth_rad_s, cl.peak_rad_s, cl.phase_90_rad_s]
    frequencies = [w for w in frequencies if w is not None and math.isfinite(w) and w > 0]
    if not frequencies:
        return FALLBACK_CURVE_RANGE_RAD_S
    low = 10.0 ** math.floor(math.log10(min(frequencies) / margin))
    high = 10.0 ** math.ceil(math.log10(max(frequencies) * margin))
    lowest, highest = analysis.frequency_range_rad_s
    return (max(low, lowest), min(high, highest))


def unit_step_response(system, n_steps, dt):
    r"""Output of a single-input single-output state-space system to a unit step from rest,
    at the times :math:`k\,\Delta t`, :math:`k = 0 \dots n-1`.

    The same discretisation as ``control.step_response`` on a uniform grid (the matrix
    exponential of :math:`[[A\Delta t, B\Delta t], [0, 0]]`, exact for a constant input), but
    the recursion :math:`x_{k+1} = A_d x_k + b_d` is evaluated by doubling instead of one Python
    step per sample: with :math:`x_0 = 0`, :math:`x_{m+k} = A_d^m x_k + x_m`, so the states of
    samples :math:`m \dots 2m-1` are one matrix product from those of :math:`0 \dots m-1`
    (:math:`\log_2 n` products). It agrees with python-control's loop to ~1e-13 of the step
    (round-off).

    Parameters
    ----------
    system : cas_freq.analysis.systems.ClosedLoopMatrices
        One input and one output (``a, b, c, d``); continuous-time (``period`` None), or
        discrete-time (sampled controllers: its output samples, each held until the next, on
        the grid).
    n_steps : int
        Number of samples (>= 1).
    dt : float
        Sample spacing [s].

    Returns
    -------
    numpy.ndarray
        Output, shape (n_steps,).
    """
    from scipy.linalg import expm

    a, b, c, d = (np.asarray(m, dtype=float) for m in (system.a, system.b, system.c, system.d))
    n = a.shape[0]
    if n == 0:
        return np.full(n_steps, float(d[0, 0]))
    if system.period is not None:  # sampled controllers: the output's samples, held
        period = float(system.period)
        count = int(np.floor((n_steps - 1) * dt / period + 1e-9)) + 1
        samples = _doubled(a, b[:, 0].copy(), c, d, count)
        return samples[np.floor(np.arange(n_steps) * dt / period + 1e-9).astype(int)]
    block = np.zeros((n + 1, n + 1))
    block[:n, :n], block[:n, n] = a * dt, b[:, 0] * dt
    with one_blas_thread():
        exponential = expm(block)
    return _doubled(exponential[:n, :n], exponential[:n, n].copy(), c, d, n_steps)


def _doubled(power, offset, c, d, n_steps):
    """y_k = C x_k + D of x_(k+1) = A x_k + b from x_0 = 0, k < n_steps, by doubling
    (``power`` = A, ``offset`` = b; see :func:`unit_step_response`)."""
    n = power.shape[0]
    states = np.zeros((n, n_steps))
    m = 1
    # an unstable loop's step overflows to inf and then NaN: that is its response (the report
    # marks a loop that is not stable), not an arithmetic error to warn about
    with np.errstate(over="ignore", invalid="ignore"):
        while m < n_steps:
            k = min(m, n_steps - m)
            states[:, m:m + k] = power @ states[:, :k] + offset[:, None]
            offset = power @ offset + offset
            power = power @ power
            m *= 2
        return (c[0] @ states) + d[0, 0]


def linear_steps(params, times, amplitudes_rad, pade_order, closed=None):
    """Output-angle step responses [rad] of the linear closed loop T with Padé delays.

    One Padé model and one response per variant: every step is the unit step response on the
    longest of the (uniform, from 0, same spacing) time grids, scaled and cut to its own grid;
    a grid that is not such a prefix gets its own response.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
    times : sequence of numpy.ndarray
        Each step's times [s], uniformly spaced from 0.
    amplitudes_rad : sequence of float
        Each step's size at the output [rad].
    pade_order : int
        Padé order of both delays.
    closed : cas_freq.analysis.systems.ClosedLoopMatrices, optional
        T of ``params`` at ``pade_order`` (:func:`~cas_freq.analysis.systems.closed_loop_matrices`)
        when already built.

    Returns
    -------
    list of numpy.ndarray
    """
    if closed is None:
        closed = closed_loop_matrices(params, pade_order)
    times = [np.asarray(t, dtype=float) for t in times]
    longest = max(times, key=len)
    cache = {}

    def unit(t):
        dt = float(t[1] - t[0]) if t.size > 1 else 1.0
        key = (t.size, dt)
        if key not in cache:
            cache[key] = unit_step_response(closed, t.size, dt)
        return cache[key]

    responses = []
    for t, amplitude in zip(times, amplitudes_rad, strict=True):
        prefix = t.size <= longest.size and np.array_equal(t, longest[:t.size])
        response = unit(longest)[:t.size] if prefix else unit(t)
        responses.append(amplitude * response)
    return responses


def requirement_verdicts(loaded, results):
    """Requirement verdicts of one variant (``cas-freq verify --json``), [] without requirements.

    The one seam between the report and :mod:`cas_freq.verify`: the verdict dicts have the keys
    ``id, variant, metric, value, unit, min, max, margin, status, severity, source, message``
    (and more). ``results`` holds what the report already computed with the same code: its
    :class:`~cas_freq.analysis.Analysis` and the step runs; verify reuses them (typed, not
    re-derived) and only runs what a requirement needs beyond them (another step size, a
    sine-dwell).
    """
    if not loaded.params.requirements:
        return []

    return [verdict_dict(verdict) for verdict in verify_variant(loaded, known=results)]


def select_verdicts(verdicts, loaded):
    """The verdicts of ``verdicts`` (list of dicts) that belong to ``loaded``'s variant."""
    chosen = []
    for verdict in verdicts:
        if verdict.get("variant", loaded.variant) != loaded.variant:
            continue
        if verdict.get("config", loaded.params.name) != loaded.params.name:
            continue
        chosen.append(dict(verdict))
    return tuple(chosen)


def gather_variant(loaded, settings=ReportSettings(), verdicts=None, progress=None):
    """Compute everything the report shows about one variant: :func:`gather_frequency` then
    :func:`gather_time`.

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant
    settings : ReportSettings
    verdicts : list of dict, optional
        Requirement verdicts (of any variants; those of this one are kept). None: evaluate them
        with :func:`requirement_verdicts`.
    progress : callable, optional
        ``progress(done, planned)`` of the sine-dwell batch.

    Returns
    -------
    VariantData
    """
    return gather_time(gather_frequency(loaded, settings), settings, verdicts, progress)


def gather_frequency(loaded, settings=ReportSettings()):
    """The frequency-domain part of a variant's data: the analysis (exact delays, with the
    Padé-vs-exact table) and the loops on the plotting grid; no simulation yet (``dwell`` None,
    no linear steps, ``verdicts`` None), which :func:`gather_time` adds. Enough for the figures
    drawn from the frequency responses alone, which can be drawn meanwhile."""
    analysis = analyze(loaded, pade_orders=settings.pade_order)
    curve_range = settings.curve_range_rad_s or loop_frequency_range(analysis)
    return VariantData(
        loaded=loaded, label=variant_label(loaded), analysis=analysis,
        curves=curves(loaded.params, curve_range, settings.curve_points_per_decade),
        dwell=None, linear_steps=(), linear_step_figures=(), curve_range_rad_s=tuple(curve_range),
        pade_order=settings.pade_order, verdicts=None,
    )


def gather_time(data, settings=ReportSettings(), verdicts=None, progress=None):
    """``data`` of :func:`gather_frequency` completed: **one** sine-dwell batch (with the
    nonlinear step of every amplitude), the linear steps, the requirement verdicts (parameters
    as :func:`gather_variant`)."""
    loaded, analysis = data.loaded, data.analysis
    # a sine-dwell beyond the simulation budget is refused before it starts and left out
    # (dwell.result None, dwell.not_computed the reason), as is the default one of a loop that
    # is not stable (no grid: no first harmonic to measure); the steps are still simulated
    dwell = sinedwell_run(loaded, settings.amplitudes_rad, settings.frequencies_rad_s,
                          progress=progress, analysis=analysis, over_budget="skip")
    amplitudes = [math.radians(run.step.amplitude_deg) for run in dwell.steps]
    # T with Padé delays, built once for the linear steps and the zeros when their orders agree
    closed = {order: closed_loop_matrices(loaded.params, order)
              for order in {settings.pade_order, analysis.stability.pade_order}}
    linear = linear_steps(loaded.params, [run.result.t for run in dwell.steps], amplitudes,
                          settings.pade_order, closed[settings.pade_order])
    linear_figures = [step_figures(run.result.t, response, amplitude)
                      for run, response, amplitude in zip(dwell.steps, linear, amplitudes,
                                                          strict=True)]
    if verdicts is None:
        computed = {"analyze": analysis, "steps": list(dwell.steps)}
        found = requirement_verdicts(loaded, computed)
        chosen = None if found is None else tuple(dict(v) for v in found)
    else:
        chosen = select_verdicts(verdicts, loaded)
    zeros = closed_loop_zeros(loaded.params, analysis.stability.pade_order,
                              closed[analysis.stability.pade_order])
    return dataclasses.replace(data, dwell=dwell, linear_steps=tuple(linear),
                               linear_step_figures=tuple(linear_figures), verdicts=chosen,
                               closed_loop_zeros=zeros)


def sinedwell_bandwidth(data, k):
    """Sine-dwell bandwidth [rad/s] of amplitude ``k``, or as text what is known instead: a
    bound from the grid ("> 5000" when no point is below −3.01 dB, "< 100" when the first one
    already is) or "not computed" (the sine-dwell was beyond the simulation budget)."""
    result = data.dwell.result
    if result is None:
        return "not computed"
    value = result.bandwidth_rad_s[k]
    if value is not None:
        return value
    return bandwidth_text(None, result.bandwidth_bounds[k])


#: The figures of a variant that need the sine-dwell (file stems of
#: :data:`cas_freq.plots.report.VARIANT_FIGURES`).
SINEDWELL_FIGURES = ("sinedwell",)


def not_computed(data):
    """What of a variant could not be computed, and why: {what: reason}, empty when
    everything was. ``"sinedwell"``: the sine-dwell (beyond the simulation budget); its figure
    (:data:`SINEDWELL_FIGURES`) is not drawn and its figures are "not computed"."""
    reason = None if data.dwell is None else data.dwell.not_computed
    return {} if reason is None else {"sinedwell": reason}


def not_computed_notice(data):
    """The one stderr line about what a variant lacks, or None: it names the variant, the
    figures and why."""
    missing = not_computed(data)
    if not missing:
        return None
    return (f"variant {data.loaded.variant}: sine-dwell (figure "
            f"{', '.join(SINEDWELL_FIGURES)}, sine-dwell bandwidths) not computed: "
            f"{missing['sinedwell']}")


def display_path(path):
    """``path`` relative to the working directory when inside it (so that a report does not
    carry the machine's absolute paths), else as given."""
    try:
        resolved, here = Path(path).resolve(), Path.cwd().resolve()
    except OSError:
        return str(path)
    if resolved.is_relative_to(here):
        return resolved.relative_to(here).as_posix()
    return str(path)


def _with_paths(value, shown):
    if isinstance(value, dict):
        return {k: (shown if k == "config_path" else _with_paths(v, shown))
                for k, v in value.items()}
    if isinstance(value, list):
        return [_with_paths(v, shown) for v in value]
    return value


def reference_rows(data):
    """The config's reference figures beside the model's, for the step nearest the reference
    step; [] when the config declares no ``reference:``.

    Returns
    -------
    list of (str, str, float or None, float or None)
        (figure, unit, reference value, model value) in display units (ms, %, rad/s, -); only
        the figures the reference declares, then the model's bandwidths at that amplitude.
    """
    reference = data.reference
    if reference is None:
        return []
    k = data.reference_index
    run = data.dwell.steps[k]
    step, fit = run.step, run.fit
    closed = data.analysis.closed_loop
    dwell_bw = sinedwell_bandwidth(data, k)
    ref_fit = reference.fit

    def of_fit(name):
        return None if ref_fit is None else getattr(ref_fit, name)

    # (figure, the label's prefix, the reference's value, the model's) [the JSON unit]
    declared = [
        ("step.rise_time_s", "", reference.rise_time, step.rise_time_s),
        ("step.overshoot_pct", "", reference.overshoot_pct, step.overshoot_pct),
        ("step.settling_time_s", "", reference.settling_time, step.settling_time_s),
        ("fit.wn_rad_s", "fit: ", of_fit("wn"), fit.wn_rad_s),
        ("fit.zeta", "fit: ", of_fit("zeta"), fit.zeta),
        ("fit.td_s", "fit: ", of_fit("td"), fit.td_s),
        ("fit.bandwidth_closed_form_rad_s", "fit: ", of_fit("bandwidth_rad_s"),
         fit.bandwidth_closed_form_rad_s),
    ]
    model_only = [
        ("sinedwell.bandwidth_rad_s", "sine-dwell at the step's amplitude: ", None, dwell_bw),
        ("closed_loop.bandwidth_rad_s", "linear T: ", None,
         None if closed is None else closed.bandwidth_rad_s),
    ]
    return [(prefix + FIGURES[key].label, FIGURES[key].shown_unit or "-",
             FIGURES[key].shown(value), FIGURES[key].shown(model))
            for key, prefix, value, model in declared if value is not None] + [
        (prefix + FIGURES[key].label, FIGURES[key].shown_unit, None, FIGURES[key].shown(model))
        for key, prefix, value, model in model_only]


def reference_dict(reference):
    """JSON of a config's ``reference:`` section in display units, or None."""
    if reference is None:
        return None
    fit = reference.fit

    def ms(value):
        return None if value is None else 1e3 * value

    return json_ready({
        "source": reference.source,
        "step_amplitude_deg": (None if reference.step_amplitude is None
                               else math.degrees(reference.step_amplitude)),
        "rise_time_ms": ms(reference.rise_time),
        "overshoot_pct": reference.overshoot_pct,
        "settling_time_ms": ms(reference.settling_time),
        "fit": None if fit is None else {
            "wn_rad_s": fit.wn, "zeta": fit.zeta, "td_ms": ms(fit.td),
            "bandwidth_rad_s": fit.bandwidth_rad_s,
        },
    })


def variant_results(data):
    """The variant's entry of ``results.json``.

    ``analyze``, ``simulate`` (smallest and largest step) and ``sinedwell`` are the JSON of
    those commands (``sinedwell`` null when it was not computed, with the reason under
    ``not_computed``, :func:`not_computed`); ``linear_steps`` the step figures of the Padé
    model; ``verify`` the requirement verdicts (None: not evaluated);
    ``reference_comparison`` the table beside the config's ``reference:`` figures (only when it
    declares one).
    """
    import dataclasses as dc

    shown = display_path(data.loaded.source)
    steps = data.dwell.steps
    chosen = sorted({data.small_index, data.large_index})
    result = {
        "variant": data.loaded.variant,
        "label": data.label,
        "curve_range_rad_s": list(data.curve_range_rad_s),
        "analyze": to_dict(data.analysis),
        "simulate": [step_run_dict(steps[k]) for k in chosen],
        # null when not computed; "not_computed" then says why
        "sinedwell": None if data.dwell.result is None else sinedwell_run_dict(data.dwell),
        "linear_steps": [
            {"pade_order": data.pade_order, **dc.asdict(figures)}
            for figures in data.linear_step_figures
        ],
        "verify": None if data.verdicts is None else [dict(v) for v in data.verdicts],
    }
    missing = not_computed(data)
    if missing:
        result["not_computed"] = missing
    if data.reference is not None:
        result["reference_comparison"] = [
            {"figure": name, "unit": unit, "reference": value, "model": model}
            for name, unit, value, model in reference_rows(data)
        ]
    return json_ready(_with_paths(result, shown))
