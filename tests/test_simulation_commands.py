"""Fin commands: values, derivatives for the feed-forward, left/right limits, CSV input."""

import math

import numpy as np
import pytest

from cas_freq.config.loader import load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.simulation import (
    Chirp,
    Ramp,
    Sine,
    Step,
    Table,
    motor_command,
    read_command_csv,
    simulate,
)

A = math.radians(2.0)


def test_step_has_no_derivatives_and_jumps_at_start():
    # docs/model.md: a step has no usable derivative, so the feed-forward gets 0.
    step = Step(A, start_s=0.01)
    angle, rate, accel = step.fin(np.array([0.0, 0.01, 0.02]))
    assert np.array_equal(angle, [0.0, A, A])
    assert not rate.any() and not accel.any()
    assert step.fin(np.array([0.01]), left=True)[0][0] == 0.0


def test_ramp_with_stop():
    ramp = Ramp(2.0, start_s=0.1, stop_s=0.3)
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    angle, rate, _ = ramp.fin(t)
    assert np.allclose(angle, [0.0, 0.0, 0.2, 0.4, 0.4])
    assert np.array_equal(rate, [0.0, 2.0, 2.0, 0.0, 0.0])
    assert np.array_equal(ramp.fin(t, left=True)[1], [0.0, 0.0, 2.0, 2.0, 0.0])
    assert ramp.settles and ramp.final_rad() == pytest.approx(0.4)
    assert not Ramp(1.0).settles


@pytest.mark.parametrize("command", [
    Sine(A, 200.0, start_s=0.001),
    Chirp(A, 10.0, 2000.0, 0.05),
    Chirp(A, 10.0, 2000.0, 0.05, method="log"),
])
def test_rate_and_acceleration_are_derivatives(command):
    # Central differences at h = 1e-7 s: error ~ h^2 f'''/6 ~ 1e-9 relative at 2000 rad/s,
    # rounding ~ eps/h ~ 1e-9; tolerance 1e-6 of the derivative's scale.
    t = np.linspace(0.002, 0.045, 500)
    h = 1e-7
    angle, rate, accel = command.fin(t)
    forward, backward = command.fin(t + h), command.fin(t - h)
    assert np.allclose((forward[0] - backward[0]) / (2 * h), rate, atol=1e-6 * np.abs(rate).max())
    assert np.allclose((forward[1] - backward[1]) / (2 * h), accel,
                       atol=1e-6 * np.abs(accel).max())


