r"""Limit cycles predicted by describing functions, each checked by a nonlinear simulation
(docs/model.md, "15. What the flight-control system sees", "Limit cycles").

For each nonlinearity the config has (:mod:`cas_freq.analysis.describing`: the gear's backlash,
Coulomb friction on the motor, the clamp of each controller's output) the harmonic balance
1 + N(A) G(jω) = 0 is solved: all three describing functions are real and positive, so a cycle
sits where G(jω) crosses the negative real axis (found on a log grid, refined by root finding
on Im G), at the amplitude where N(A) = −1/G(jω). Its stability is Loeb's criterion on
F(A, ω) = G(jω) + 1/N(A) = X + jY: the cycle is stable when
∂X/∂A · ∂Y/∂ω − ∂X/∂ω · ∂Y/∂A > 0 (here ∂Y/∂A = 0).

The describing function keeps only the first harmonic. Its low-pass hypothesis is checked at
each cycle: the nonlinearity's output harmonics k = 2, 3 (from the waveform, relative to the
first) passed back through |G(jkω)/G(jω)| estimate the harmonic at the nonlinearity's input
relative to the first; above :data:`HARMONIC_LIMIT` the prediction is marked as outside the
method's assumptions. So is a cycle whose nonlinearity is biased (a hinge moment preloads the
play) or shares the loop with another nonlinearity the prediction leaves out.
"""

import dataclasses
import math

import numpy as np

import cas_freq.analysis.describing as describing
from cas_freq.core.exceptions import CasFreqError
from cas_freq.model.loops import PreparedResponses, Selector
from cas_freq.model.structure import build

#: Largest estimated harmonic at the nonlinearity's input, relative to the first, for which the
#: describing function's low-pass hypothesis is taken to hold [-].
HARMONIC_LIMIT = 0.15
#: A backlash cycle whose twist amplitude is below this multiple of the half-play barely
#: engages the gear (its describing function is below ~1e-3): outside the assumptions.
BARELY = 1.01
#: Frequencies searched for cycles [rad/s].
SEARCH_RANGE_RAD_S = (0.01, 1e5)
#: Grid points per decade of the search.
POINTS_PER_DECADE = 400
#: A simulated oscillation within this relative error of the prediction (amplitude and
#: frequency) confirms it.
CONFIRM_TOLERANCE = 0.25
#: Periods of the predicted cycle simulated, and measured at the end.
SIMULATED_PERIODS, MEASURED_PERIODS = 40, 10
#: Longest simulation of a check [s] (the simulator's step budget at 5 us; the measured periods
#: shrink to 40 % of it), and the fewest periods of the cycle it must hold to check it.
MAX_SIMULATED_S, MIN_SIMULATED_PERIODS = 10.0, 6

#: What each clamp limits, per loop: parameter field, signal, unit.
CLAMPS = {
    "current_loop": ("v_max", "voltage V", "V"),
    "velocity_loop": ("i_max", "current command", "A"),
    "position_loop": ("i_max", "current command", "A"),
}
CASCADE_POSITION_CLAMP = ("omega_max", "velocity command", "rad/s")


@dataclasses.dataclass(frozen=True)
class Simulated:
    """The nonlinear simulation started near a predicted cycle.

    Attributes
    ----------
    command_rad : float
        The output step that started it [rad].
    sustained : bool
        Whether an oscillation lasted to the end (its amplitude over the last
        ``MEASURED_PERIODS`` periods at least half that of the ten before).
    amplitude : float or None
        First-harmonic amplitude of the nonlinearity's input over the last periods.
    frequency_rad_s : float or None
        Its frequency from the zero crossings [rad/s].
    output_amplitude_rad : float or None
        First-harmonic amplitude of the output [rad].
    verdict : str
        ``confirmed`` (amplitude and frequency within ``CONFIRM_TOLERANCE``), ``refuted``
        (no sustained oscillation, or one elsewhere: the numbers say where).
    method : str
        ``settles`` (a stable cycle: one run, measured at its end) or ``threshold`` (an
        unstable cycle: runs of growing steps; the cycle is the amplitude between the runs
        whose oscillation dies out and those whose oscillation grows, ``sustained`` then
        meaning such a threshold was found, ``command_rad`` the smallest step that grew).
    """

    command_rad: float
    sustained: bool
    amplitude: float | None
    frequency_rad_s: float | None
    output_amplitude_rad: float | None
    verdict: str
    method: str = "settles"


