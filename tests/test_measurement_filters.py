"""Analog filters on the measurements (issue 26: "anti-aliasing matters for a sampled
measurement"): ``filters:`` at ``current_feedback`` (on the measured current) and
``position_feedback`` (on the position loop's measured angle).

References and tolerances
-------------------------
- **Continuous loops by hand.** With F_i on the measured current and F_p on the measured angle,
  the loops of the QT-CAS (docs/model.md §3-§4, the plant i/V = Y written out in
  tests/sampled_oracle.py from the physical equations): L_i = C_i e^{-s tau_c} Y F_i,
  i/i_cmd = C_i e^{-s tau_c} Y/(1 + L_i), theta/i_cmd = G = (i/i_cmd) M,
  L_p = C_p e^{-s tau_p} G F_p and T = C_r e^{-s tau_p} G/(1 + L_p) (the output read
  unfiltered). Exact formulas against exact responses: 1e-12 relative (rounding).
- **Every continuous representation** against tests/architecture_oracle.py (written without
  cas_freq; its three methods carry the new points as sensor blocks): analyze's figures
  (compiled response kernel and margin search) to 1e-6 as tests/test_architectures.py, the
  Padé-6 closed-loop poles to 1e-7, the python-control loops against the responses with the
  same Padé delays to 1e-7; the compiled grid responses against numpy's to 1e-12 as
  tests/test_response_kernel.py.
- **Sampled loops.** An analog filter is continuous dynamics before the sampler: it belongs in
  the plant's hold-equivalent. tests/sampled_oracle.py builds the filtered plant with
  python-control (``control.series`` of the plant and the filters' own realisations), its
  exact fractional-delay hold-equivalent by matrix exponentials and the multirate loop as a
  lifted state space; cas_freq (modal residues of the augmented plant, decimation sum) agrees
  to 1e-9 relative, as tests/test_sampled_responses.py asks without filters. Applying the
  filter digitally as well (or instead) moves the loops by > 1e-2: the test can fail.
- **Simulation.** Both engines perform the same operations (1e-9 of each signal's scale, as
  tests/test_simulation_architectures.py); the small sine dwell against the linear closed loop
  (continuous and sampled at the EPOS4 rates) within 0.05 dB and 0.3 deg (measured < 0.005 dB,
  < 0.09 deg).
- **Nothing else moves.** Without the new points the figures are those of the commit before
  them to the last bit (pinned below, printed by that commit).
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from architecture_oracle import Filter as OracleFilter
from architecture_oracle import (
    closed_loop_poles,
    example_cascade,
    figures,
    qt_cas_drive,
    replace,
)
from sampled_oracle import current_voltage_to_current, drive_of, lifted

import cas_freq as cf
from cas_freq.analysis import sampled_stability
from cas_freq.analysis.response_kernel import grid_responses
from cas_freq.analysis.stability import closed_loop_poles as our_poles
from cas_freq.analysis.stability import loop_polynomials
from cas_freq.analysis.systems import linear_model
from cas_freq.config import load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.filters_config import ANALOG_POINTS, FILTER_POINTS, Filter
from cas_freq.core.parameters import LoopParameters
from cas_freq.model import loops, sampled, state_space
from cas_freq.model.delay import EXACT, DelayModel
from cas_freq.model.structure import analog_sensor, build, digital_sensor
from cas_freq.simulation import Step, simulate_batch
from cas_freq.simulation.sinedwell import linear_reference, sine_dwell
from tests.test_architectures import _compare
from tests.test_simulation_architectures import _assert_same

ROOT = Path(__file__).resolve().parents[1]
QT_CAS = ROOT / "configs" / "qt_cas.yaml"
AXIS = ROOT / "configs" / "cascade_axis.yaml"
EPOS4 = (("current_loop", 25e3), ("position_loop", 2.5e3))
#: cascade_axis's multirate sampling (its step is 10 us: 5, 20 and 40 steps).
AXIS_RATES = (("current_loop", 20e3), ("velocity_loop", 5e3), ("position_loop", 2.5e3))
#: A 5 kHz first-order anti-aliasing filter on the angle, a 12 kHz second-order one on the
#: current [rad/s].
W_ANGLE, W_CURRENT = 2 * math.pi * 5e3, 2 * math.pi * 12e3
MEASUREMENT_FILTERS = (Filter("position_feedback", "lowpass1", W_ANGLE),
                       Filter("current_feedback", "lowpass2", W_CURRENT, damping=0.6))


def _params(config=QT_CAS, variant="base", filters=MEASUREMENT_FILTERS, **changes):
    params = LoopParameters.from_config(load_variant(config, variant).params)
    return dataclasses.replace(params, filters=tuple(filters), **changes)


def _lowpass1(w0):
    return lambda s: 1.0 / (s / w0 + 1.0)


def _lowpass2(w0, zeta):
    return lambda s: w0 * w0 / (s * s + 2.0 * zeta * w0 * s + w0 * w0)


# ----------------------------------------------------------------------------------- config

def test_the_config_accepts_the_measurement_points():
    raw = [{"at": "current_feedback", "type": "lowpass1", "frequency": "75000 rad/s"},
           {"at": "position_feedback", "type": "notch", "frequency": "9000 rad/s",
            "width": "3000 rad/s", "depth": "-10 dB"}]
    params = LoopParameters.from_config(load_variant(QT_CAS, "base",
                                                     overrides=[("filters", raw)]).params)
    assert [(f.at, f.kind) for f in params.filters] == [("current_feedback", "lowpass1"),
                                                         ("position_feedback", "notch")]
    assert params.filters[0].frequency[0] == 75000.0
    # one place says which points are analog, and they are points
    assert set(ANALOG_POINTS) == {"current_feedback", "position_feedback"}
    assert set(ANALOG_POINTS) < set(FILTER_POINTS)


def test_a_bad_point_names_every_accepted_point():
    raw = [{"at": "angle_feedback", "type": "lowpass1", "frequency": "1000 rad/s"}]
    with pytest.raises(ConfigError, match="filters.0.at: 'angle_feedback' is not a filter "
                       "point; use current_command, velocity_command, velocity_feedback, "
                       "current_feedback, position_feedback or "
                       "position_command"):
        load_variant(QT_CAS, "base", overrides=[("filters", raw)])


def test_the_measurement_filters_are_the_analog_sensor_blocks_of_their_loops():
    structure = build(loops.Selector(_params(AXIS, filters=(
        *MEASUREMENT_FILTERS, Filter("velocity_feedback", "lowpass1", 4000.0))))())
    current, velocity, position = structure.loops
    assert [b.analog for b in current.sensor] == [True]
    assert [b.analog for b in position.sensor] == [True]
    assert not analog_sensor(velocity) and len(digital_sensor(velocity)) == 2  # with tau_vf


# --------------------------------------------------------------------------- continuous

def test_the_continuous_loops_are_the_hand_formulas():
    p = _params()
    d = drive_of(QT_CAS)  # the same drive without the filters (the oracle's plain numbers)
    omega = np.geomspace(1.0, 3e5, 200)
    s = 1j * omega
    found = loops.responses(loops.Selector(p)(), s)
    y = current_voltage_to_current(d)(s)
    c_i = d.ci_Kp + d.ci_Ki / s
    f_i, f_p = _lowpass2(W_CURRENT, 0.6)(s), _lowpass1(W_ANGLE)(s)
    l_i = c_i * np.exp(-s * d.tau_c) * y * f_i
    g = c_i * np.exp(-s * d.tau_c) * y / (1 + l_i) * d.Km / (s * (d.J * s + d.mu_v))
    c_p = d.cp_Kp + d.cp_Ki / s + d.cp_Kd * s / (d.Tf * s + 1)
    c_r = d.cp_Kp + d.cp_Ki / s if d.derivative_on_measurement else c_p
    l_p = c_p * np.exp(-s * d.tau_p) * g * f_p
    t = c_r * np.exp(-s * d.tau_p) * g / (1 + l_p)
    for ours, theirs in ((found.current_loop, l_i), (found.position_loop, l_p),
                         (found.closed_loop, t)):
        np.testing.assert_allclose(ours, theirs, rtol=1e-12)
    # the filters matter here (the test can fail): 6 and 28 deg at 3e4 rad/s
    assert abs(np.angle(f_i[np.searchsorted(omega, 3e4)], deg=True)) > 5.0


def _oracle_filters(filters):
    return tuple(OracleFilter(f.at, f.kind, float(f.frequency[0]),
                              damping=float(np.nan_to_num(f.damping[0], nan=0.7)))
                 for f in filters)


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
@pytest.mark.parametrize("case", ["qt_loaded_output", "cascade_axis"])
def test_every_continuous_representation_has_the_measurement_filters(case):
    if case == "qt_loaded_output":  # the fin encoder's angle filtered, the gear inside
        loaded = cf.load(QT_CAS, variant="loaded", set={
            "position_loop.feedback": "output",
            "filters": [{"at": "position_feedback", "type": "lowpass1",
                         "frequency": f"{W_ANGLE} rad/s"},
                        {"at": "current_feedback", "type": "lowpass2",
                         "frequency": f"{W_CURRENT} rad/s", "damping": 0.6}]})
        drive = replace(qt_cas_drive("loaded"), feedback="output",
                        filters=_oracle_filters(MEASUREMENT_FILTERS))
    else:  # the shipped cascade (its notch and velocity filter kept) with both added
        extra = [{"at": "position_feedback", "type": "lowpass1", "frequency": "2000 rad/s"},
                 {"at": "current_feedback", "type": "lowpass1", "frequency": "30000 rad/s"}]
        shipped = load_variant(AXIS).params.filters
        loaded = cf.load(AXIS, set={"filters": [
            {"at": f.at, "type": f.type, **{k: getattr(f, k) for k in
                                            ("frequency", "damping", "width", "depth")
                                            if getattr(f, k) is not None}}
            for f in shipped] + extra})
        drive = example_cascade(cv_Kp=1.3)
        drive = replace(drive, filters=(*drive.filters,
                                        OracleFilter("position_feedback", "lowpass1", 2000.0),
                                        OracleFilter("current_feedback", "lowpass1", 3e4)))
    # analyze's figures (the compiled response kernel, the margin searches)
    ours = loaded.analyze()
    reference = figures(drive)
    assert (ours.stability.verdict == "stable") == reference["stable"]
    _compare(ours.to_dict(), reference)
    p = LoopParameters.from_config(loaded.params)
    # the Padé-6 closed loop's poles (the stability verdicts' polynomials)
    mine, theirs = np.sort_complex(our_poles(p, 6)), np.sort_complex(closed_loop_poles(drive, 6))
    assert mine.size == theirs.size
    np.testing.assert_allclose(mine, theirs, rtol=1e-7, atol=1e-6)
    # ... and the characteristic polynomial of the whole loop has them as roots (its degree,
    # its Routh verdict)
    whole = np.trim_zeros(list(loop_polynomials(p, 6).values())[-1][0], "f")
    assert whole.size - 1 == theirs.size
    assert np.sum(np.roots(whole).real > 0) == np.sum(theirs.real > 0)
    # python-control's systems (state space from the structure) = the responses, Padé-6
    omega = np.geomspace(1.0, 1e5, 40)
    reference = loops.responses(loops.Selector(p)(), 1j * omega, delay=DelayModel(6))
    model = linear_model(p, 6)
    # 1e-7 relative, and 1e-12 of the response's largest magnitude absolute: the state
    # space's rounding is absolute, so T at 1e5 rad/s (1e-11 of its DC gain) is 1.3e-7 off
    # relative (1.4e-18 absolute) on an AVX2 CPU
    for name in build(p).names:
        np.testing.assert_allclose(np.squeeze(getattr(model, name)(1j * omega)),
                                   reference.loops[name], rtol=1e-7,
                                   atol=1e-12 * np.max(np.abs(reference.loops[name])))
    np.testing.assert_allclose(np.squeeze(model.closed_loop(1j * omega)),
                               reference.closed_loop, rtol=1e-7,
                               atol=1e-12 * np.max(np.abs(reference.closed_loop)))
    # the compiled grid responses = numpy's
    compiled = grid_responses(loops.Selector(p)(column=True), omega, 1, EXACT)
    exact = loops.responses(loops.Selector(p)(), 1j * omega)
    for name in ("current_loop", "position_loop", "closed_loop"):
        np.testing.assert_allclose(np.squeeze(getattr(compiled, name)),
                                   np.squeeze(getattr(exact, name)), rtol=1e-12)


# ------------------------------------------------------------------------------ sampled

def _tf(block_filter):
    """(num, den) of one of MEASUREMENT_FILTERS, for the oracle (in s, highest power first)."""
    w0 = float(block_filter.frequency[0])
    if block_filter.kind == "lowpass1":
        return (1.0,), (1.0 / w0, 1.0)
    zeta = float(block_filter.damping[0])
    return (w0 * w0,), (1.0, 2.0 * zeta * w0, w0 * w0)


def _oracle_drive(filters):
    """The oracle's drive with ``filters`` (those at one point in series)."""
    by_point = {}
    for f in filters:
        num, den = by_point.get(f.at, ((1.0,), (1.0,)))
        f_num, f_den = _tf(f)
        by_point[f.at] = (tuple(np.polymul(num, f_num)), tuple(np.polymul(den, f_den)))
    none = ((1.0,), (1.0,))
    return dataclasses.replace(drive_of(QT_CAS), current_filter=by_point.get(
        "current_feedback", none), angle_filter=by_point.get("position_feedback", none))


