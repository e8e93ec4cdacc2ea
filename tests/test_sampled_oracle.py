"""Checks of the independent reference tests/sampled_oracle.py (issue 26).

The oracle is checked against itself by different methods (the aliasing sum, the exact
fractional-delay state space, python-control's sample_system, a first-order case worked out by
hand, the lifted multirate system against the decimation sum and against the single-rate
composition) and, in the continuous limit, against `cas-freq analyze` (the Python API's
``analyze``, the same figures).
"""

import math
from pathlib import Path

import control
import numpy as np
import pytest
from sampled_oracle import (
    continuous_margins,
    controllers,
    current_voltage_to_current,
    delay_tf,
    drive_of,
    evaluate,
    evaluate_ss,
    fast_position_plant,
    first_order_modified_z,
    hold_equivalent,
    hold_equivalent_by_aliasing,
    lifted,
    plant_matrices,
    plant_ss,
    replace,
    sampled_margins,
    samples,
    single_rate,
    voltage_to_angle,
)

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
QT_CAS = CONFIGS / "qt_cas.yaml"
DC_SERVO = CONFIGS / "dc_servo.yaml"


def _rel(a, b):
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b)) / np.abs(b)))


@pytest.fixture(scope="module")
def base():
    return drive_of(QT_CAS, "base")


def test_samples_rounds_only_floating_noise():
    """ceil(tau/T) in samples, an exact multiple not pushed to the next sample by rounding
    ((0.1 + 0.2)/0.1 is 3.0000000000000004 in floating point: 3 samples, not 4); a real
    fraction rounds up (60 us at 25 kHz: 2 samples)."""
    assert (0.1 + 0.2) / 0.1 > 3
    assert samples(0.1 + 0.2, 0.1) == 3
    assert samples(0.4e-3, 4e-5) == 10
    assert samples(0.06e-3, 4e-5) == 2
    assert samples(0.0, 4e-5) == 0
    assert samples(0.2e-3, 4e-5) == 5


# ---------------------------------------------------------------- item 2 (a): integer delay

def test_hold_equivalents_with_an_integer_delay_equal_sample_system(base):
    """tau = 3 T: the exact hold-equivalent (the fractional-delay state space with e = 0) and
    the aliasing sum both equal control.sample_system(plant, T, 'zoh') times z^-3, for V -> i
    (relative degree 1: the slowest aliasing sum) and V -> theta (relative degree 3).

    Tolerances: the two exact methods to 1e-10 (rounding in expm and the solves); the aliasing
    sum within its own tail bound plus rounding (1e-10 relative), the bound itself < 1e-3
    relative (K = 20000; an integer delay is its worst case: every term adds)."""
    period = 20e-6
    a, b, c = plant_matrices(base)
    omega = np.geomspace(10.0, 0.999 * math.pi / period, 40)
    reference = control.series(control.ss(delay_tf(3, period)),
                               control.sample_system(plant_ss(base), period, "zoh"))
    ad, bd, cd = hold_equivalent(a, b, c, period, 3 * period)
    z = np.exp(1j * omega * period)
    for row, g, degree in ((0, current_voltage_to_current(base), 1),
                           (1, voltage_to_angle(base), 3)):
        expected = evaluate(reference[row, 0], omega)
        assert _rel(evaluate_ss(ad, bd, cd[row:row + 1], 0.0, z), expected) < 1e-10
        value, tail = hold_equivalent_by_aliasing(g, period, 3 * period, omega,
                                                  relative_degree=degree)
        assert np.all(np.abs(value - expected) <= tail + 1e-10 * np.abs(expected))
        assert np.max(tail / np.abs(expected)) < 1e-3


# ------------------------------------------------------------- item 2 (b): fractional delay

