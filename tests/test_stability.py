"""Closed-loop poles (numpy state space) against python-control's Padé model of the same loops.

Reference: :func:`cas_freq.analysis.systems.linear_model`, built with python-control from the
same blocks by a different route (transfer-function sections, ``interconnect``/``feedback``).

Tolerance of the pole comparison: an eigenvalue of a balanced matrix is computed with an
absolute error of about eps * ||A|| * kappa (kappa its condition number). ||A|| is set by the
largest poles (the Padé poles of the 0.06 ms current delay, up to ~2e5 rad/s at n = 10), so the
small poles (~10 rad/s) carry the largest *relative* error. Measured: at most 1.4e-10 relative,
per pole, over every case here (orders 2, 6, 10); the test allows 1e-8 relative per pole plus
1e-12 of the largest pole magnitude (for poles near 0), which is ~70x the measured spread and
still far below any difference that could move a pole across the imaginary axis.
"""

import dataclasses
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from cas_freq.analysis.stability import (
    closed_loop_poles,
    closed_loop_stability,
    current_loop_poles,
    loop_polynomials,
    pole_verdict,
)
from cas_freq.analysis.systems import linear_model
from cas_freq.config import load_variant
from cas_freq.core.filters_config import Filter
from cas_freq.core.parameters import LoopParameters

ORDERS = (2, 6, 10)
RTOL = 1e-8  # per pole; see the module docstring
ATOL_OF_LARGEST = 1e-12  # absolute, as a fraction of the largest pole magnitude


def assert_same_poles(actual, expected):
    """Match two pole sets one-to-one (optimal assignment) and compare each pair."""
    actual = np.asarray(actual, dtype=complex)
    expected = np.asarray(expected, dtype=complex)
    assert actual.shape == expected.shape, (actual.size, expected.size)
    rows, cols = linear_sum_assignment(np.abs(actual[:, None] - expected[None, :]))
    scale = ATOL_OF_LARGEST * np.max(np.abs(expected))
    error = np.abs(actual[rows] - expected[cols])
    allowed = RTOL * np.abs(expected[cols]) + scale
    assert np.all(error <= allowed), np.max(error / allowed)


def _random_overrides(rng, variant):
    """Gains scaled 0.3..3x (log-uniform) and both delays 0..1 ms around a shipped variant."""
    base = load_variant(None, variant).params
    scale = lambda: float(np.exp(rng.uniform(np.log(0.3), np.log(3.0))))  # noqa: E731
    return [
        ("current_loop.Kp", base.current_loop.Kp * scale()),
        ("current_loop.Ki", base.current_loop.Ki * scale()),
        ("position_loop.Kp", base.position_loop.Kp * scale()),
        ("position_loop.Ki", base.position_loop.Ki * scale()),
        ("position_loop.Kd", base.position_loop.Kd * scale()),
        ("current_loop.delay", float(rng.uniform(0.0, 1e-3))),
        ("position_loop.delay", float(rng.uniform(0.0, 1e-3))),
    ]


def _cases():
    rng = np.random.default_rng(20261122)
    cases = [("base", ()), ("fitted", ()),
             ("base", (("position_loop.derivative_on", "measurement"),))]
    for index in range(20):
        variant = ("base", "fitted")[index % 2]
        cases.append((variant, tuple(_random_overrides(rng, variant))))
    return cases


CASES = _cases()


@pytest.mark.parametrize(("variant", "overrides"), CASES)
def test_poles_match_python_control_model(variant, overrides):
    params = load_variant(None, variant, list(overrides)).params
    for order in ORDERS:
        model = linear_model(params, order)
        expected = model.closed_loop.poles()
        stability = closed_loop_stability(params, order)
        poles = np.array([complex(*p) for p in stability.poles])
        assert len(poles) == 2 * order + 6  # plant 3, PI 1, PID 2, two Padé delays
        assert_same_poles(poles, expected)
        assert np.all(np.diff(poles.real) <= 0)  # sorted by real part, largest first
        assert stability.verdict == pole_verdict(expected)
        assert stability.pade_order == order
        current = model.current_closed_loop.poles()
        assert_same_poles(current_loop_poles(params, order), current)
        assert stability.current_loop_verdict == pole_verdict(current)


def test_random_variants_cover_both_verdicts():
    # The random set is only a meaningful check of the verdict if it holds both outcomes
    # (delays up to 1 ms, 2.5x the shipped 0.4 ms, make most of them unstable).
    verdicts = {
        closed_loop_stability(load_variant(None, v, list(o)).params, 6).verdict for v, o in CASES
    }
    assert verdicts >= {"stable", "unstable"}