def _sampled(p, omega):
    found = sampled.responses(loops.Selector(p)(), 1j * omega)
    return {"current_loop": found.current_loop, "position_loop": found.position_loop,
            "closed_loop": found.closed_loop}


def _relative(ours, theirs):
    return max(float(np.max(np.abs(theirs[k] - ours[k]) / np.abs(ours[k]))) for k in ours)


#: Double poles: a critically damped lowpass2, two equal lowpass1 in series.
DOUBLE_POLES = (Filter("current_feedback", "lowpass2", 2 * math.pi * 1e3, damping=1.0),
                Filter("position_feedback", "lowpass1", 2 * math.pi * 2e3),
                Filter("position_feedback", "lowpass1", 2 * math.pi * 2e3))


@pytest.mark.parametrize("filters, rates, method", [
    (MEASUREMENT_FILTERS, EPOS4, "backward"),
    (MEASUREMENT_FILTERS[:1], EPOS4, "tustin"),
    (MEASUREMENT_FILTERS[1:], (("current_loop", 25e3), ("position_loop", 25e3)), "backward"),
    (DOUBLE_POLES, EPOS4, "backward"),
], ids=["both", "angle-tustin", "current-single-rate", "double-poles"])
def test_the_sampled_loops_hold_the_analog_filters_before_the_samplers(filters, rates, method):
    omega = np.geomspace(1.0, 0.999 * math.pi * rates[-1][1], 200)
    p = _params(filters=filters, sample_rates=rates, sampling_method=method)
    fast, ratio = 1.0 / rates[0][1], round(rates[0][1] / rates[-1][1])
    oracle = lifted(_oracle_drive(filters), fast, ratio, method)
    theirs = oracle.responses(omega)
    ours = _sampled(p, omega)
    assert _relative(ours, theirs) < 1e-9
    # the discrete-time poles (the stability verdicts) are the oracle's lifted system's
    poles = sampled_stability.loop_poles(p)["position_loop"][0]
    expected = oracle.poles()
    for pole in expected[np.abs(expected) > 1e-7]:
        assert np.min(np.abs(poles - pole)) < 1e-8 * max(1.0, abs(pole))
    # the filter is applied once, before the sampler: the loops differ by far more from the
    # filter applied (also) after it at the loop's equivalent s, or left out
    without = _sampled(_params(filters=(), sample_rates=rates, sampling_method=method), omega)
    assert _relative(without, theirs) > 1e-2
    for f in filters:
        name = ANALOG_POINTS[f.at]
        period = dict(rates)[name] ** -1
        x = sampled.equivalent_s(omega, period, method)
        num, den = _tf(f)
        twice = ours[name] * np.polyval(num, x) / np.polyval(den, x)
        assert np.max(np.abs(twice / theirs[name] - 1)) > 1e-2


