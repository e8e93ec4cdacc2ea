"""Second-order-plus-delay model (report §7): closed form and least-squares fit."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from cas_freq.simulation import fit_second_order, second_order_step

WN, ZETA, TD = 462.0, 0.54, 2e-3  # the report's fit to the bench step (§7, docs/model.md)


@pytest.mark.parametrize("zeta", [0.0, 0.3, 0.999, 1.0, 1.001, 2.0, 5.0])
def test_closed_form_matches_ode(zeta):
    # The ODE x'' = -wn^2 x - 2 zeta wn x' + wn^2 u(t - td), integrated by solve_ivp at
    # rtol 1e-12: the closed form agrees to rounding (found 3e-13), across zeta = 1.
    def rhs(_, x):
        return [x[1], -WN**2 * x[0] - 2 * zeta * WN * x[1] + WN**2]

    sol = solve_ivp(rhs, [0, 0.06], [0.0, 0.0], rtol=1e-12, atol=1e-14, dense_output=True)
    t = np.linspace(0.0, 0.06, 601)
    ode = np.where(t > TD, sol.sol(np.clip(t - TD, 0.0, 0.06))[0], 0.0)
    assert np.max(np.abs(second_order_step(t, WN, zeta, TD) - ode)) < 1e-9


@pytest.mark.parametrize("method", ["lm", "least_squares"])
def test_fit_recovers_report_model_and_bandwidth(method):
    # Noise-free synthetic step of the report's (462 rad/s, 0.54, 2 ms): recovered to 1e-3
    # relative (the requirement; found ~1e-12), by either optimiser. Closed-form bandwidth of
    # 462/0.54: 566 rad/s (report §7).
    t = np.arange(0.0, 0.06, 1e-5)
    step = math.radians(10.0)
    fit = fit_second_order(t, step * second_order_step(t, WN, ZETA, TD), step, method=method)
    assert fit.success
    assert fit.wn_rad_s == pytest.approx(WN, rel=1e-3)
    assert fit.zeta == pytest.approx(ZETA, rel=1e-3)
    assert fit.td_s == pytest.approx(TD, rel=1e-3)
    assert fit.rms_residual < 1e-9 * step
    assert round(fit.bandwidth_closed_form_rad_s) == 566


def test_fit_with_noise_confidence_intervals():
    # White noise of 1 % of the step on the report's model. One noisy fit: values within 1 % and
    # intervals narrower than 2 % of the value; residual RMS = the noise level (5 % for its
    # sampling spread over 6000 points). Then coverage over 100 seeds: a ~95 % interval must
    # hold the true value in 88..100 of them (binomial sd 2.2 at p = 0.95; 88 is 3 sd below;
    # found 93-95 % over 200 seeds).
    t = np.arange(0.0, 0.06, 1e-5)
    clean = second_order_step(t, WN, ZETA, TD)
    fit = fit_second_order(t, clean + 0.01 * np.random.default_rng(0).standard_normal(t.size), 1.0)
    truth = ((WN, fit.wn_rad_s, fit.wn_ci_rad_s), (ZETA, fit.zeta, fit.zeta_ci),
             (TD, fit.td_s, fit.td_ci_s))
    for value, fitted, (low, high) in truth:
        assert fitted == pytest.approx(value, rel=0.01)
        assert 0 < high - low < 0.02 * value
    assert fit.rms_residual == pytest.approx(0.01, rel=0.05)
    hits = np.zeros(3)
    for seed in range(100):
        noise = 0.01 * np.random.default_rng(seed).standard_normal(t.size)
        fit = fit_second_order(t, clean + noise, 1.0)
        intervals = (fit.wn_ci_rad_s, fit.zeta_ci, fit.td_ci_s)
        pairs = zip((WN, ZETA, TD), intervals, strict=True)
        hits += [low <= value <= high for value, (low, high) in pairs]
    assert np.all(hits >= 88), hits


@pytest.mark.parametrize("method", ["lm", "least_squares"])
@pytest.mark.parametrize("zeta, td", [(1.0, 1e-3), (1.8, 0.5e-3), (0.2, 0.0)])
def test_fit_other_damping_cases(zeta, td, method):
    # Critically damped, overdamped and lightly damped with no delay (td at its bound 0), from
    # the default initial guess, by either optimiser; recovered to 1e-3 (td absolutely, to 1e-3
    # of 1/wn).
    t = np.arange(0.0, 0.05, 1e-5)
    fit = fit_second_order(t, -2.0 * second_order_step(t, 300.0, zeta, td), -2.0, method=method)
    assert fit.wn_rad_s == pytest.approx(300.0, rel=1e-3)
    assert fit.zeta == pytest.approx(zeta, rel=1e-3)
    assert fit.td_s == pytest.approx(td, abs=1e-3 / 300.0)


def test_fit_rejects_bad_input():
    with pytest.raises(ValueError, match="step"):
        fit_second_order(np.arange(5.0), np.arange(5.0), 0.0)
    with pytest.raises(ValueError, match="same length"):
        fit_second_order(np.arange(5.0), np.arange(4.0), 1.0)