@pytest.mark.parametrize("variant", ["base", "fitted"])
def test_frictionless_motor_has_no_spurious_marginal_pole(variant):
    # mu_v = 0: Y = Js/D has a zero at s = 0 that cancels the PI integrator in L_i. The whole
    # loop sees that mode through theta (all 2n + 6 poles, as python-control finds); the current
    # loop alone must not report it (python-control's unminimised T_i keeps a pole at ~0).
    params = load_variant(None, variant, [("motor.mu_v", "0 N*m*s/rad")]).params
    for order in ORDERS:
        model = linear_model(params, order)
        stability = closed_loop_stability(params, order)
        assert stability.verdict == "stable"
        assert stability.current_loop_verdict == "stable"
        assert_same_poles(closed_loop_poles(params, order), model.closed_loop.poles())
        reference = model.current_closed_loop.poles()
        at_zero = np.abs(reference) < 1e-6
        assert at_zero.sum() == 1  # the cancelled mode, in python-control's realisation
        assert_same_poles(current_loop_poles(params, order), reference[~at_zero])


@pytest.mark.parametrize(
    ("key", "extra"),
    [("position_loop.Ki", "closed"), ("current_loop.Ki", "both")],
)
def test_zero_integral_gain_drops_the_integrator(key, extra):
    # Ki = 0 leaves C = Kp s/s in the shared (num, den) form that python-control realises
    # without cancelling: its model has one extra pole at exactly 0; ours must not.
    params = load_variant(None, "base", [(key, 0.0)]).params
    model = linear_model(params, 6)
    stability = closed_loop_stability(params, 6)
    assert stability.verdict == "stable"
    assert stability.current_loop_verdict == "stable"
    reference = model.closed_loop.poles()
    assert_same_poles(closed_loop_poles(params, 6), reference[np.abs(reference) > 1e-9])
    current = model.current_closed_loop.poles()
    if extra == "both":
        current = current[np.abs(current) > 1e-9]
    assert_same_poles(current_loop_poles(params, 6), current)


@pytest.mark.parametrize(
    "overrides",
    [[("position_loop.Kd", 0.0)], [("position_loop.Kp", 20 * 6.3435)]],
    ids=["Kd=0", "Kp_x20"],
)
def test_unstable_variants_are_reported_unstable(overrides):
    params = load_variant(None, "base", overrides).params
    for order in ORDERS:
        stability = closed_loop_stability(params, order)
        assert stability.verdict == "unstable"
        assert stability.poles[0][0] > 0
        assert_same_poles(closed_loop_poles(params, order), linear_model(params, order)
                          .closed_loop.poles())


def test_derivative_on_measurement_keeps_the_poles():
    # Only the reference path changes (docs/model.md); python-control builds that model by a
    # separate interconnect, so this also checks its realisation.
    error = load_variant(None, "fitted").params
    measurement = load_variant(None, "fitted", [("position_loop.derivative_on",
                                                 "measurement")]).params
    for order in ORDERS:
        assert_same_poles(closed_loop_poles(measurement, order),
                          linear_model(measurement, order).closed_loop.poles())
        assert_same_poles(closed_loop_poles(measurement, order), closed_loop_poles(error, order))


@pytest.mark.parametrize("config", ["qt_cas.yaml", "cascade_axis.yaml"])
def test_current_loop_poles_are_its_polynomials_roots_with_a_current_filter(config):
    # A filter on the measured current is part of the current loop: its poles are the roots of
    # the current loop's characteristic polynomial (the verdict's, the recurrence of
    # cas_freq.model.structure in polynomials: another route), two more than without it.
    root = Path(__file__).resolve().parents[1] / "configs"
    base = LoopParameters.from_config(load_variant(root / config).params)
    filtered = dataclasses.replace(base, filters=(
        *base.filters, Filter("current_feedback", "lowpass2", 2 * math.pi * 12e3, damping=0.6)))
    for order in ORDERS:
        polynomial = loop_polynomials(filtered, order)["current_loop"][0]
        roots = np.roots(np.trim_zeros(polynomial, "f"))
        poles = current_loop_poles(filtered, order)
        assert_same_poles(poles, roots)
        assert poles.size == current_loop_poles(base, order).size + 2


def test_analysis_path_imports_neither_control_nor_matplotlib():
    code = (
        "import sys\n"
        "from cas_freq.analysis.analyze import analyze\n"
        "from cas_freq.config import load_variant\n"
        "for variant in ('base', 'fitted'):\n"
        "    analysis = analyze(load_variant(None, variant))\n"
        "    assert analysis.stability.verdict == 'stable', analysis.stability\n"
        "loaded = sorted(m for m in sys.modules if m.split('.')[0] in ('control', 'matplotlib'))\n"
        "assert not loaded, loaded\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
