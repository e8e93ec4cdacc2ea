r"""Margins and closed-loop figures of any loop: ``cf.loop_margins`` and ``cf.closed_loop_figures``.

A thin public layer over the engine the actuator figures use (:mod:`cas_freq.analysis.margins`,
:mod:`cas_freq.analysis.closed_loop`, same definitions, docs/model.md). The loop may be

1. a SISO python-control ``TransferFunction`` or ``StateSpace``, evaluated by its own
   ``__call__`` at :math:`s = j\omega` (continuous time) or :math:`z = e^{j\omega T}`
   (discrete time of period T = ``dt``, analysed up to the Nyquist frequency
   :math:`\pi / T`), times an exact :math:`e^{-j\omega\tau}` when ``delay=``
   :math:`\tau` [s] is given;
2. a callable of s, ``loop(s) -> complex``, vectorised over a complex array;
3. frequency-response data: a ``control.FrequencyResponseData`` or a pair
   ``(omega [rad/s], response)``. Its margins are found by interpolation on the given data
   only (ln|L| and the unwrapped phase linear in ln omega between the samples): nothing is
   refined beyond what the data resolve, and only crossings inside the data range are found.

The frequency range, unless ``omega_range=`` is given, runs from 1e-3 times the smallest to
1e3 times the largest nonzero |pole| or |zero| (and 1/delay) of an LTI system; for a callable
it must be given (default 1e-3..1e3 rad/s). The grid is densified where a delay turns the
phase quickly (:func:`~cas_freq.analysis.frequency.frequency_grid`): linear steps of
pi / (8 delay) above ~34 / delay, so a long delay over a wide range makes a long grid (python-
control's example21 with a 6 s delay: 1.5 million points, every one of its ~95,000 phase
crossovers listed; 1.6 s as a TransferFunction, 44 s as a StateSpace, which python-control
evaluates point by point); ``omega_range=`` bounds it.

Closed-loop stability, needed for Ms and the disk margin (None otherwise, with the reason in
``stability_basis``): for an LTI system from the poles of ``feedback(L, 1)``; with a delay from
those of the loop with a Padé approximant of order :data:`PADE_ORDER` of the delay (an
approximation, stated in ``stability_basis``); for a callable or data the caller says
(``stable=True/False``); left unknown it is None.
"""

import dataclasses
import math

import numpy as np

from cas_freq.analysis.closed_loop import closed_loop_figures as _closed_loop_engine
from cas_freq.analysis.closed_loop import figures_of_run
from cas_freq.analysis.frequency import continuous_phase, frequency_grid
from cas_freq.analysis.margins import (
    GainCrossover,
    PhaseCrossover,
    loop_figures,
    margins_of_run,
)
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.figures import FIGURES
from cas_freq.core.summary import Summary, table_rows

#: Order of the Padé approximant of a delay used only to decide closed-loop stability.
PADE_ORDER = 10

#: Range used for a callable when ``omega_range`` is not given [rad/s].
CALLABLE_RANGE_RAD_S = (1e-3, 1e3)

#: A pole or zero smaller than this times the largest is at s = 0 to rounding: the ss -> poles
#: conversion leaves an integrator at ~1e-12 of the fastest pole instead of 0 (L(0) is then
#: ~1e30, numerically infinite, not a static gain).
AT_ZERO = 1e-9

#: A discrete-time loop is analysed up to this share of its Nyquist frequency pi / dt: at
#: pi / dt itself L is real (z = -1), where a sign test of Im L would read rounding.
NYQUIST_SHARE = 1.0 - 1e-9


@dataclasses.dataclass(frozen=True, eq=False)
class _Loop:
    """A loop made evaluable: ``evaluate(omega) -> complex`` at s = j omega, its grid, and
    what is known of its closed loop."""

    evaluate: object
    omega: np.ndarray
    system: object          # the python-control system, or None
    delay_s: float
    is_data: bool


def _is_lti(obj):
    try:
        import control
    except ImportError:  # pragma: no cover - python-control is a dependency
        return False
    return isinstance(obj, control.LTI)


