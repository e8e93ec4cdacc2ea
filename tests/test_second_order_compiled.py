"""The compiled iteration of the second-order fit against the numpy iteration, bit for bit.

:func:`second_order._levenberg_marquardt_compiled` with :func:`fit_kernel.refine` (what
:func:`fit_second_order_batch` runs with the compiled engine) does, run by run, the operations of
:func:`second_order._levenberg_marquardt` with :func:`second_order._refine` (the numpy iteration
the fits were first computed with) in the same order, with numpy's rounding rules (its clip and
maximum, einsum's and norm's order of summation, LAPACK's solve and eigvalsh) and numpy's own
power for the one function whose last bit numpy computes differently from libm. Both take their
sums from the same compiled kernel, so the estimates are expected EQUAL, not close: any
difference would move the ~1e-12 to which the Newton steps pin a minimum, and the full-precision
means of ``montecarlo --json`` with it.

The runs: an overdamped step with a delay (the shipped actuator's: zeta ~ 2), an overshooting one,
zeta = 1 exactly (the power series), a delay at its bound 0, a first-order step (unidentifiable:
zeta runs off and the iteration limit stops it, not converged), a flat response, noisy copies,
the same runs stopped after 3 iterations (not converged: a result, success False) and an
infinite response (a stuck run: its system is not finite).
"""

import math

import numpy as np
import pytest

from cas_freq.config import load_variant
from cas_freq.core.jit import use_compiled
from cas_freq.core.parameters import variant_parameters
from cas_freq.simulation import Step, second_order, simulate_batch
from cas_freq.simulation.second_order import (
    fit_second_order_batch,
    second_order_step,
)

pytestmark = pytest.mark.skipif(not use_compiled(), reason="numba is not importable")


def _runs():
    """(t, unit response) of the cases of the module docstring, 400-1200 samples each."""
    rng = np.random.default_rng(30)
    runs = []
    for wn, zeta, td, samples in [(1000.0, 2.0, 1.2e-3, 1200), (462.0, 0.3, 2e-3, 900),
                                  (300.0, 1.0, 1e-3, 700), (600.0, 0.8, 0.0, 500)]:
        t = np.linspace(0.0, td + 15.0 / wn, samples)
        clean = second_order_step(t, wn, zeta, td)
        runs += [(t, clean), (t, clean + 0.01 * rng.standard_normal(t.size))]
    t = np.linspace(0.0, 0.2, 400)
    runs += [(t, 1.0 - np.exp(-30.0 * t)), (t, np.zeros_like(t))]
    # and many drawn ones, so that the damping updates go through many values: with 10 runs
    # a libm cube instead of numpy's happened to change nothing
    t = np.linspace(0.0, 0.03, 800)
    for wn, zeta, td in zip(rng.uniform(400, 1200, 40), rng.uniform(0.3, 2.5, 40),
                            rng.uniform(0.0, 2e-3, 40), strict=True):
        runs.append((t, second_order_step(t, wn, zeta, td) + 0.003 * rng.standard_normal(t.size)))
    return runs


def _padded(runs):
    """The padded arrays, starts, scales and upper bounds _fit_block iterates on."""
    k, m = len(runs), max(t.size for t, _ in runs)
    t_pad, unit_pad = np.zeros((k, m)), np.zeros((k, m))
    x0, scale, upper = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
    for i, (t, unit) in enumerate(runs):
        t_pad[i, :t.size], unit_pad[i, :t.size] = t, unit
        x0[i], scale[i], upper[i] = second_order._start(t, unit)
    return t_pad, unit_pad, x0, scale, upper


def _both(t, unit, x0, scale, upper, max_iterations):
    """(numpy iteration, compiled iteration): each (p, converged, refined p, cost, J^T J)."""
    from cas_freq.simulation.fit_kernel import refine

    # (numpy warns of the stuck run's inf - inf; the compiled iteration computes it silently)
    with np.errstate(invalid="ignore", over="ignore"):
        p, converged = second_order._levenberg_marquardt(t, unit, x0, scale, upper,
                                                         max_iterations)
        refined = second_order._refine(t, unit, p, scale, upper)
        cost, normal, _ = second_order._normal_equations_at(t, unit, refined, scale)
    numpy_iteration = (p, converged, refined, cost, normal)
    p, converged, cost, normal, gradient = second_order._levenberg_marquardt_compiled(
        t, unit, x0, scale, upper, max_iterations)
    compiled = (p, converged, *refine(t, unit, p, scale, upper, cost, normal, gradient,
                                      second_order._REFINE_STEPS))
    return numpy_iteration, compiled