def test_the_digital_sensor_of_a_sampled_loop_leaves_the_analog_filters_out():
    p = _params(sample_rates=EPOS4, sampling_method="backward")
    closings = state_space.closings(p, sampled=True)
    assert closings["current_loop"].sensor is None and closings["position_loop"].sensor is None
    # each loop reads its filtered signal, the rows after the plant's four
    assert closings["current_loop"].row >= 4 and closings["position_loop"].row >= 4
    # to_control's discrete systems are the responses (one more method: state space)
    model = linear_model(p)
    omega = np.array([30.0, 700.0, 3000.0])
    found = sampled.responses(loops.Selector(p)(), 1j * omega)
    for name in ("current_loop", "position_loop", "closed_loop"):
        system = getattr(model, name)
        values = np.squeeze(system(np.exp(1j * omega * system.dt)))
        expected = found.closed_loop if name == "closed_loop" else found.loops[name]
        np.testing.assert_allclose(values, expected, rtol=1e-10)


@pytest.mark.parametrize("rates", [(("current_loop", 20e3), ("velocity_loop", 20e3),
                                    ("position_loop", 20e3)),
                                   AXIS_RATES], ids=["single-rate", "multirate"])
def test_a_sampled_cascade_with_measurement_filters_in_state_space(rates):
    # the velocity loop between them: to_control's discrete systems (the plant augmented with
    # the filters, matrix exponentials, lifting) against the responses (modal split,
    # decimation sum), two methods, 1e-10 relative
    base = _params(AXIS, filters=())
    p = dataclasses.replace(base, filters=(*base.filters, *MEASUREMENT_FILTERS),
                            sample_rates=rates, sampling_method="tustin")
    model = linear_model(p)
    omega = np.array([3.0, 30.0, 300.0, 3000.0])
    found = sampled.responses(loops.Selector(p)(), 1j * omega)
    for name in ("current_loop", "velocity_loop", "position_loop", "closed_loop"):
        system = getattr(model, name)
        values = np.squeeze(system(np.exp(1j * omega * system.dt)))
        expected = found.closed_loop if name == "closed_loop" else found.loops[name]
        np.testing.assert_allclose(values, expected, rtol=1e-10)


