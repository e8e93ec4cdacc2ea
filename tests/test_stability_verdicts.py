"""Stability verdicts (Routh arrays of the Padé characteristic polynomials, many variants at
once) against the poles of python-control's model, and the root refiners.

Reference: the poles of :func:`cas_freq.analysis.systems.linear_model`, built with python-control
from the same blocks by another route (transfer-function sections, ``interconnect``/
``feedback``), judged by :func:`cas_freq.analysis.stability.pole_verdict`; the verdicts must
agree exactly.
"""

import math

import numpy as np
import pytest

from cas_freq.analysis.margins import phase_jumps
from cas_freq.analysis.roots import refine_maxima, refine_roots
from cas_freq.analysis.stability import (
    characteristic_polynomials,
    closed_loop_poles,
    current_loop_poles,
    pole_verdict,
    stability_verdicts,
)
from cas_freq.analysis.systems import linear_model
from cas_freq.config import load_variant
from cas_freq.core.parameters import variant_parameters


def python_control_verdicts(params, order=6):
    """(whole loop, current loop) verdicts from python-control's poles."""
    model = linear_model(params, order)
    return (pole_verdict(model.closed_loop.poles()),
            pole_verdict(model.current_closed_loop.poles()))


def test_verdicts_match_python_control_across_stable_and_unstable():
    loaded = load_variant()
    # Kp from 2 to 200 A/rad crosses the position loop's stability limit (between 60 and 100
    # by the single path); current-loop Kp up to 3 V/A crosses the current loop's (GM ~9.7 dB
    # at 0.62 V/A, i.e. x3.05).
    kp = np.array([2.0, 6.3435, 15.0, 60.0, 100.0, 200.0, 6.3435, 6.3435])
    ci = np.array([0.6163, 0.6163, 0.6163, 0.6163, 0.6163, 0.6163, 1.5, 3.0])
    changes = {"position_loop.Kp": kp, "current_loop.Kp": ci}
    verdict, current = stability_verdicts(variant_parameters(loaded.params, changes))
    for i in range(kp.size):
        reference = python_control_verdicts(
            load_variant(None, "base", [("position_loop.Kp", float(kp[i])),
                                        ("current_loop.Kp", float(ci[i]))]).params)
        assert (verdict[i], current[i]) == reference, i
    assert "unstable" in set(verdict) and "stable" in set(verdict)


@pytest.mark.parametrize("overrides", [
    [("current_loop.Ki", 0.0)],       # C_i = Kp: no integrator
    [("position_loop.Ki", 0.0)],      # C_p without integrator
    [("position_loop.Kd", 0.0), ("position_loop.Tf", 0.001)],  # Kd = 0 drops the filter
    [("motor.mu_v", 0.0)],            # pole of C_i cancels the zero of Y at 0 (current loop)
    [("position_loop.derivative_on", "measurement")],
])
def test_exact_cancellations_give_the_verdict_of_the_poles(overrides):
    # python-control's model keeps the cancelled modes (e.g. the integrator pole at 0 with
    # mu_v = 0 in the current loop), so the reference is our own block matrix's poles, which
    # test_stability.py checks against python-control's where both are minimal.
    loaded = load_variant(None, "base", overrides)
    params = variant_parameters(loaded.params, {})
    verdict, current = stability_verdicts(params)
    assert verdict[0] == pole_verdict(closed_loop_poles(params, 6))
    assert current[0] == pole_verdict(current_loop_poles(params, 6))


def test_characteristic_polynomial_roots_are_the_padé_model_poles():
    loaded = load_variant()
    _, q = characteristic_polynomials(variant_parameters(loaded.params, {}), 6)
    roots = np.sort_complex(np.roots(q[0]))
    poles = np.sort_complex(linear_model(loaded.params, 6).closed_loop.poles())
    assert roots.size == poles.size
    # np.roots of a degree-18 polynomial spanning 1..1e5 rad/s: 1e-6 relative is what its
    # conditioning allows.
    np.testing.assert_allclose(roots, poles, rtol=1e-6)