@pytest.mark.parametrize("max_iterations", [second_order._MAX_ITERATIONS, 3])
def test_the_compiled_iteration_is_the_numpy_iteration(max_iterations):
    data = _padded(_runs())
    numpy_iteration, compiled = _both(*data, max_iterations)
    for expected, got in zip(numpy_iteration, compiled, strict=True):
        np.testing.assert_array_equal(got, expected)  # bit for bit (NaN equal to NaN)
    converged = numpy_iteration[1]
    if max_iterations == 3:  # stopped early: not converged, still estimates
        assert not converged.any() and np.isfinite(compiled[2]).all()
    else:
        # the first-order step does not converge (its zeta runs off to ~1e7 and wn with it,
        # only wn / (2 zeta) is determined): it reaches the iteration limit, success False
        assert list(converged) == [True] * 8 + [False] + [True] * 41
        # the cases are what they claim: overdamped, overshooting, zeta = 1, td at 0
        refined = compiled[2]
        assert refined[0, 1] == pytest.approx(2.0, rel=1e-9)
        assert refined[2, 1] == pytest.approx(0.3, rel=1e-9)
        assert refined[4, 1] == pytest.approx(1.0, rel=1e-9)
        assert refined[6, 2] == 0.0
        assert refined[8, 1] > 1e3


def test_the_same_on_simulated_steps():
    # 10 deg steps of 128 variants of the shipped actuator (motor.Km, motor.J and
    # current_loop.delay drawn as montecarlo --tolerance motor.Km=10% --tolerance motor.J=10%
    # --tolerance current_loop.delay=0.01ms draws them), strided as the
    # fit strides them: the Monte Carlo's fits, where a libm cube instead of numpy's changes
    # the iteration's estimates (the analytic runs above happened not to show it)
    loaded = load_variant()
    rng = np.random.default_rng(7)
    n = 128
    changes = {key: value * (1.0 + 0.1 / 3.0 * rng.standard_normal(n))
               for key, value in (("motor.Km", loaded.params.motor.Km),
                                  ("motor.J", loaded.params.motor.J))}
    changes["current_loop.delay"] = (loaded.params.current_loop.delay
                                     + 1e-5 / 3.0 * rng.standard_normal(n))
    amplitude = math.radians(10.0)
    result = simulate_batch(variant_parameters(loaded.params, changes), Step(amplitude))
    runs = [second_order._strided_unit_step(result.t, result.delta[run], amplitude,
                                            second_order.MAX_FIT_POINTS, "test")
            for run in range(n)]
    numpy_iteration, compiled = _both(*_padded(runs), second_order._MAX_ITERATIONS)
    for expected, got in zip(numpy_iteration, compiled, strict=True):
        np.testing.assert_array_equal(got, expected)


def test_a_stuck_run_is_a_result_in_both():
    # A response that is not finite (which _fit_block screens out as diverged; an overflowing
    # Jacobian does the same): its gradient is NaN, the damped system is not finite, and the
    # run stops at its start, not converged, beside a normal run.
    runs = _runs()[:1]
    t = runs[0][0]
    runs.append((t, np.full(t.size, np.inf)))
    data = _padded(runs)
    numpy_iteration, compiled = _both(*data, second_order._MAX_ITERATIONS)
    for expected, got in zip(numpy_iteration, compiled, strict=True):
        np.testing.assert_array_equal(got, expected)
    assert list(compiled[1]) == [True, False]


def test_a_fit_that_does_not_converge_reports_it():
    # Through the public batch: 3 iterations are too few, the fit is returned with success
    # False and finite estimates, not raised
    t, unit = _runs()[1]
    fit, = fit_second_order_batch([t], [unit * 0.2], 0.2, max_iterations=3)
    assert not fit.success
    assert all(math.isfinite(v) for v in (fit.wn_rad_s, fit.zeta, fit.td_s, fit.rms_residual))