def _check_delay(delay):
    try:
        delay = float(delay)
    except (TypeError, ValueError):
        raise ValueError(f"delay: {delay!r} is not a number; accepted: a delay >= 0 [s]") \
            from None
    if not (math.isfinite(delay) and delay >= 0.0):
        raise ValueError(f"delay: {delay!r} is not accepted; accepted: a finite delay >= 0 [s]")
    return delay


def _check_range(omega_range):
    try:
        w_min, w_max = (float(w) for w in omega_range)
    except (TypeError, ValueError):
        raise ValueError(f"omega_range: {omega_range!r} is not accepted; accepted: "
                         "(w_min, w_max) [rad/s] with 0 < w_min < w_max") from None
    if not (0.0 < w_min < w_max < math.inf):
        raise ValueError(f"omega_range: {omega_range!r} is not accepted; accepted: "
                         "(w_min, w_max) [rad/s] with 0 < w_min < w_max")
    return w_min, w_max


def _period(system):
    """The sampling period [s] of a discrete-time system, None for a continuous one."""
    if not system.isdtime(strict=True):
        return None
    period = system.dt
    if period is True or not (isinstance(period, int | float) and 0 < period < math.inf):
        raise CasFreqError(f"loop: a discrete-time system of dt={period!r}; accepted: a "
                         "continuous system or a discrete one of a given period dt > 0 [s]")
    return float(period)


def _s_plane(system, roots):
    """Roots as s-plane frequencies [rad/s]: themselves for a continuous system, ln(z) / dt
    for a discrete one (z = 0 maps to infinity)."""
    roots = np.atleast_1d(np.asarray(roots, dtype=complex))
    period = _period(system)
    if period is None:
        return roots
    with np.errstate(divide="ignore"):
        return np.log(roots) / period


def _automatic_range(system, delay):
    """1e-3 x the smallest .. 1e3 x the largest nonzero |pole|, |zero| (and 1/delay) [rad/s]
    (a discrete system's mapped to the s-plane, :func:`_s_plane`)."""
    sizes = np.abs(np.concatenate([_s_plane(system, system.poles()),
                                   _s_plane(system, system.zeros())]))
    sizes = sizes[np.isfinite(sizes)]
    if sizes.size:
        sizes = sizes[sizes > AT_ZERO * sizes.max()]
    if delay > 0:
        sizes = np.append(sizes, 1.0 / delay)
    if sizes.size == 0:
        return CALLABLE_RANGE_RAD_S
    return 1e-3 * sizes.min(), 1e3 * sizes.max()


def _data_loop(data, delay):
    """(omega, response) of frequency-response data, checked."""
    import control

    if isinstance(data, control.FrequencyResponseData):
        if data.ninputs != 1 or data.noutputs != 1:
            raise ValueError(f"loop: a {data.noutputs}x{data.ninputs} FrequencyResponseData; "
                             "accepted: a SISO loop")
        omega = np.asarray(data.omega, dtype=float)
        response = np.asarray(data.frdata, dtype=complex).reshape(-1)
    else:
        omega, response = data
        omega = np.asarray(omega, dtype=float)
        response = np.asarray(response, dtype=complex)
    if omega.ndim != 1 or response.shape != omega.shape or omega.size < 3:
        raise ValueError(f"loop: frequency data of shapes {omega.shape} and {response.shape}; "
                         "accepted: (omega, response), equal 1-D arrays of >= 3 samples")
    if not (np.all(omega > 0) and np.all(np.diff(omega) > 0) and np.all(np.isfinite(omega))):
        raise ValueError("loop: the data frequencies are not accepted; accepted: positive, "
                         "finite and strictly increasing [rad/s]")
    if not (np.all(np.isfinite(response)) and np.all(response != 0)):
        raise ValueError("loop: the data response has zero or non-finite values; accepted: "
                         "finite and nonzero")
    response = response * np.exp(-1j * omega * delay)
    log_w = np.log(omega)
    log_mag = np.log(np.abs(response))
    phase = np.unwrap(np.angle(response))

    def evaluate(w):
        x = np.log(w)
        return np.exp(np.interp(x, log_w, log_mag) + 1j * np.interp(x, log_w, phase))

    return omega, response, evaluate