def test_chirp_frequency_law_and_end():
    # The phase recovered from angle = sin(phase) and rate = w(t) cos(phase), with the sweep law
    # w(t) written out below, must grow at w(t): linear sweep at (10 + 2000)/2 halfway, log
    # sweep at the geometric mean sqrt(10 * 2000). np.gradient on 2e5 points: ~1e-6 relative;
    # tolerance 1e-4. After the sweep the angle holds and the rate is 0.
    for method, halfway in (("linear", 1005.0), ("log", math.sqrt(10.0 * 2000.0))):
        chirp = Chirp(1.0, 10.0, 2000.0, 0.05, method=method)
        t = np.linspace(0.0, 0.05, 200001)[:-1]  # the rate is 0 from the end on
        angle, rate, _ = chirp.fin(t)
        w = np.gradient(np.unwrap(np.arctan2(angle, rate / chirp_frequency(chirp, t))), t)
        assert w[len(t) // 2] == pytest.approx(halfway, rel=1e-4)
        assert np.allclose(w[1:-1], chirp_frequency(chirp, t)[1:-1], rtol=1e-4)
        after, end = chirp.fin(np.array([0.06])), chirp.fin(np.array([0.05]))
        assert after[0][0] == pytest.approx(end[0][0]) and after[1][0] == 0.0


def chirp_frequency(chirp, t):
    """The sweep law, written out independently of the implementation."""
    w0, w1, d = chirp.start_rad_s, chirp.stop_rad_s, chirp.duration_s
    if chirp.method == "linear":
        return w0 + (w1 - w0) * t / d
    return w0 * (w1 / w0) ** (t / d)


def test_chirp_rejects_bad_values():
    with pytest.raises(ConfigError, match="method"):
        Chirp(A, 1.0, 2.0, 1.0, method="cubic")
    with pytest.raises(ConfigError, match="start_rad_s"):
        Chirp(A, 0.0, 2.0, 1.0, method="log")
    with pytest.raises(ConfigError, match="duration_s"):
        Chirp(A, 1.0, 2.0, 0.0)


def test_motor_command_scales_by_gear_ratio():
    # docs/model.md: theta_cmd = N delta_cmd; a 10 deg fin step is 3.4907 rad at the motor.
    angle, rate, accel = motor_command(Sine(math.radians(10.0), 50.0), 20.0, np.array([0.01]))
    fin = Sine(math.radians(10.0), 50.0).fin(np.array([0.01]))
    assert np.allclose([angle, rate, accel], 20.0 * np.array(fin))
    assert motor_command(Step(math.radians(10.0)), 20.0, np.array([0.0]))[0][0] == pytest.approx(
        3.4907, abs=1e-4)


def test_csv_command(tmp_path):
    path = tmp_path / "cmd.csv"
    path.write_text("# a user command\ntime_s,fin_deg\n0,0\n0.01,2\n0.03,2\n0.04,-1\n")
    table = read_command_csv(path)
    assert isinstance(table, Table) and table.duration_s == pytest.approx(0.04)
    angle, rate, _ = table.fin(np.array([0.005, 0.02, 0.05]))
    assert np.allclose(angle, np.radians([1.0, 2.0, -1.0]))
    assert np.allclose(rate, np.radians([200.0, 0.0, 0.0]))
    # At a knot: the right limit is the next segment's slope, the left limit the previous one.
    assert table.fin(np.array([0.01]))[1][0] == 0.0
    assert table.fin(np.array([0.01]), left=True)[1][0] == pytest.approx(math.radians(200.0))
    run = simulate(load_variant().params, table, t_end=0.06, extend=False)
    assert run.command[-1] == pytest.approx(math.radians(-1.0))


@pytest.mark.parametrize("text, message", [
    ("0,0\n0.01,abc\n", "row 2: not numbers"),
    ("0,0\n0.01\n", "row 2: expected 2 columns"),
    ("0,0\n0.02,1\n0.01,1\n", "row 3: time 0.01 s does not increase"),
    ("0,0\n0.01,nan\n", "row 2: values must be finite"),
    ("-1,0\n0.01,1\n", "row 1: time must be >= 0"),
    ("t,deg\n0,1\n", "need at least 2 rows"),
])
def test_csv_errors_name_file_and_row(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=message) as info:
        read_command_csv(path)
    assert str(path) in str(info.value)


def test_csv_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="none.csv: command file not found"):
        read_command_csv(tmp_path / "none.csv")


def test_fin_limits_are_the_right_and_left_limits_of_fin():
    # The compiled engine asks for both limits at once; the sine computes its sine and cosine
    # once for both, the step shares its zero rate and acceleration. Each limit must be fin's,
    # bit for bit, also at the start (where the left limit is still 0) and for per-run
    # amplitudes, frequencies and starts.
    from cas_freq.simulation.commands import Sine, Step, fin_limits

    t = np.array([-1e-3, 0.0, 0.5e-3, 1e-3, 2e-3])[:, None]
    for command in (Sine(np.array([0.1, 0.2]), np.array([50.0, 900.0]), start_s=1e-3),
                    Sine(0.1, 300.0), Step(0.2, start_s=1e-3),
                    Step(np.array([0.1, -0.3]), start_s=np.array([0.0, 1e-3]))):
        right, left = fin_limits(command, t)
        for got, expected in ((right, command.fin(t)), (left, command.fin(t, left=True))):
            for part, reference in zip(got, expected, strict=True):
                np.testing.assert_array_equal(part, reference)
        # the grid holds each command's start, where the limits differ (the rate of a sine)
        assert any(not np.array_equal(a, b) for a, b in zip(right, left, strict=True))