@pytest.mark.parametrize("tau_over_t", [0.0, 0.3, 1.5, 2.75])
def test_first_order_with_a_fractional_delay_equals_the_hand_formula(tau_over_t):
    """G = 1/(s + a), a = 3000 1/s, T = 40 us, tau = (0, 0.3, 1.5, 2.75) T: the modified
    z-transform worked out by hand (sampled_oracle.first_order_modified_z) equals the exact
    fractional-delay state space to 1e-12, and the aliasing sum (K = 20000) to within its tail
    bound plus rounding (1e-10 relative). The bound is < 1e-3 relative; the actual error is
    < 2e-5 with tau = 0 (every term adds, the worst case) and < 1e-7 with a fractional delay
    (the phases e^{-j 2 pi k tau/T} make the tail cancel)."""
    a_pole, period = 3000.0, 40e-6
    tau = tau_over_t * period
    omega = np.geomspace(1.0, 0.999 * math.pi / period, 30)
    z = np.exp(1j * omega * period)
    hand = first_order_modified_z(a_pole, period, tau, z)
    ad, bd, cd = hold_equivalent(np.array([[-a_pole]]), np.array([[1.0]]), np.array([[1.0]]),
                                 period, tau)
    assert _rel(evaluate_ss(ad, bd, cd, 0.0, z), hand) < 1e-12
    value, tail = hold_equivalent_by_aliasing(lambda s: 1.0 / (s + a_pole), period, tau, omega)
    assert np.all(np.abs(value - hand) <= tail + 1e-10 * np.abs(hand))
    assert np.max(tail / np.abs(hand)) < 1e-3
    assert _rel(value, hand) < (2e-5 if tau_over_t == 0 else 1e-7)


def test_aliasing_sum_of_the_current_loop_with_tau_c_one_and_a_half_samples(base):
    """The QT-CAS voltage -> current at 25 kHz with tau_c = 60 us = 1.5 samples (the EPOS4
    case): the aliasing sum against the exact fractional-delay state space, within its tail
    bound, the bound < 5e-4 relative up to 0.999 of the Nyquist frequency and < 1e-6 below a
    tenth of it, the actual error < 1e-8 (as its docstring states)."""
    period = 40e-6
    a, b, c = plant_matrices(base)
    omega = np.geomspace(1.0, 0.999 * math.pi / period, 40)
    ad, bd, cd = hold_equivalent(a, b, c[:1], period, base.tau_c)
    exact = evaluate_ss(ad, bd, cd, 0.0, np.exp(1j * omega * period))
    value, tail = hold_equivalent_by_aliasing(current_voltage_to_current(base), period,
                                              base.tau_c, omega)
    assert np.all(np.abs(value - exact) <= tail + 1e-10 * np.abs(exact))
    assert np.max(tail / np.abs(exact)) < 5e-4
    low = omega < 0.1 * math.pi / period
    assert np.max(tail[low] / np.abs(exact[low])) < 1e-6
    assert _rel(value, exact) < 1e-8


# ------------------------------------------------------------------------- the controllers