def _prepare(loop, delay, omega_range, points_per_decade):
    delay = _check_delay(delay)
    if omega_range is not None:
        omega_range = _check_range(omega_range)
    import control

    if isinstance(loop, control.FrequencyResponseData) or isinstance(loop, tuple):
        omega, response, evaluate = _data_loop(loop, delay)
        return _Loop(evaluate, omega, None, delay, True), response
    if _is_lti(loop):
        if loop.ninputs != 1 or loop.noutputs != 1:
            raise ValueError(f"loop: a {loop.noutputs}x{loop.ninputs} system; accepted: SISO")
        system = loop
        period = _period(system)
        if period is None:
            def evaluate(w):
                s = 1j * np.asarray(w, dtype=float)
                value = np.asarray(system(s.reshape(-1), squeeze=True), dtype=complex)
                return value.reshape(s.shape) * np.exp(-s * delay)
        else:
            def evaluate(w):
                s = 1j * np.asarray(w, dtype=float)
                z = np.exp(s.reshape(-1) * period)
                value = np.asarray(system(z, squeeze=True), dtype=complex)
                return value.reshape(s.shape) * np.exp(-s * delay)

        w_min, w_max = omega_range or _automatic_range(system, delay)
        if period is not None:
            nyquist = NYQUIST_SHARE * math.pi / period
            if omega_range is not None and w_max > nyquist:
                raise CasFreqError(f"omega_range: {omega_range!r} goes past the Nyquist "
                                 f"frequency pi/dt = {math.pi / period:.6g} rad/s; accepted: "
                                 "(w_min, w_max) [rad/s] with w_max below it")
            w_max = nyquist if omega_range is None else w_max
            if w_min >= w_max:
                w_min = 1e-3 * w_max
    elif callable(loop):
        system = None

        def evaluate(w):
            s = 1j * np.asarray(w, dtype=float)
            return np.broadcast_to(np.asarray(loop(s), dtype=complex), s.shape) * \
                np.exp(-s * delay)

        w_min, w_max = omega_range or CALLABLE_RANGE_RAD_S
    else:
        raise TypeError(f"loop: a {type(loop).__name__} is not accepted; accepted: a "
                        "python-control TransferFunction/StateSpace/FrequencyResponseData, a "
                        "callable of s, or (omega, response) arrays")
    omega = frequency_grid(w_min, w_max, points_per_decade, total_delay=delay)
    return _Loop(evaluate, omega, system, delay, False), evaluate(omega)


def _closed_loop_stability(prepared, stable, closed):
    """(stable or None, how it was decided). ``closed``: the system is T itself (its own poles
    decide), else L (the poles of feedback(L, 1))."""
    if stable is not None:
        if not isinstance(stable, (bool, np.bool_)):
            raise ValueError(f"stable: {stable!r} is not accepted; accepted: True, False or "
                             "None (not known)")
        return bool(stable), "given by the caller (stable=)"
    if prepared.system is None:
        return None, "unknown: pass stable=True/False for a callable or frequency data"
    import control

    system = prepared.system
    period = _period(system)
    basis = "poles of T" if closed else "closed-loop poles of feedback(L, 1)"
    if prepared.delay_s > 0 and not closed and period is not None:
        samples = prepared.delay_s / period
        if abs(samples - round(samples)) > 1e-9 * max(samples, 1.0):
            return None, ("unknown: a delay of a fraction of a sample (pass stable=True/False "
                          "for a discrete loop with such a delay)")
        system = system * control.tf([1.0], [1.0] + [0.0] * round(samples), period)
        basis = f"closed-loop poles with the delay as z^-{round(samples)}"
    elif prepared.delay_s > 0 and not closed:
        num, den = control.pade(prepared.delay_s, PADE_ORDER)
        system = system * control.tf(num, den)
        basis = f"closed-loop poles with a Padé-{PADE_ORDER} delay (an approximation)"
    try:
        poles = (system if closed else control.feedback(system, 1)).poles()
    except (ValueError, np.linalg.LinAlgError, control.ControlArgument) as error:
        return None, f"unknown: the closed-loop poles could not be computed ({error})"
    if period is not None:
        return bool(np.all(np.abs(poles) < 1.0)), basis + " (inside the unit circle)"
    return bool(np.all(poles.real < 0)), basis