@dataclasses.dataclass(frozen=True)
class LimitCycle:
    """One predicted limit cycle.

    Attributes
    ----------
    nonlinearity : str
        ``backlash``, ``coulomb_friction`` or ``saturation.<loop>``.
    where : str
        Where it sits, in words.
    input_name, unit : str
        The nonlinearity's input (whose amplitude is given) and its SI unit.
    amplitude : float
        Predicted amplitude of the input.
    frequency_rad_s : float
        Predicted frequency [rad/s].
    stability : str
        ``stable`` or ``unstable`` (Loeb).
    describing_function : float
        N(A) at the cycle [output per input].
    loop_value : float
        G(jω), real at the cycle [input per output].
    output_amplitude_rad : float or None
        The output's first harmonic [rad] (None where not derived).
    harmonics : tuple of float
        Estimated 2nd and 3rd harmonics at the input relative to the first [-].
    assumptions_hold : bool
        The low-pass hypothesis holds and nothing below breaks the method's assumptions.
    notes : tuple of str
        Why the assumptions do not hold, or other remarks.
    simulated : Simulated or None
        The check by simulation (None: not run).
    """

    nonlinearity: str
    where: str
    input_name: str
    unit: str
    amplitude: float
    frequency_rad_s: float
    stability: str
    describing_function: float
    loop_value: float
    output_amplitude_rad: float | None
    harmonics: tuple
    assumptions_hold: bool
    notes: tuple = ()
    simulated: Simulated | None = None


@dataclasses.dataclass(frozen=True)
class LimitCycles:
    """The limit cycles of one variant: ``cycles`` (possibly empty), ``checked`` (the
    nonlinearities looked at), ``reason`` (why the list is empty, else None) and ``notes``."""

    cycles: tuple
    checked: tuple
    reason: str | None
    notes: tuple = ()



# --- harmonic balance ------------------------------------------------------------------------

def negative_real_crossings(function, low, high, points_per_decade=POINTS_PER_DECADE):
    """Frequencies in [low, high] where ``function(omega)`` (complex, vectorised) crosses the
    negative real axis, with its (real) value there: ``[(omega [rad/s], value), ...]``.

    The sign changes of its imaginary part on a log grid are bisected together (60 halvings:
    2^-60 of a grid interval); a change through infinity (a pole) is not a crossing.
    """
    omega = np.geomspace(low, high, int(points_per_decade * math.log10(high / low)) + 1)
    value = function(omega)
    k = np.nonzero((np.signbit(value.imag[:-1]) != np.signbit(value.imag[1:]))
                   & np.isfinite(value[:-1]) & np.isfinite(value[1:]))[0]
    if not len(k):
        return []
    left, right = omega[k], omega[k + 1]
    left_sign = np.signbit(value.imag[k])
    for _ in range(60):
        mid = 0.5 * (left + right)
        same = np.signbit(function(mid).imag) == left_sign
        left, right = np.where(same, mid, left), np.where(same, right, mid)
    root = 0.5 * (left + right)
    at = function(root)
    keep = (at.real < 0) & (np.abs(at.imag) <= 1e-6 * np.abs(at))
    return [(float(w), float(g.real)) for w, g in zip(root[keep], at[keep], strict=True)]


def _slope_imag(function, omega):
    """d Im G / d omega by a central difference."""
    h = 1e-6 * omega
    return float((function(np.array([omega + h]))[0] - function(np.array([omega - h]))[0]).imag
                 / (2 * h))