def test_a_filter_pole_on_a_plant_pole_is_a_config_error_naming_the_loop():
    # F's part needs (p_i I - A_f) invertible: a lowpass1 exactly at the plant's real pole
    p = _params(filters=(), sample_rates=EPOS4, sampling_method="backward")
    poles = sampled.plant_modes(loops.Selector(p)()).poles.reshape(-1)
    real = poles[(np.abs(poles.imag) < 1e-9 * np.abs(poles)) & (poles.real < 0)].real
    p = dataclasses.replace(p, filters=(Filter("current_feedback", "lowpass1", -real[0]),))
    with pytest.raises(ConfigError, match="an analog filter on current_loop's measurement has "
                       "a pole at one of the plant's"):
        sampled.plant_modes(loops.Selector(p)())


def test_a_batch_of_sampled_runs_is_each_run_alone():
    # per-run filter frequencies, plants and current-loop delays (the fractional part of
    # tau_c differs: 1.5, 1.25 and 2 samples): the batch's responses are each run's alone
    base = _params(sample_rates=EPOS4, sampling_method="backward").take([0, 0, 0])
    filters = tuple(f.replace(frequency=f.frequency * np.array([1.0, 0.5, 2.0]))
                    for f in base.filters)
    batch = dataclasses.replace(base, filters=filters).replace(
        tau_c=np.array([60e-6, 50e-6, 80e-6]), J=base.J * np.array([1.0, 1.2, 0.9]))
    omega = np.geomspace(1.0, 0.999 * math.pi * 2.5e3, 50)
    together = sampled.responses(loops.Selector(batch)(column=True), 1j * omega)
    for run in range(3):
        alone = _sampled(batch.take([run]), omega)
        for name in ("current_loop", "position_loop"):
            np.testing.assert_allclose(together.loops[name][run], alone[name], rtol=1e-12)
        np.testing.assert_allclose(together.closed_loop[run], alone["closed_loop"], rtol=1e-12)
    assert abs(together.position_loop[1, -1] / together.position_loop[0, -1] - 1) > 1e-2