def test_controllers_are_the_substitutions():
    """The discrete PID is the continuous one with s replaced: backward s -> (z - 1)/(T z),
    evaluated here directly from the continuous formula; tustin s -> (2/T)(z - 1)/(z + 1),
    also python-control's own sample_system(C, T, 'tustin'). To 1e-11: rounding, where
    z - 1 at the lowest frequency (omega T = 4e-4) keeps only eps / (omega T) = 5.6e-13 of
    relative precision, used a few times (1.26e-12 measured on an AVX2 CPU); the same 1e-11
    against python-control's normalised coefficients."""
    d = drive_of(QT_CAS, "base")
    period = 400e-6
    omega = np.geomspace(1.0, 0.99 * math.pi / period, 50)
    z = np.exp(1j * omega * period)

    def pid(s):
        return d.cp_Kp + d.cp_Ki / s + d.cp_Kd * s / (d.Tf * s + 1)

    continuous = control.tf([d.cp_Kd + d.cp_Kp * d.Tf, d.cp_Kp + d.cp_Ki * d.Tf, d.cp_Ki],
                            [d.Tf, 1.0, 0.0])
    for method, s in (("backward", (z - 1) / (period * z)),
                      ("tustin", 2 / period * (z - 1) / (z + 1))):
        c_i, c_p, c_r = controllers(d, period, period, method)
        assert _rel(evaluate(c_p, omega), pid(s)) < 1e-11
        assert _rel(evaluate(c_i, omega), d.ci_Kp + d.ci_Ki / s) < 1e-11
        assert c_r is c_p                               # derivative on the error
    tustin = control.sample_system(continuous, period, "tustin")
    assert _rel(evaluate(controllers(d, period, period, "tustin")[1], omega),
                evaluate(tustin, omega)) < 1e-11
    on_measurement = controllers(replace(d, derivative_on_measurement=True), period, period)
    assert _rel(evaluate(on_measurement[2], omega),
                d.cp_Kp + d.cp_Ki * period * z / (z - 1)) < 1e-12


# ---------------------------------------------------------------- item 3: the lifted system

@pytest.mark.parametrize("config, variant, period, method", [
    (QT_CAS, "base", 20e-6, "backward"), (QT_CAS, "fitted", 20e-6, "tustin"),
    (DC_SERVO, "base", 50e-6, "backward")])
def test_lifted_with_ratio_one_equals_the_single_rate_composition(config, variant, period,
                                                                  method):
    """Ratio 1: the lifted system (exact hold-equivalent state space, the closed current loop
    and the delay register written out by hand) equals the single-rate composition
    (sample_system, z^-d transfer functions, control.series/feedback): every response to 1e-9
    relative (both exact; rounding in two different realisations) and the same closed-loop
    poles (the largest |z| to 1e-9), all inside the unit circle."""
    d = drive_of(config, variant)
    omega = np.geomspace(1.0, 0.999 * math.pi / period, 200)
    one, two = single_rate(d, period, method), lifted(d, period, 1, method)
    ours, theirs = one.responses(omega), two.responses(omega)
    for key in ours:
        assert _rel(ours[key], theirs[key]) < 1e-9, key
    assert abs(max(abs(one.poles())) - max(abs(two.poles()))) < 1e-9
    assert one.stable() and two.stable()


def test_lifted_equals_the_decimation_sum(base):
    """The lifted slow plant (A^M, sum A^i B) against the decimation sum of the shared design,
    P(e^{jwT_s}) = (1/M) sum_{k<M} H_M(z_k) G(z_k), z_k = e^{j(w + 2 pi k/T_s) T_f},
    H_M(z) = sum_{i<M} z^-i, with G the fast position plant: two formulas of the same
    sampled system, to 1e-9 relative."""
    fast, ratio = 40e-6, 10
    slow = fast * ratio
    omega = np.geomspace(1.0, 0.999 * math.pi / slow, 60)
    fast_plant, _ = fast_position_plant(base, fast)
    k = np.arange(ratio)
    z_k = np.exp(1j * (omega[:, None] + 2 * math.pi * k[None, :] / slow) * fast)
    hold = sum(z_k ** -i for i in range(ratio))
    g = evaluate_ss(fast_plant.A, fast_plant.B, fast_plant.C, 0.0, z_k)
    decimated = np.sum(hold * g, axis=1) / ratio
    assert _rel(evaluate(lifted(base, fast, ratio).plant_p, omega), decimated) < 1e-9


def test_an_unstable_rate_is_a_result():
    """The same loop at a slow enough rate is unstable, and the oracle says so from the poles
    (a pole outside the unit circle, |z| = 1.093) with a negative phase margin (-12.9 deg)
    rather than failing: the QT-CAS base position loop at 625 Hz (ratio 40) with the current
    loop at 25 kHz. At 1 kHz (ratio 25) it is still stable, PM 3.8 deg, GM 0.80 dB."""
    d = drive_of(QT_CAS, "base")
    loops = lifted(d, 40e-6, 40)
    assert not loops.stable()
    assert max(abs(loops.poles())) > 1.05
    assert sampled_margins(loops.position, points=800).phase_margin_deg < -10
    assert lifted(d, 40e-6, 25).stable()