def loeb_stable(function, omega, inverse_n_slope):
    """Loeb's criterion for F = G(jω) + 1/N(A): stable when d(1/N)/dA · dIm G/dω > 0."""
    return inverse_n_slope * _slope_imag(function, omega) > 0


def harmonics(nonlinearity, amplitude, function, omega):
    """Estimated 2nd and 3rd harmonics at the nonlinearity's input relative to the first:
    the output's harmonics of ``nonlinearity(A sin)`` (256 samples a period) times
    |G(jkω)/G(jω)|."""
    phase = 2 * np.pi * (np.arange(256) + 0.5) / 256  # no sample on a zero of the sine
    spectrum = np.abs(np.fft.rfft(nonlinearity(amplitude * np.sin(phase))))
    first = spectrum[1]
    g = np.abs(function(np.array([omega, 2 * omega, 3 * omega])))
    if first == 0:
        return (0.0, 0.0)
    return tuple(float(spectrum[k] / first * g[k - 1] / g[0]) for k in (2, 3))


# --- the nonlinearities ----------------------------------------------------------------------

def _one_run(params):
    return Selector(params)()


def _backlash_cycles(params, p, label, unit):
    half = 0.5 * float(params.backlash[0])
    structure = build(p)  # once for the search below

    def g(omega):
        return describing.twist_loop(p, 1j * omega, structure)[0]

    out = []
    for omega, real in negative_real_crossings(g, *SEARCH_RANGE_RAD_S):
        n = -1.0 / real
        if not 0 < n < 1:
            continue
        amplitude = float(describing.dead_zone_amplitude(n, half))
        delta_per_y = abs(describing.twist_loop(p, 1j * np.array([omega]), structure)[1][0])
        notes = []
        if amplitude < BARELY * half:
            notes.append(f"the cycle barely engages the gear (the twist passes the half-play by "
                         f"{100 * (amplitude / half - 1):.2g} %): the output floats in the play "
                         f"and what the describing function leaves out (friction, the first "
                         f"contact's damping) decides whether it exists")
        if float(params.tau_h[0]) != 0:
            notes.append(f"the hinge moment preloads the play (tau_h/K_g = "
                         f"{abs(float(params.tau_h[0])) / float(params.K_g[0]):.3g} {unit} against "
                         f"a half-play of {half:.3g} {unit}): the twist does not oscillate about "
                         f"the play's centre, as the describing function assumes")
        out.append(_cycle(
            "backlash", f"the gear's play ({label})", "gear twist theta/N - delta", unit,
            amplitude, omega, n, real, delta_per_y * n * amplitude,
            lambda x: x - np.clip(x, -half, half), g,
            # 1/N falls as A grows (N rises from 0 to 1)
            -1.0, notes))
    return out


def _friction_cycles(params, p):
    level = float(params.F_c[0])
    structure = build(p)  # once for the search below

    def g(omega):
        return describing.speed_loop(p, 1j * omega, structure)[0]

    out = []
    for omega, real in negative_real_crossings(g, *SEARCH_RANGE_RAD_S):
        amplitude = -real * 4.0 * level / np.pi  # N(A) = 4 F_c/(pi A) = -1/G
        delta_per_torque = abs(describing.speed_loop(p, 1j * np.array([omega]),
                                                     structure)[1][0])
        out.append(_cycle(
            "coulomb_friction", "Coulomb friction on the motor shaft", "motor speed omega",
            "rad/s", amplitude, omega, -1.0 / real, real,
            delta_per_torque * level * 4.0 / np.pi, lambda x: level * np.sign(x), g, 1.0, []))
    return out