def _sums_in_python(t, unit, p, scale):
    """The compiled kernel's sums of one run, in plain Python floats (IEEE doubles, libm's exp,
    cos and sin, as numba's), in its order, but computing the overdamped step's fast decay
    e^{-(beta + zeta) s} at every sample (the kernel leaves it out where it cannot count)."""
    wn, zeta, td = p[0] * scale[0], p[1], p[2] * scale[2]
    q = 1.0 - zeta * zeta
    root = math.sqrt(abs(q))
    d_wn, d_td = scale[0], -(wn * scale[2])
    sums = [0.0] * 10  # r r, J J^T (00 01 02 11 12 22), J r (0 1 2)
    for tj, uj in zip(t, unit, strict=True):
        tau = max(tj - td, 0.0)
        s = wn * tau
        x = q * s * s
        if abs(x) < 1.0:
            series = []
            for coefficients in (second_order.C_SERIES, second_order.S_SERIES,
                                 second_order.D_SERIES):
                total = float(coefficients[-1])
                for c in coefficients[-2::-1]:
                    total = total * -x + float(c)
                series.append(total)
            decay = math.exp(-zeta * s)
            ec, es, ed = decay * series[0], decay * s * series[1], decay * (s * s * s) * series[2]
        elif q > 0.0:
            decay = math.exp(-zeta * s)
            ec = decay * math.cos(root * s)
            es = decay * math.sin(root * s) / root
            ed = (s * ec - es) / q
        else:
            slow = math.exp(s * (-1.0 / (root + zeta)))
            fast = math.exp(-(root + zeta) * s)
            ec = 0.5 * (slow + fast)
            es = (0.5 / root) * (slow - fast)
            ed = (s * ec - es) / q
        r = (1.0 - (ec + zeta * es)) - uj
        j = (es * tau * d_wn, ed, es * d_td)
        terms = (r * r, j[0] * j[0], j[0] * j[1], j[0] * j[2], j[1] * j[1], j[1] * j[2],
                 j[2] * j[2], j[0] * r, j[1] * r, j[2] * r)
        sums = [total + term for total, term in zip(sums, terms, strict=True)]
    return sums


def test_the_kernels_sums_leave_out_only_what_cannot_count():
    # The overdamped step's fast decay is left out where it is below 2^-54 of the slow one
    # (fit_kernel.FAST_NEGLIGIBLE): the sums must equal, bit for bit, those computing it at
    # every sample. Runs over zeta from just above 1 (the decays close: never left out) to 5,
    # with s = wn (t - td) up to ~300 (left out from s = 40 / (beta + zeta - 1 / (beta + zeta)),
    # 3 to 40), one underdamped run, td > 0 (the first samples at s = 0: the series, whose
    # value the kernel takes without Horner's steps there), and zeta = 1 (the series at every
    # sample, at x = 0).
    from cas_freq.simulation.fit_kernel import normal_equations_of

    rng = np.random.default_rng(5)
    zetas = [1.02, 1.3, 2.0, 5.0, 0.6, 1.0]
    t = np.linspace(0.0, 0.3, 500)
    k = len(zetas)
    p = np.column_stack([np.ones(k), zetas, np.full(k, 1.0)])
    scale = np.column_stack([np.full(k, 1000.0), np.ones(k), np.full(k, 1.5e-3)])
    unit = np.array([second_order_step(t, 1000.0 * (1 + 0.05 * rng.standard_normal()), zeta,
                                       1.4e-3) for zeta in zetas])
    t_all = np.tile(t, (k, 1))
    cost, normal, gradient = normal_equations_of(t_all, unit, np.arange(k), p, scale)
    for run in range(k):
        sums = _sums_in_python(t, unit[run], p[run], scale[run])
        got = [cost[run], *normal[run][np.triu_indices(3)], *gradient[run]]
        assert got == sums, zetas[run]


@pytest.mark.slow  # run by .ci/run: numba compiles the fallback in every process (~4 s)
def test_the_public_solve_fallback_gives_the_helpers_solution():
    # fit_kernel reaches LAPACK's dgesv through numba's private helper; a numba without it
    # takes numba's public np.linalg.solve instead (the same dgesv). Reference: the helper's
    # solution, to the bit, and both report a singular system.
    from cas_freq.core.jit import cached_jit
    from cas_freq.simulation import fit_kernel

    fallback = cached_jit(nogil=True)(fit_kernel._solve_by_numpy)
    rng = np.random.default_rng(30)
    for system in [*rng.standard_normal((4, 3, 3)), np.ones((3, 3))]:
        rhs = rng.standard_normal(3)
        ours, theirs = np.empty(3), np.empty(3)
        info = fit_kernel._solve(system, rhs, ours)
        assert (fallback(system, rhs, theirs) != 0) == (info != 0)
        if info == 0:
            np.testing.assert_array_equal(theirs, ours)