def test_vectorised_refiners_on_known_functions():
    # roots of sin(x) in brackets around pi and 2 pi; maximum of -(x - 1)^2 at 1
    lo, hi = np.array([3.0, 6.0]), np.array([3.3, 6.5])
    roots = refine_roots(lambda x, j: np.sin(x), lo, hi)
    np.testing.assert_allclose(np.log(roots), [math.pi, 2 * math.pi], rtol=1e-12)
    where, value = refine_maxima(lambda x, j: -(x - 1.0) ** 2, np.array([0.5]), np.array([1.7]))
    assert np.log(where[0]) == pytest.approx(1.0, abs=1e-8)
    assert value[0] == pytest.approx(0.0, abs=1e-15)


def test_phase_jumps_are_where_numpy_unwrap_adds_turns():
    # random walks around the origin, with steps large enough to jump often
    rng = np.random.default_rng(11)
    u = np.cumsum(rng.normal(size=(50, 400)) + 1j * rng.normal(size=(50, 400)), axis=1)
    expected = np.abs(np.diff(np.angle(u), axis=1)) > math.pi
    np.testing.assert_array_equal(phase_jumps(u), expected)


def _mixed_cascade_batch():
    """40 variants of the cascade whose blocks realise to different state counts: velocity
    and position integrators on and off, zero and nonzero delays (shared and per run), the
    speed filter on and off, two coupling stiffnesses."""
    rng = np.random.default_rng(7)
    n = 40
    params = load_variant("configs/cascade_axis.yaml").params

    def some(value, other):
        return np.where(rng.uniform(size=n) < 0.3, other, value)

    return variant_parameters(params, {
        "position_loop.Kp": 40.0 * rng.uniform(0.5, 1.5, n),
        "velocity_loop.Kp": 1.3 * rng.uniform(0.5, 1.5, n),
        "velocity_loop.Ki": some(15.0, 0.0), "position_loop.Ki": some(100.0, 0.0),
        "velocity_loop.delay": some(1e-4, 0.0),
        "current_loop.delay": rng.choice([0.0, 5e-5, 6e-5], n),
        "velocity_loop.feedback_filter": some(2e-4, 0.0),
        "gear.stiffness": some(2000.0, 1000.0),
    })


def test_batched_poles_are_the_poles_of_each_run_to_the_bit():
    # A batch's ambiguous Routh verdicts come from closed_loop_poles_of_runs (stacked state
    # matrices, one eigenvalue call per group of runs that realise alike). Reference: the
    # one-run path, closed_loop_poles of each run alone; every product in the assembly has
    # an inner dimension of 1 and LAPACK sees the same matrix, so they must be equal exactly
    # (the verdicts then cannot depend on the runs beside a run, e.g. on the chunking).
    from cas_freq.analysis.stability import _sorted, closed_loop_poles_of_runs

    for p in (_mixed_cascade_batch(),
              variant_parameters(load_variant().params,
                                 {"position_loop.Kp": np.array([4.0, 6.3, 60.0, 200.0]),
                                  "position_loop.Ki": np.array([0.0, 5.0, 5.0, 0.0]),
                                  "position_loop.Kd": np.array([0.0, 0.05, 0.0, 0.05])})):
        batch = closed_loop_poles_of_runs(p, 6)
        sizes = set()
        for run, poles in enumerate(batch):
            alone = closed_loop_poles(p.run(run), 6)
            sizes.add(alone.size)
            np.testing.assert_array_equal(_sorted(poles), alone)
        assert len(sizes) > 1  # the batch mixes state counts