def _saturation_cycles(params, p):
    names = _loop_names(params)
    prepared = PreparedResponses(p)  # the structure built once for the searches below
    out = []
    for name in names:
        field, signal, unit = CLAMPS[name]
        if name == "position_loop" and params.cascade:
            field, signal, unit = CASCADE_POSITION_CLAMP
        limit = float(getattr(params, field)[0])
        if not math.isfinite(limit):
            continue

        def g(omega, name=name):
            omega = np.asarray(omega, dtype=float)
            return prepared.responses(np.zeros(omega.shape, dtype=int), 1j * omega,
                                      closed=False, loop_at_a_time=True).loop_at_a_time[name]

        for omega, real in negative_real_crossings(g, *SEARCH_RANGE_RAD_S):
            n = -1.0 / real
            if not 0 < n < 1:
                continue
            amplitude = float(describing.saturation_amplitude(n, limit))
            output = None
            notes = ["the clamp's anti-windup (the integrator holds while clamped) is not in "
                     "the describing function"]
            if name == names[-1]:
                s = np.array([1j * omega])
                output = n * amplitude * abs(describing.clamp_to_output(p, s, g(s.imag))[0])
            else:
                notes.append("an inner loop's clamp: the outer loops' clamps act first on a "
                             "cycle this large; not checked by simulation")
            out.append(_cycle(
                f"saturation.{name}", f"the clamp ±{limit:.4g} {unit} of the {signal}",
                f"{signal} before the clamp", unit, amplitude, omega, n, real, output,
                lambda x, limit=limit: np.clip(x, -limit, limit), g, 1.0, notes))
    return out


def _loop_names(params):
    return (("current_loop", "velocity_loop", "position_loop") if params.cascade
            else ("current_loop", "position_loop"))


def _cycle(key, where, input_name, unit, amplitude, omega, n, real, output_amplitude,
           nonlinearity, g, inverse_n_slope, notes):
    stable = loeb_stable(g, omega, inverse_n_slope)
    ratios = harmonics(nonlinearity, amplitude, g, omega)
    notes = list(notes)
    if max(ratios) > HARMONIC_LIMIT:
        notes.append(f"low-pass hypothesis fails: the harmonics at the input are estimated at "
                     f"{ratios[0]:.2g} (2nd) and {ratios[1]:.2g} (3rd) of the first "
                     f"(limit {HARMONIC_LIMIT:g})")
    return LimitCycle(
        nonlinearity=key, where=where, input_name=input_name, unit=unit,
        amplitude=float(amplitude), frequency_rad_s=float(omega),
        stability="stable" if stable else "unstable", describing_function=float(n),
        loop_value=float(real),
        output_amplitude_rad=None if output_amplitude is None else float(output_amplitude),
        harmonics=ratios, assumptions_hold=not notes, notes=tuple(notes))


def _other_nonlinearities(params, key):
    """The notes for the nonlinearities in the loop besides ``key``."""
    others = []
    if key != "backlash" and float(params.backlash[0]) > 0:
        others.append("backlash")
    if key != "coulomb_friction" and float(params.F_c[0]) > 0:
        others.append("Coulomb friction")
    eta, eta_b = float(params.eta[0]), float(params.eta_b[0])
    if eta != 1 or eta_b != 1:  # the load reflects by 1/eta or by eta_b by the power's direction
        others.append(f"the gear's efficiency (eta = {eta:g}, eta_b = {eta_b:g}: it depends "
                      "on the direction of power)")
    return others


