"""Loop transfer functions: the numpy factor products against python-control state space."""

import control
import numpy as np
import pytest

from cas_freq.analysis.systems import exact_frequency_responses, linear_model, plant_system
from cas_freq.config import load_variant
from cas_freq.core.parameters import LoopParameters
from cas_freq.model import ActuatorLoops, DelayModel, parts

LOOPS = ("current_loop", "current_closed_loop", "position_loop", "sensitivity", "closed_loop")
OMEGA = np.logspace(-1, 5.5, 60)  # [rad/s] covers every loop's crossover and beyond


@pytest.fixture(scope="module", params=["base", "fitted"])
def params(request):
    return load_variant(variant=request.param).params


def test_plant_factors_follow_the_differential_equations(params):
    # Y = i/V and M = theta/i written out from docs/model.md's equations must equal the 3-state
    # plant's transfer functions (same equations in state space); rounding-level tolerance.
    # Both come from cas_freq.model.parts: the polynomials Z_e = Ls + R, D = s (Js + mu_v)
    # (mechanics, unloaded) and the state matrices, written separately there; they must describe
    # the same plant.
    p = LoopParameters.from_config(params)
    plant = plant_system(params)
    s = 1j * OMEGA
    response = plant(s)  # (3 outputs, 1 input, n)
    motor = params.motor
    mu = motor.viscous_friction
    y = (motor.J * s + mu) / ((motor.L * s + motor.R) * (motor.J * s + mu) + motor.Ke * motor.Km)
    np.testing.assert_allclose(response[0, 0], y, rtol=1e-10)
    np.testing.assert_allclose(response[2, 0] / response[0, 0],
                               motor.Km / (s * (motor.J * s + mu)), rtol=1e-10)
    d, n_theta, _ = parts.mechanics(p)
    assert n_theta == (1.0,)
    d = parts.polyval(d, s)
    y_parts = d / (parts.polyval(parts.electrical(p), s) * d + parts.back_emf_coupling(p) * s)
    np.testing.assert_allclose(y_parts, y, rtol=1e-12)


def test_pid_factor_is_parallel_form(params):
    loop = params.position_loop
    s = 1j * OMEGA
    tf = loop.Kd / (10 * loop.Kp)  # docs/model.md default filter constant
    expected = loop.Kp + loop.Ki / s + loop.Kd * s / (tf * s + 1)
    p = LoopParameters.from_config(params)
    numerator = parts.polyval(parts.position_controller(p), s)
    actual = numerator / (s * parts.polyval(parts.position_filter(p), s))
    np.testing.assert_allclose(actual, expected, rtol=1e-12)


@pytest.mark.parametrize("order", [1, 8, 10])
@pytest.mark.parametrize("derivative_on", ["error", "measurement"])
def test_state_space_composition_equals_factor_product(order, derivative_on):
    # Two ways of composing the same loops: python-control state space (series/feedback/
    # interconnect of the blocks) and the product of low-order factors. They are the same
    # algebra, so they must agree to rounding: 1e-8 relative, and an absolute 1e-14 of the
    # response's largest magnitude for S, which is ~1e-8 at the lowest frequency, where the
    # rounding of 1 + L (~1e-16 absolute) is ~1e-8 relative (1.2e-8 measured at Padé 10 on an
    # AVX2 CPU, 2.2e-16 absolute).
    params = load_variant(overrides=[("position_loop.derivative_on", derivative_on)]).params
    model = linear_model(params, order)
    loops = ActuatorLoops(params, DelayModel(order))
    for name in LOOPS:
        expected = getattr(loops, name)(1j * OMEGA)
        np.testing.assert_allclose(
            getattr(model, name)(1j * OMEGA), expected, rtol=1e-8,
            atol=1e-14 * np.max(np.abs(expected)), err_msg=name,
        )


def test_state_space_models_are_minimal_and_stable():
    # The closed loop's states: plant (3) + current PI (1) + position PID (2) + both delays.
    params = load_variant().params
    for order in (1, 10):
        model = linear_model(params, order)
        assert model.closed_loop.nstates == 3 + 1 + 2 + 2 * order
        assert np.all(np.isfinite(model.closed_loop.A))
        assert np.max(model.closed_loop.poles().real) < 0
        # minimal: no pole is cancelled by a zero (a cancelled pole at 0 once slipped in here)
        assert np.min(np.abs(model.closed_loop.poles())) > 1.0


def test_closed_loop_dc_gain_is_one():
    # docs/model.md: T(0) = 1 (the plant integrates, so the loop has zero steady-state error).
    for derivative_on in ("error", "measurement"):
        params = load_variant(overrides=[("position_loop.derivative_on", derivative_on)]).params
        model = linear_model(params, 4)
        assert control.dcgain(model.closed_loop) == pytest.approx(1.0, rel=1e-9)


def test_derivative_on_measurement_changes_only_the_reference_path():
    base = ActuatorLoops(load_variant().params)
    measured = ActuatorLoops(
        load_variant(overrides=[("position_loop.derivative_on", "measurement")]).params
    )
    s = 1j * OMEGA
    np.testing.assert_allclose(measured.position_loop(s), base.position_loop(s), rtol=1e-14)
    np.testing.assert_allclose(measured.sensitivity(s), base.sensitivity(s), rtol=1e-14)
    assert not np.allclose(measured.closed_loop(s), base.closed_loop(s))


def test_closed_loop_is_complementary_sensitivity():
    loops = ActuatorLoops(load_variant().params)
    s = 1j * OMEGA
    np.testing.assert_allclose(loops.closed_loop(s) + loops.sensitivity(s), 1, atol=1e-12)


def test_exact_frequency_response_objects():
    loops = ActuatorLoops(load_variant().params)
    frds = exact_frequency_responses(loops, OMEGA)
    assert set(frds) == set(LOOPS)
    for name, frd in frds.items():
        assert isinstance(frd, control.FrequencyResponseData)
        np.testing.assert_allclose(frd.frdata[0, 0], getattr(loops, name)(1j * OMEGA))


def test_tf_option_is_used():
    params = load_variant(overrides=[("position_loop.Tf", "0.2 ms")]).params
    assert params.position_loop.filter_time_constant == pytest.approx(2e-4)


@pytest.mark.parametrize("derivative_on", ["error", "measurement"])
def test_feedforward_closed_loop(derivative_on):
    # With i_ff = F theta_cmd added to the controller output (docs/model.md), theta = P((C_r + F)
    # theta_cmd - C_p theta) with P = e^(-s tau_p) T_i M, so theta/theta_cmd = T (1 + F/C_r)
    # where T is the closed loop without feed-forward. Same algebra: rounding tolerance.
    params = load_variant(overrides=[("position_loop.derivative_on", derivative_on)]).params
    loops = ActuatorLoops(params)
    s = 1j * OMEGA
    loop = params.position_loop
    feedforward = loop.ff_v * s + loop.ff_a * s**2
    tf = loop.filter_time_constant
    reference = (loop.Kp + loop.Ki / s) if derivative_on == "measurement" else (
        loop.Kp + loop.Ki / s + loop.Kd * s / (tf * s + 1)
    )
    np.testing.assert_allclose(
        loops.closed_loop(s, feedforward=True),
        loops.closed_loop(s) * (1 + feedforward / reference),
        rtol=1e-10,
    )
