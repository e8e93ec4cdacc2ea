"""The simulator's shortcuts give bit-for-bit the results of the general code they skip.

The engine tells the controllers where the command does not jump (the same array passed as
left and right limit), the controllers skip ``integrate_with_anti_windup`` where no output is
near its limit, and the delay line hands out both limits at once. Each shortcut must return
exactly (not to a tolerance) what the general path returns: clamp flags where an output rests
at its limit depend on the last bit.
"""

import numpy as np
import pytest

from cas_freq.simulation.controllers import Controller, integrate_with_anti_windup
from cas_freq.simulation.delay_line import DelayLine

N_RUNS = 5


def _controller(sampled, kd):
    rng = np.random.default_rng(7)
    kp = rng.uniform(2.0, 8.0, N_RUNS)
    ki = rng.uniform(0.0, 60.0, N_RUNS)
    kd = np.full(N_RUNS, kd)
    return Controller(kp, ki, kd, np.full(N_RUNS, 6e-4), np.full(N_RUNS, 2.0), 5e-6 * (
        80 if sampled else 1
    ), sampled=sampled)


def _errors(n_updates):
    # Errors that drive the outputs into the clamp and out again (amplitude 1 vs limit 2/kp).
    rng = np.random.default_rng(3)
    t = np.arange(n_updates)[:, None]
    return np.sin(2 * np.pi * t / 400 + rng.uniform(0, 6, N_RUNS)) + 0.01 * rng.normal(
        size=(n_updates, N_RUNS)
    )


@pytest.mark.parametrize("sampled", [False, True])
@pytest.mark.parametrize("kd", [0.0, 0.02])
def test_controller_shortcuts_are_exact(sampled, kd):
    # Same inputs three ways: the same array as both limits (shortcut), equal copies (general
    # path), and a hand-made update that always calls integrate_with_anti_windup.
    fast, general = _controller(sampled, kd), _controller(sampled, kd)
    errors = _errors(1200)
    fast.start(errors[0], errors[0])
    general.start(errors[0], errors[0].copy())
    clamped_updates = 0
    for e in errors[1:]:
        before = (general.integral, general._e, general._rest)
        ff = 0.1 * e
        u_fast = fast.update(e, e, ff_left=ff, ff_right=ff)
        u_general = general.update(e, e.copy(), ff_left=ff, ff_right=ff.copy())
        for a, b in zip(u_fast, u_general, strict=True):
            assert np.array_equal(a, b)
        assert np.array_equal(fast.integral, general.integral)
        # The integral is what the anti-windup function gives, bit for bit (the output's other
        # terms at the end of the update are the new right limit's: no jump here).
        expected = integrate_with_anti_windup(
            before[0], before[1], e, before[2], general._rest, general.ki, general.limit,
            general.period, locate=not sampled, backward=general.backward,
        )
        assert np.array_equal(general.integral, expected)
        clamped_updates += bool(u_general[2].any())
    assert clamped_updates > 50  # the clamp was exercised


@pytest.mark.parametrize("hold", [False, True])
@pytest.mark.parametrize("delays", [[60e-6] * 4, [60e-6, 62.5e-6, 0.0, 3e-6]])
def test_delay_line_read_limits_equal_reads(hold, delays):
    # read_limits returns (read(k), read(k, left=True)), the same array only where they are
    # equal; samples with and without jumps, uniform and per-run (fractional) delays.
    dt = 5e-6
    line = DelayLine(np.array(delays), dt, hold=hold)
    rng = np.random.default_rng(11)
    for k in range(60):
        right = rng.normal(size=4)
        left = right if k % 3 else right + 1.0
        line.push(k, right, left)
        for q in (k, k + 1):
            pair = line.read_limits(q)
            assert np.array_equal(pair[0], line.read(q))
            assert np.array_equal(pair[1], line.read(q, left=True))
            if pair[0] is pair[1]:
                assert np.array_equal(line.read(q), line.read(q, left=True))