def limit_cycles(params, simulate=False, linear=False):
    """The limit cycles of one variant (a batch of one).

    Parameters
    ----------
    params : cas_freq.core.parameters.LoopParameters
        One run.
    simulate : bool
        Check each cycle with an output amplitude by a nonlinear simulation.
    linear : bool
        The output is linear (the gear's twist in m, not rad).

    Returns
    -------
    LimitCycles
    """
    p = _one_run(params)
    notes = []
    if params.sample_rates:
        notes.append("of the continuous loops: the sampled controllers are not modelled here")
        p.sample_rates = ()
    checked, cycles = [], []
    if float(params.backlash[0]) > 0 and float(params.K_g[0]) > 0:
        checked.append("backlash")
        label = ("inside the position loop: it measures the output" if params.feedback_output
                 else "outside the position loop's measurement: it measures the motor")
        cycles += _backlash_cycles(params, p, label, "m" if linear else "rad")
    if float(params.F_c[0]) > 0:
        checked.append("coulomb_friction")
        cycles += _friction_cycles(params, p)
    checked += [f"saturation.{name}" for name in _loop_names(params)]
    cycles += _saturation_cycles(params, p)
    finished = []
    for cycle in cycles:
        others = _other_nonlinearities(params, cycle.nonlinearity)
        if others and not cycle.nonlinearity.startswith("saturation"):
            cycle = dataclasses.replace(
                cycle, assumptions_hold=False, notes=cycle.notes + (
                    "the loop has other nonlinearities the prediction leaves out: "
                    + ", ".join(others),))
        if simulate and cycle.output_amplitude_rad is not None:
            try:
                cycle = judged(dataclasses.replace(cycle,
                                                   simulated=simulate_cycle(params, cycle)))
            except CasFreqError as error:  # a cycle beyond the simulation's budget
                cycle = dataclasses.replace(cycle, notes=cycle.notes + (
                    f"not checked by simulation: {error}",))
        finished.append(cycle)
    reason = None
    if not finished:
        reason = ("no loop seen by " + ", ".join(checked) + " crosses the negative real axis "
                  "where its describing function reaches (1 + N(A) G(jω) = 0 has no solution "
                  f"over {SEARCH_RANGE_RAD_S[0]:g}..{SEARCH_RANGE_RAD_S[1]:g} rad/s)")
    return LimitCycles(tuple(finished), tuple(checked), reason, tuple(notes))


# --- the check by simulation -----------------------------------------------------------------

def simulate_cycle(params, cycle):
    """Start the nonlinear simulation near ``cycle`` and measure it. A stable cycle: an output
    step of twice its predicted output amplitude, and the
    oscillation it settles into: the first harmonic of the nonlinearity's input and of the
    output over the last :data:`MEASURED_PERIODS` periods, its frequency from the zero
    crossings. An unstable cycle: :func:`simulate_threshold`."""
    from cas_freq.simulation.commands import Step
    from cas_freq.simulation.simulator import simulate_batch

    def signal_of(result, k):
        if cycle.nonlinearity == "backlash":
            return result.theta[k] / params.ratio[0] - result.delta[k]
        if cycle.nonlinearity == "coulomb_friction":
            return result.omega[k]
        return result.delta[k]  # a clamp's input is not recorded: its output is measured

    period = 2 * np.pi / cycle.frequency_rad_s
    periods = THRESHOLD_PERIODS if cycle.stability == "unstable" else SIMULATED_PERIODS
    if min(periods * period, MAX_SIMULATED_S) < MIN_SIMULATED_PERIODS * period:
        raise CasFreqError(f"its period ({period:.3g} s) is too long: {MAX_SIMULATED_S:g} s of "
                           f"simulation hold fewer than {MIN_SIMULATED_PERIODS} periods")
    if cycle.stability == "unstable":
        return simulate_threshold(params, cycle, signal_of)
    step = 2.0 * cycle.output_amplitude_rad
    t_end = min(max(SIMULATED_PERIODS * period, 0.2), MAX_SIMULATED_S)
    result = simulate_batch(params, Step(step), t_end=t_end, extend=False,
                            record_every=_record_every(period))
    found = measure(result.t, signal_of(result, 0), result.delta[0], period, step)
    if cycle.nonlinearity.startswith("saturation"):  # the output was measured
        found = dataclasses.replace(found, amplitude=None)
    return found


#: The output steps of a threshold check, relative to twice the predicted output amplitude.
THRESHOLD_STEPS = 2.0 ** (np.arange(-6, 7) / 3.0)
#: Periods of a threshold check; a run whose oscillation over the last periods is more than
#: twice that of its first period grows.
THRESHOLD_PERIODS = 30