def test_roots_of_rows_are_numpys_roots_and_verdicts_agree_run_by_run():
    # _roots_of_rows (the inner loops' ambiguous verdicts): the companion matrices np.roots
    # builds, stacked; equal rows solved once. Reference: np.roots of each row, exactly; and
    # the batch's verdicts equal those of each run analysed alone.
    from cas_freq.analysis.stability import _roots_of_rows, loop_polynomials, loop_verdicts

    p = _mixed_cascade_batch()
    for polynomials in loop_polynomials(p, 6).values():
        repeated = np.vstack([polynomials, polynomials[:5]])
        for row, roots in zip(repeated, _roots_of_rows(repeated), strict=True):
            np.testing.assert_array_equal(roots, np.roots(np.trim_zeros(row, "f")))
    together = loop_verdicts(p, 6)
    for run in range(p.n_runs):
        alone = loop_verdicts(p.run(run), 6)
        assert {k: v[run] for k, v in together.items()} == {k: v[0] for k, v in alone.items()}


def _poles_verdicts(polynomials):
    return [pole_verdict(np.roots(np.trim_zeros(row, "f"))) for row in polynomials]


def test_routh_with_error_bounds_agrees_with_the_roots_or_defers_to_them():
    # The Routh verdict decides only where every first-column sign is clear of its running
    # error bound. Reference: the verdict of numpy's roots of polynomials built from known
    # roots: well separated (decided by Routh, and equal to the roots' verdict), spread over
    # five decades like the cascade's (decided or deferred, never wrong), and with a pair
    # exactly on the imaginary axis (marginal: the first column has an exact zero there, which
    # rounding turns into noise within the bound, so Routh must defer).
    from cas_freq.analysis.routh import verdicts

    rng = np.random.default_rng(25)
    cases = []
    for spread in (1.0, 5.0):
        for _ in range(200):
            magnitude = 10.0 ** rng.uniform(0, spread, 5)
            angle = rng.uniform(0.05, 0.95, 5) * np.pi / 2
            sign = np.where(rng.uniform(size=5) < 0.1, 1.0, -1.0)  # one in ten unstable
            pairs = magnitude * (sign * np.cos(angle) + 1j * np.sin(angle))
            cases.append(np.real(np.poly(np.concatenate([pairs, pairs.conj(), [-1.0]]))))
    on_axis = np.real(np.poly([1j * 30.0, -1j * 30.0, -2.0, -5.0 + 40j, -5.0 - 40j,
                               -7.0 + 9j, -7.0 - 9j, -50.0, -60.0, -70.0, -80.0]))
    polynomials = np.vstack(cases + [on_axis])
    deferred = []

    def fallback(rows):
        deferred.extend(rows)
        return _poles_verdicts(polynomials[rows])

    got = verdicts(polynomials, fallback)
    expected = _poles_verdicts(polynomials)
    assert list(got) == expected
    assert len(polynomials) - 1 in deferred  # the pair on the axis
    assert expected[-1] == "marginal"
    assert not set(deferred) & set(range(200))  # one decade apart: Routh decides them all
    assert {"stable", "unstable"} <= set(expected[:200])


def test_cascade_inner_loop_verdicts_are_decided_by_routh():
    # The velocity loop of configs/cascade_axis.yaml (degree 24, poles from 17 rad/s to
    # 3e5 rad/s) has first-column entries 1e-16 of their row's largest, which the former
    # relative test (1e-8 of the row) sent to the roots for every run, yet each is clear of its
    # rounding-error bound by a factor of over 1e5. Now Routh decides it, and agrees with the
    # roots (the former fallback) run by run.
    from cas_freq.analysis.routh import verdicts
    from cas_freq.analysis.stability import loop_polynomial_bounds

    p = variant_parameters(load_variant("configs/cascade_axis.yaml").params,
                           {"velocity_loop.Kp": np.linspace(0.5, 3.0, 12)})
    e, m = loop_polynomial_bounds(p, 6)["velocity_loop"]
    deferred = []
    got = verdicts(e, lambda rows: deferred.extend(rows) or _poles_verdicts(e[rows]), m)
    assert deferred == []
    assert list(got) == _poles_verdicts(e)