def _none(value):
    return None if value is None or not np.isfinite(value) else float(value)


def _static_phase_crossover(prepared, values):
    """The phase crossover at w = 0 of an LTI loop whose static gain L(0) is finite and
    negative (as python-control and MATLAB list it), added to the crossings and the headline
    gain margins when nearer 0 dB; {} otherwise. (Not found for callables and data, which
    are known only inside their range.) None either when the loop has a pole at s = 0 to
    rounding (:data:`AT_ZERO`): L(0) is then infinite, whatever finite number the arithmetic
    leaves."""
    if prepared.system is None or _pole_at_zero(prepared.system):
        return {}
    with np.errstate(all="ignore"):
        dc = complex(np.asarray(prepared.system.dcgain()).reshape(-1)[0])
    if not (np.isfinite(dc) and dc.real < 0 and dc.imag == 0):
        return {}
    gm = -20.0 * math.log10(-dc.real)
    out = {"phase_crossovers": (PhaseCrossover(0.0, gm), *values["phase_crossovers"])}
    if gm >= 0 and (values["gain_margin_db"] is None or gm < values["gain_margin_db"]):
        out.update(gain_margin_db=gm, phase_crossover_rad_s=0.0)
    if gm < 0 and (values["gain_margin_low_db"] is None or gm > values["gain_margin_low_db"]):
        out.update(gain_margin_low_db=gm, phase_crossover_low_rad_s=0.0)
    return out


def _pole_at_zero(system):
    """Whether an LTI system has a pole at s = 0 (z = 1) to rounding: one smaller than
    :data:`AT_ZERO` times its largest pole or zero (in the s-plane, :func:`_s_plane`)."""
    poles = np.abs(_s_plane(system, system.poles()))
    if poles.size == 0:
        return False
    sizes = np.concatenate([poles, np.abs(_s_plane(system, system.zeros()))])
    return bool(poles.min() <= AT_ZERO * sizes[np.isfinite(sizes)].max())