def simulate_threshold(params, cycle, signal_of):
    """Check an unstable cycle: steps of the output over :data:`THRESHOLD_STEPS` (in one
    batch), each run's oscillation of the nonlinearity's input over its first period (its
    first harmonic at the predicted frequency) and whether it grows. The simulated cycle is
    the geometric mean of the first-period amplitudes of the largest run that does not grow
    and the smallest that does (every larger one growing too); its frequency is that of the
    growing run's zero crossings while its amplitude stays below three times that."""
    from cas_freq.simulation.commands import Step
    from cas_freq.simulation.simulator import simulate_batch

    period = 2 * np.pi / cycle.frequency_rad_s
    steps = 2.0 * cycle.output_amplitude_rad * THRESHOLD_STEPS
    runs = params.take(np.zeros(len(steps), dtype=int))
    t_end = min(THRESHOLD_PERIODS * period, MAX_SIMULATED_S)
    result = simulate_batch(runs, Step(steps), t_end=t_end, extend=False,
                            record_every=_record_every(period))
    first, grows = [], []
    for k in range(len(steps)):
        x = signal_of(result, k)
        early = result.t < period
        late = result.t >= result.t[-1] - 3 * period
        a0 = _first_harmonic(result.t[early], x[early], cycle.frequency_rad_s)
        finite = bool(np.all(np.isfinite(x)))
        first.append(a0)
        grows.append(not finite or np.ptp(x[late]) > 4.0 * a0)
    grows = np.array(grows)
    # the smallest step from which every larger one grows
    start = next((k for k in range(len(steps)) if grows[k:].all()), None)
    if start is None or start == 0:
        return Simulated(float(steps[0] if start == 0 else steps[-1]), False, None, None, None,
                         "refuted", "threshold")
    amplitude = math.sqrt(first[start - 1] * first[start])
    x = signal_of(result, start)
    periods = 1
    while periods < 8 and _first_harmonic(
            *_period(result.t, x, periods, period), cycle.frequency_rad_s) < 3.0 * amplitude:
        periods += 1
    window = result.t <= periods * period
    omega = _crossing_frequency(result.t[window], x[window])
    if cycle.nonlinearity.startswith("saturation"):  # the output was measured
        return Simulated(float(steps[start]), True, None, omega, float(amplitude), "pending",
                         "threshold")
    out = result.delta[start]
    output = _first_harmonic(result.t[result.t < period], out[result.t < period],
                             cycle.frequency_rad_s)
    return Simulated(float(steps[start]), True, float(amplitude), omega, output, "pending",
                     "threshold")


def _period(t, x, index, period):
    """The samples of period ``index`` (from 0) of a run."""
    inside = (t >= index * period) & (t < (index + 1) * period)
    return t[inside], x[inside]


def _record_every(period):
    """Keep about 400 samples a period at the default step (5 us; at most 20 us)."""
    return max(1, int(period / 5e-6 / 400))


def _crossing_frequency(t, x):
    """Frequency of the upward zero crossings of ``x`` less its mean [rad/s] (None for fewer
    than three)."""
    x = x - x.mean()
    k = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    if len(k) < 3:
        return None
    times = t[k] - x[k] * (t[k + 1] - t[k]) / (x[k + 1] - x[k])
    return float(2 * np.pi * (len(times) - 1) / (times[-1] - times[0]))


def measure(t, signal, output, period, command_rad):
    """The oscillation at the end of a run (see :func:`simulate_cycle`)."""
    span = min(MEASURED_PERIODS * period, 0.4 * (t[-1] - t[0]))
    last = t >= t[-1] - span
    before = (t >= t[-1] - 2 * span) & ~last
    x = signal[last] - signal[last].mean()
    spread_last = np.ptp(signal[last])
    spread_before = np.ptp(signal[before]) if before.any() else spread_last
    crossings = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    tl = t[last]
    sustained = bool(len(crossings) >= 2 and spread_last >= 0.5 * spread_before
                     and spread_last > 0)
    if not sustained:
        return Simulated(float(command_rad), False, None, None, None, "refuted")
    # the crossing instants, interpolated
    times = tl[crossings] - x[crossings] * (tl[crossings + 1] - tl[crossings]) / (
        x[crossings + 1] - x[crossings])
    omega = 2 * np.pi * (len(times) - 1) / (times[-1] - times[0])
    window = (tl >= times[0]) & (tl <= times[-1])
    amplitude = _first_harmonic(tl[window], signal[last][window], omega)
    out_amplitude = _first_harmonic(tl[window], output[last][window], omega)
    return Simulated(float(command_rad), True, amplitude, float(omega), out_amplitude,
                     "pending")