# ---------------------------------------------------------------------------- simulation

@pytest.mark.parametrize("config, variant, sampling", [
    (QT_CAS, "base", {}), (QT_CAS, "sampled", {}), (AXIS, "base", {}),
    (AXIS, "base", dict(sample_rates=AXIS_RATES, sampling_method="tustin"))],
    ids=["qt_cas", "qt_cas_sampled", "cascade_axis", "cascade_axis_sampled"])
def test_both_engines_agree_with_measurement_filters(config, variant, sampling):
    shipped = LoopParameters.from_config(load_variant(config, variant).params).filters
    p = _params(config, variant, filters=(*shipped, *MEASUREMENT_FILTERS), **sampling)
    compiled, reference = (simulate_batch(p, Step(math.radians(2.0)), t_end=0.006,
                                          extend=False, engine=engine)
                           for engine in ("compiled", "reference"))
    _assert_same(compiled, reference)
    # the filters act: the same step without them differs
    plain = simulate_batch(_params(config, variant, filters=shipped, **sampling),
                           Step(math.radians(2.0)), t_end=0.006, extend=False)
    assert np.max(np.abs(plain.i - compiled.i)) > 1e-3 * np.max(np.abs(plain.i))


@pytest.mark.parametrize("variant, rates", [("base", {}),
                                            ("sampled", dict(current_rate_hz=25e3,
                                                             position_rate_hz=2.5e3))])