@dataclasses.dataclass(frozen=True, repr=False)
class LoopMarginResult(Summary):
    """Every margin of one loop (:func:`loop_margins`); a figure that does not exist is None.

    Attributes
    ----------
    gain_crossovers : tuple of GainCrossover
        Every |L| = 1 in range: frequency [rad/s], phase margin [deg] in (-180, 180], delay
        margin [s], continuous phase [deg].
    phase_crossovers : tuple of PhaseCrossover
        Every L real and negative in range: frequency [rad/s], gain margin [dB] (> 0 upper,
        < 0 lower); for an LTI loop with a negative static gain also w = 0 (first).
    phase_margin_deg, crossover_rad_s
        The gain crossover nearest the critical point (smallest |PM|) [deg], [rad/s].
    gain_margin_db, phase_crossover_rad_s
        Smallest upper gain margin (> 0 dB) [dB] and where [rad/s].
    gain_margin_low_db, phase_crossover_low_rad_s
        Lower gain margin closest to 0 dB (< 0 dB) [dB] and where [rad/s].
    delay_margin_s, delay_margin_crossover_rad_s
        Smallest delay margin over the gain crossovers [s] and at which [rad/s].
    sensitivity_peak_db, sensitivity_peak_rad_s
        Ms = max |1/(1+L)| [dB] and where [rad/s]; None unless the closed loop is stable and
        |S| has an interior maximum in range (largest at a range end, its value there is a
        bound, not a peak: 3(10+s)/(2+s) tends to 1/4 as omega grows).
    disk_margin_alpha, disk_margin_gain_db, disk_margin_phase_deg
        Symmetric disk margin alpha, its gain [dB] and phase [deg] margins; None unless the
        closed loop is stable and max |S - 1/2| is at an interior maximum in range.
    closed_loop_stable : bool or None
        None when not known.
    stability_basis : str
        How ``closed_loop_stable`` was decided.
    omega_range_rad_s : tuple of float
        The analysed range [rad/s]: crossings outside it are not found.
    """

    gain_crossovers: tuple[GainCrossover, ...]
    phase_crossovers: tuple[PhaseCrossover, ...]
    phase_margin_deg: float | None
    crossover_rad_s: float | None
    gain_margin_db: float | None
    phase_crossover_rad_s: float | None
    gain_margin_low_db: float | None
    phase_crossover_low_rad_s: float | None
    delay_margin_s: float | None
    delay_margin_crossover_rad_s: float | None
    sensitivity_peak_db: float | None
    sensitivity_peak_rad_s: float | None
    disk_margin_alpha: float | None
    disk_margin_gain_db: float | None
    disk_margin_phase_deg: float | None
    closed_loop_stable: bool | None
    stability_basis: str
    omega_range_rad_s: tuple[float, float]
    _evaluate: object = dataclasses.field(repr=False, compare=False, default=None)

    def _summary(self):
        stable = {True: "stable", False: "unstable", None: "stability unknown"}
        title = (f"{len(self.gain_crossovers)} gain and {len(self.phase_crossovers)} phase "
                 f"crossovers in {self.omega_range_rad_s[0]:.4g}..{self.omega_range_rad_s[1]:.4g}"
                 f" rad/s, closed loop {stable[self.closed_loop_stable]}")
        return title, table_rows(self, "position_loop", (
            "phase_margin_deg", "crossover_rad_s", "gain_margin_db", "gain_margin_low_db",
            "delay_margin_s", "sensitivity_peak_db", "phase_crossover_rad_s",
            "phase_crossover_low_rad_s", "sensitivity_peak_rad_s", "disk_margin_alpha",
            "disk_margin_gain_db", "disk_margin_phase_deg"))

    def to_dict(self):
        """The figures as a JSON-ready dict (lists of dicts for the crossovers)."""
        out = _public_fields(self)
        out["gain_crossovers"] = [dataclasses.asdict(c) for c in self.gain_crossovers]
        out["phase_crossovers"] = [dataclasses.asdict(c) for c in self.phase_crossovers]
        return out

    def plot(self, points=2000):
        """Bode plot of the loop with every crossover marked.

        Parameters
        ----------
        points : int
            Samples of the plotted curve (log-spaced over ``omega_range_rad_s``).

        Returns
        -------
        matplotlib.figure.Figure
        """
        fig, magnitude, phase = _bode(self, "L", points)
        magnitude.axhline(0.0, color="grey", lw=0.8)
        pm_name, gm_name = (FIGURES[f"position_loop.{name}"].short  # the figure table's names
                            for name in ("phase_margin_deg", "gain_margin_db"))
        for c in self.gain_crossovers:
            magnitude.plot(c.frequency_rad_s, 0.0, "o", color="C1")
            phase.plot(c.frequency_rad_s, c.phase_deg, "o", color="C1")
            phase.annotate(f"{pm_name} {c.phase_margin_deg:.1f}°",
                           (c.frequency_rad_s, c.phase_deg), fontsize=8)
        for c in self.phase_crossovers:
            magnitude.plot(c.frequency_rad_s, -c.gain_margin_db, "s", color="C2")
            magnitude.annotate(f"{gm_name} {c.gain_margin_db:.1f} dB",
                               (c.frequency_rad_s, -c.gain_margin_db), fontsize=8)
        pm = "none" if self.phase_margin_deg is None else f"{self.phase_margin_deg:.2f}°"
        gm = "none" if self.gain_margin_db is None else f"{self.gain_margin_db:.2f} dB"
        magnitude.set_title(f"loop: {pm_name} {pm}, {gm_name} {gm}")
        magnitude.set_ylabel("magnitude [dB]")
        phase.set_ylabel("phase [deg]")
        phase.set_xlabel("frequency ω [rad/s]")
        for ax in (magnitude, phase):
            ax.grid(True, which="both", alpha=0.35)
        return fig