def _first_harmonic(t, x, omega):
    """Amplitude of the first harmonic at ``omega`` over whole periods (least squares with an
    offset)."""
    basis = np.column_stack([np.sin(omega * t), np.cos(omega * t), np.ones_like(t)])
    coefficients = np.linalg.lstsq(basis, x, rcond=None)[0]
    return float(np.hypot(coefficients[0], coefficients[1]))


def judged(cycle):
    """``cycle`` with its simulation's verdict: confirmed when the simulated amplitude and
    frequency are both within :data:`CONFIRM_TOLERANCE` of the prediction."""
    sim = cycle.simulated
    if sim is None or not sim.sustained:
        return cycle
    measured, predicted = sim.amplitude, cycle.amplitude
    if measured is None:  # a clamp's input is not recorded: its output was measured
        measured, predicted = sim.output_amplitude_rad, cycle.output_amplitude_rad
    close = sim.frequency_rad_s is not None and (abs(measured / predicted - 1) <= CONFIRM_TOLERANCE
             and abs(sim.frequency_rad_s / cycle.frequency_rad_s - 1) <= CONFIRM_TOLERANCE)
    return dataclasses.replace(cycle, simulated=dataclasses.replace(
        sim, verdict="confirmed" if close else "refuted"))


# --- output ----------------------------------------------------------------------------------

def to_json(result):
    """The ``limit_cycles`` list of ``analyze``'s JSON (output amplitudes in degrees, as
    ``*_deg`` keys that a linear output turns into mm) and its companions: ``{"limit_cycles":
    [...], "limit_cycles_reason": ..., "limit_cycles_checked": [...], "limit_cycles_notes":
    [...]}``."""
    cycles = []
    for cycle in result.cycles:
        sim = cycle.simulated
        cycles.append({
            "nonlinearity": cycle.nonlinearity, "where": cycle.where,
            "input": cycle.input_name, "unit": cycle.unit, "amplitude": cycle.amplitude,
            "frequency_rad_s": cycle.frequency_rad_s, "stability": cycle.stability,
            "describing_function": cycle.describing_function, "loop_value": cycle.loop_value,
            "output_amplitude_deg": _degrees(cycle.output_amplitude_rad),
            "harmonics": {"second": cycle.harmonics[0], "third": cycle.harmonics[1]},
            "assumptions_hold": cycle.assumptions_hold, "notes": list(cycle.notes),
            "simulated": None if sim is None else {
                "command_step_deg": _degrees(sim.command_rad), "sustained": sim.sustained,
                "amplitude": sim.amplitude, "frequency_rad_s": sim.frequency_rad_s,
                "output_amplitude_deg": _degrees(sim.output_amplitude_rad),
                "verdict": sim.verdict, "method": sim.method},
        })
    return {"limit_cycles": cycles, "limit_cycles_reason": result.reason,
            "limit_cycles_checked": list(result.checked),
            "limit_cycles_notes": list(result.notes)}


def _degrees(value):
    return None if value is None else math.degrees(value)