# ------------------------------------------------------------------ the continuous limit

def test_sampled_margins_approach_the_continuous_ones(base):
    """At T = 20 us and 10 us (single rate, tau_c = 3 and 6 samples, tau_p = 20 and 40) the
    sampled margins of L_i and L_p differ from the continuous ones of `cas-freq analyze` by
    a first-order term in T: the difference halves with T (ratio 2 +- 10 %) and the phase
    margins lie within one sample of phase at the crossover (w_c T in degrees: the hold alone
    costs half of it). The oracle's own continuous margins equal analyze's to 1e-7."""
    from cas_freq import api

    figures = api.load(QT_CAS, "base").analyze().to_dict()
    continuous = continuous_margins(base)
    for loop in ("current_loop", "position_loop"):
        assert continuous[loop].phase_margin_deg == pytest.approx(
            figures[loop]["phase_margin_deg"], rel=1e-7)
        assert continuous[loop].gain_margin_db == pytest.approx(
            figures[loop]["gain_margin_db"], rel=1e-7)
    differences = []
    for period in (20e-6, 10e-6):
        loops = single_rate(base, period)
        for loop, system in (("current_loop", loops.current), ("position_loop",
                                                               loops.position)):
            m = sampled_margins(system, points=1500)
            dpm = m.phase_margin_deg - figures[loop]["phase_margin_deg"]
            dgm = m.gain_margin_db - figures[loop]["gain_margin_db"]
            assert abs(dpm) < math.degrees(figures[loop]["crossover_rad_s"] * period)
            differences.append((dpm, dgm))
    coarse, fine = differences[:2], differences[2:]
    for (pm_coarse, gm_coarse), (pm_fine, gm_fine) in zip(coarse, fine, strict=True):
        assert pm_coarse / pm_fine == pytest.approx(2.0, rel=0.1)
        assert gm_coarse / gm_fine == pytest.approx(2.0, rel=0.1)


@pytest.mark.filterwarnings("ignore:Badly conditioned filter coefficients")
def test_margins_equal_python_control_where_it_is_reliable(base):
    """The oracle's margins (root finding on the exact responses) against
    control.stability_margins on the single-rate QT-CAS loops at 50 kHz, and its responses
    against control.frequency_response. python-control's discrete margins go through
    polynomials (or, warning of inaccuracy, an interpolated FRD): on the 50 kHz L_p its FRD
    fallback agrees to 1e-4 deg / 1e-4 dB, which is the tolerance here; on the multirate L_p
    (19 states at 2.5 kHz) its polynomial method returns no phase margin at all (PM inf),
    which is why the oracle finds the crossings itself (its polynomial conversion also warns
    of badly conditioned coefficients here, ignored)."""
    loops = single_rate(base, 20e-6)
    omega = np.geomspace(1.0, 0.99 * math.pi / 20e-6, 50)
    with pytest.warns(UserWarning, match="frd"):
        gm, pm, _, w180, wc, _ = control.stability_margins(loops.position)
    ours = sampled_margins(loops.position, points=1500)
    assert ours.phase_margin_deg == pytest.approx(pm, abs=1e-4)
    assert ours.crossover_rad_s == pytest.approx(wc, rel=1e-5)
    assert ours.gain_margin_db == pytest.approx(20 * math.log10(gm), abs=1e-4)
    assert ours.phase_crossover_rad_s == pytest.approx(w180, rel=1e-5)
    for system in (loops.current, loops.position):
        response = control.frequency_response(system, omega).complex
        assert _rel(evaluate(system, omega), response) < 1e-12