def loop_margins(loop, *, delay=0.0, omega_range=None, stable=None, points_per_decade=200):
    """Every gain/phase crossover and margin of a loop broken for negative unit feedback.

    Parameters
    ----------
    loop : control.TransferFunction, control.StateSpace, control.FrequencyResponseData,
           callable or tuple
        The loop L (module notes): a continuous SISO LTI system, ``loop(s) -> complex``, or
        frequency data ``(omega [rad/s], response)``. Data are interpolated between the given
        samples only (no refinement beyond them); a discrete-time system is evaluated at
        z = exp(j omega dt) up to its Nyquist frequency pi / dt.
    delay : float
        Delay in the loop [s], applied exactly as exp(-s delay).
    omega_range : (float, float), optional
        Analysed range [rad/s]; by default from the poles and zeros (module notes). Ignored
        for data, which are analysed over their own frequencies.
    stable : bool, optional
        Whether the closed loop is stable; by default decided from the closed-loop poles of an
        LTI system and unknown (Ms and disk margin None) for a callable or data.
    points_per_decade : int
        Log density of the grid [1/decade].

    Returns
    -------
    LoopMarginResult
    """
    prepared, response = _prepare(loop, delay, omega_range, points_per_decade)
    is_stable, basis = _closed_loop_stability(prepared, stable, closed=False)
    figures = loop_figures(lambda runs, w: prepared.evaluate(w), prepared.omega,
                           response[None, :], np.array([is_stable is True]), crossings=True)
    margins = margins_of_run(figures)
    values = {f.name: getattr(margins, f.name) for f in dataclasses.fields(LoopMarginResult)
              if hasattr(margins, f.name)}
    values.update(_static_phase_crossover(prepared, values))
    s_inside, d_inside, s_top, d_top = (bool(v[0]) for v in figures["_interior_maxima"])
    sampled = prepared.system is not None and _period(prepared.system) is not None
    # |S| of a discrete loop is symmetric about its Nyquist frequency: a maximum there is a peak
    sensitivity_inside = s_inside or (sampled and s_top)
    disk_inside = d_inside or (sampled and d_top)
    if not sensitivity_inside:  # |S| largest at a range end: a bound there, not a peak
        values.update(sensitivity_peak_db=None, sensitivity_peak_rad_s=None)
    if not disk_inside:
        values.update(disk_margin_alpha=None, disk_margin_gain_db=None, disk_margin_phase_deg=None)
    return LoopMarginResult(
        **values, closed_loop_stable=is_stable, stability_basis=basis,
        omega_range_rad_s=(float(prepared.omega[0]), float(prepared.omega[-1])),
        _evaluate=prepared.evaluate)


@dataclasses.dataclass(frozen=True, repr=False)
class ClosedLoopResult(Summary):
    """Bandwidth and shape of a closed loop T (:func:`closed_loop_figures`); None where a
    figure does not exist in range, or (all of them) when T is known to be unstable.

    Attributes
    ----------
    dc_gain_db : float or None
        |T(0)| [dB], taken 1000 times below the range (the lowest sample for data).
    bandwidth_rad_s : float or None
        Lowest frequency where |T| falls 3.0103 dB below |T(0)| [rad/s].
    peak_db, peak_rad_s : float or None
        Largest |T|/|T(0)| [dB] and where [rad/s] (None: no interior maximum).
    phase_90_rad_s : float or None
        Lowest frequency where the continuous phase of T reaches -90° [rad/s].
    stable : bool or None
        Whether T is stable (None: not known); ``stability_basis`` says how it was decided.
    omega_range_rad_s : tuple of float
        The analysed range [rad/s].
    """

    dc_gain_db: float | None
    bandwidth_rad_s: float | None
    peak_db: float | None
    peak_rad_s: float | None
    phase_90_rad_s: float | None
    stable: bool | None
    stability_basis: str
    omega_range_rad_s: tuple[float, float]
    _evaluate: object = dataclasses.field(repr=False, compare=False, default=None)

    def _summary(self):
        stable = {True: "stable", False: "unstable", None: "stability unknown"}
        title = (f"closed loop {stable[self.stable]}, {self.omega_range_rad_s[0]:.4g}.."
                 f"{self.omega_range_rad_s[1]:.4g} rad/s")
        return title, table_rows(self, "closed_loop", (
            "bandwidth_rad_s", "dc_gain_db", "peak_db", "peak_rad_s", "phase_90_rad_s"))

    def to_dict(self):
        """The figures as a JSON-ready dict."""
        return _public_fields(self)

    def plot(self, points=2000):
        """Bode plot of T with the bandwidth, peak and -90° frequency marked.

        Returns
        -------
        matplotlib.figure.Figure
        """
        fig, magnitude, phase = _bode(self, "T", points)
        dc = self.dc_gain_db if self.dc_gain_db is not None else 0.0
        if self.bandwidth_rad_s is not None:
            magnitude.plot(self.bandwidth_rad_s, dc - 20 * math.log10(math.sqrt(2)), "o",
                           color="C1", label=f"bandwidth {self.bandwidth_rad_s:.4g} rad/s")
        if self.peak_rad_s is not None:
            magnitude.plot(self.peak_rad_s, dc + self.peak_db, "s", color="C2",
                           label=f"peak {self.peak_db:.2f} dB")
        if self.phase_90_rad_s is not None:
            phase.plot(self.phase_90_rad_s, -90.0, "o", color="C3",
                       label=f"-90° at {self.phase_90_rad_s:.4g} rad/s")
            phase.legend()
        magnitude.legend()
        magnitude.set_ylabel("magnitude [dB]")
        phase.set_ylabel("phase [deg]")
        phase.set_xlabel("frequency ω [rad/s]")
        for ax in (magnitude, phase):
            ax.grid(True, which="both", alpha=0.35)
        return fig