def text_lines(result, unit=None):
    """The ``analyze`` table's lines for ``result`` (``unit``: the output's
    :class:`cas_freq.core.output.OutputUnit`, default degrees)."""
    lines = ["  limit cycles (describing functions: " + ", ".join(result.checked) + ")"]
    if not result.cycles:
        lines.append(f"    none: {result.reason}")
    found = {cycle.nonlinearity for cycle in result.cycles}
    quiet = [name for name in result.checked if name not in found]
    if result.cycles and quiet:
        lines.append(f"    no cycle of {', '.join(quiet)}: the loop each sees does not reach "
                     "the negative real axis where its describing function can")
    for cycle in result.cycles:
        output = ""
        if cycle.output_amplitude_rad is not None:
            output = f", output ±{_shown(cycle.output_amplitude_rad, unit)}"
        lines.append(
            f"    {cycle.nonlinearity}: {cycle.stability} cycle at "
            f"{cycle.frequency_rad_s:.4g} rad/s, {cycle.input_name} ±{cycle.amplitude:.4g} "
            f"{cycle.unit}{output} (N = {cycle.describing_function:.3g}; 3rd harmonic "
            f"{cycle.harmonics[1]:.2g} of the 1st; assumptions {_hold(cycle)})")
        sim = cycle.simulated
        if sim is not None and sim.method == "threshold":
            if sim.sustained:
                lines.append(
                    f"      simulated (output steps, the smallest that grew "
                    f"{_shown(sim.command_rad, unit)}): oscillations below "
                    f"{_measured(sim, cycle, unit)} die out, larger ones grow, at "
                    f"{_rate(sim.frequency_rad_s)}: {sim.verdict.upper()}")
            else:
                lines.append("      simulated (output steps): no amplitude divides runs that "
                             f"die out from runs that grow: {sim.verdict.upper()}")
        elif sim is not None:
            if sim.sustained:
                lines.append(
                    f"      simulated ({_shown(sim.command_rad, unit)} step): "
                    f"{_rate(sim.frequency_rad_s)}, {_measured(sim, cycle, unit)}, "
                    f"output ±{_shown(sim.output_amplitude_rad, unit)}: {sim.verdict.upper()}")
            else:
                lines.append(f"      simulated ({_shown(sim.command_rad, unit)} step): no "
                             f"sustained oscillation: {sim.verdict.upper()}")
        lines += [f"      - {note}" for note in cycle.notes]
    lines += [f"    ({note})" for note in result.notes]
    return lines


def _hold(cycle):
    return "hold" if cycle.assumptions_hold else "do not hold"


def _measured(sim, cycle, unit):
    """The simulated amplitude: of the nonlinearity's input, else of the output."""
    if sim.amplitude is None:
        return f"output ±{_shown(sim.output_amplitude_rad, unit)}"
    return f"±{sim.amplitude:.4g} {cycle.unit}"


def _rate(omega):
    return "an unmeasured frequency" if omega is None else f"{omega:.4g} rad/s"


def _shown(value_si, unit):
    """An output quantity [rad or m] as text in the output's unit (deg or mm)."""
    if unit is None:
        return f"{math.degrees(value_si):.4g} deg"
    return f"{float(unit.from_si(value_si)):.4g} {unit.shown}"


def report_sentence(result, unit=None):
    """One sentence for a variant's report section: each predicted cycle in brief (the
    simulation's verdict where it ran), or none and why."""
    head = f"Limit cycles (describing functions of {', '.join(result.checked)}"
    head += "; the continuous loops): " if result.notes else "): "
    if not result.cycles:
        return head + f"none: {result.reason}."
    parts = []
    for cycle in result.cycles:
        text = f"{cycle.nonlinearity} {cycle.stability} at {cycle.frequency_rad_s:.4g} rad/s"
        if cycle.output_amplitude_rad is not None:
            text += f", output ±{_shown(cycle.output_amplitude_rad, unit)}"
        text += (", assumptions hold" if cycle.assumptions_hold
                 else ", outside the method's assumptions")
        if cycle.simulated is not None:
            text += f", {cycle.simulated.verdict} by simulation"
        parts.append(text)
    return (head + "; ".join(parts) + " (`cas-freq analyze --limit-cycles` checks them by "
            "simulation and says why an assumption fails).")