def test_the_small_sine_dwell_is_the_linear_closed_loop(variant, rates):
    # 0.002 deg: below every limit (tests/test_sampled_analysis.py); up to ~3/4 of the
    # position loop's half Nyquist frequency (3927 rad/s)
    filters = (Filter("position_feedback", "lowpass1", 2 * math.pi * 1e3),
               Filter("current_feedback", "lowpass2", 2 * math.pi * 8e3, damping=0.7))
    p = _params(variant=variant, filters=filters)
    omega = np.array([300.0, 3000.0])
    dwell = sine_dwell(p, [math.radians(0.002)], omega, **rates)
    assert not dwell.limit_hit.any()
    linear = linear_reference(p, omega)
    np.testing.assert_allclose(dwell.magnitude_db[0], 20 * np.log10(np.abs(linear)), atol=0.05)
    np.testing.assert_allclose(dwell.phase_deg[0], np.degrees(np.unwrap(np.angle(linear))),
                               atol=0.3)
    # the filters move T here by 5 % and more, ten times the tolerance (0.05 dB and 0.3 deg
    # are 0.6 % and 0.5 %): the test can fail
    plain = linear_reference(_params(variant=variant, filters=()), omega)
    assert np.min(np.abs(linear / plain - 1)) > 0.05


# ------------------------------------------------------------------- nothing else moves

#: analyze's position PM [deg], GM [dB], current PM [deg], bandwidth [rad/s] and the step's
#: last output [rad] and current at step 100 [A] (1 deg, 10 ms), printed by the commit before
#: the measurement filters (7df52db).
PINS = {
    ("qt_cas.yaml", "base"): ((34.715520266494806, 8.3492509075378, 63.410779091994264,
                               1385.3408656716704), (0.018107520282221228, 6.876428806840313)),
    ("qt_cas.yaml", "sampled"): ((22.035816528991226, 5.022682415676265, 53.210494565714185,
                                  1277.1367977399755), (0.015884199367397857,
                                                        5.7673322369444415)),
    ("cascade_axis.yaml", "base"): ((87.12008535275989, 17.655926118214072, 44.42286865111193,
                                     42.63809247804237), (0.006563473731189943,
                                                          6.049447691669238)),
}


@pytest.mark.parametrize("config, variant", list(PINS))
def test_without_the_new_points_the_figures_are_bit_identical(config, variant):
    figures_, step = PINS[(config, variant)]
    found = cf.load(ROOT / "configs" / config, variant=variant).analyze().to_dict()
    got = (found["position_loop"]["phase_margin_deg"], found["position_loop"]["gain_margin_db"],
           found["current_loop"]["phase_margin_deg"], found["closed_loop"]["bandwidth_rad_s"])
    # the sampled responses were regrouped after 7df52db (the loops multiplied out once per
    # batch): the same arithmetic in another order, 2e-15 relative on the current loop's PM;
    # and the probes at corners of ln L (narrow notches) split some brackets since, so the same
    # roots end on another last iterate of the refinement, up to 2e-14 relative (a GM, a PM)
    assert got == pytest.approx(figures_, rel=1e-13)
    p = LoopParameters.from_config(load_variant(ROOT / "configs" / config, variant).params)
    run = simulate_batch(p, Step(math.radians(1.0)), t_end=0.01, extend=False)
    # bit-identical on the CPU the pins were printed on; another x86-64 CPU's SIMD paths
    # (numpy's and numba's, AVX2 against AVX-512) move the last bits: 2.6e-15 relative measured
    assert (float(run.delta[0, -1]), float(run.i[0, 100])) == pytest.approx(step, rel=1e-13)