def closed_loop_figures(closed_loop, *, delay=0.0, omega_range=None, stable=None,
                        points_per_decade=200):
    """Bandwidth (-3.0103 dB), resonance peak and -90° frequency of a closed loop T.

    Parameters
    ----------
    closed_loop : control.TransferFunction, control.StateSpace, control.FrequencyResponseData,
                  callable or tuple
        T, in any of the forms :func:`loop_margins` accepts (data: interpolated between the
        given samples only).
    delay : float
        Delay in T [s], exact (it does not change stability).
    omega_range : (float, float), optional
        Analysed range [rad/s] (default as :func:`loop_margins`).
    stable : bool, optional
        Whether T is stable; by default from its poles for an LTI system, else unknown (the
        figures are then computed, ``stable`` None). Known unstable: every figure is None.
    points_per_decade : int
        Log density of the grid [1/decade].

    Returns
    -------
    ClosedLoopResult
    """
    prepared, response = _prepare(closed_loop, delay, omega_range, points_per_decade)
    is_stable, basis = _closed_loop_stability(prepared, stable, closed=True)
    figures = _closed_loop_engine(lambda runs, w: prepared.evaluate(w), prepared.omega,
                                  response[None, :], np.array([is_stable is not False]))
    result = figures_of_run(figures)
    values = dataclasses.asdict(result) if result is not None else {}
    names = ("dc_gain_db", "bandwidth_rad_s", "peak_db", "peak_rad_s", "phase_90_rad_s")
    return ClosedLoopResult(
        **{name: _none(values.get(name)) for name in names},
        stable=is_stable, stability_basis=basis,
        omega_range_rad_s=(float(prepared.omega[0]), float(prepared.omega[-1])),
        _evaluate=prepared.evaluate)


def _public_fields(result):
    """A result's dataclass fields (not those starting with ``_``) as a dict, its frequency range
    as a list (JSON-ready)."""
    out = {f.name: getattr(result, f.name) for f in dataclasses.fields(result)
           if not f.name.startswith("_")}
    out["omega_range_rad_s"] = list(result.omega_range_rad_s)
    return out


def _bode(result, label, points):
    """A two-panel Bode figure (|.| [dB], continuous phase [deg]) of a result's response over its
    frequency range; returns (figure, magnitude axes, phase axes). The figure displays itself in
    a notebook (:class:`~cas_freq.plots.common.NotebookFigure`)."""
    from cas_freq.plots.common import NotebookFigure

    w = np.geomspace(*result.omega_range_rad_s, points)
    response = result._evaluate(w)
    fig = NotebookFigure(figsize=(8, 6), layout="constrained")
    magnitude, phase = fig.subplots(2, 1, sharex=True)
    magnitude.semilogx(w, 20.0 * np.log10(np.abs(response)), label=label)
    phase.semilogx(w, np.degrees(continuous_phase(response, w)), label=label)
    return fig, magnitude, phase
