"""Encoder quantisation in the simulation (issue 41; docs/model.md, "Encoder quantisation").

Every loop that reads an angle reads it as its encoder counts it, q * round(theta / q) with
q = 2 pi / C (the motor's encoder, ``sensors.counts_per_rev``; the output's,
``sensors.output_counts_per_rev``, seen by the loops on the motor's scale as N q). The checks
are derived here, not read from cas_freq:

* whole counts: with a proportional position loop and a delay of whole steps, the current
  command is Kp (theta_cmd - theta_measured(t - tau_p)), so (theta_cmd - i_cmd / Kp) / q must
  be a whole number at every unclamped sample (to rounding, 1e-6 of a count);
* a limit cycle against the describing function of a quantiser (midtread, step q):
  N(A) = (4 q / (pi A)) sum_k sqrt(1 - ((2k - 1) q / (2 A))^2) over the levels below A
  (Gelb & Vander Velde, "Multiple-Input Describing Functions", 1968, the quantiser); a loop
  whose gain margin 1/|L(j w180)| lies in (1, 4/pi) oscillates at w180 with N(A) = GM, the
  larger root being the stable one. L is written out below from docs/model.md's equations
  (PID-on-PI, exact delays). The describing function drops the harmonics, so the tolerance is
  wide: 15 % on the amplitude of the fundamental, 5 % on the frequency (measured: 9 % and 2 %);
* the two engines (numpy reference, compiled kernel) agree on quantised runs (to 1e-9 rad),
  on the QT-CAS and on the cascade axis.
"""

import math

import numpy as np
import pytest
from clirun import run_cli
from scipy.optimize import brentq

import cas_freq as cf
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import LoopParameters
from cas_freq.simulation import simulate_batch
from cas_freq.simulation.commands import Step

QT = "configs/qt_cas.yaml"
AXIS = "configs/cascade_axis.yaml"
SCREW = "configs/ball_screw.yaml"


def _params(path, **changes):
    return LoopParameters.from_config(cf.load(path, set=changes).params)


def _step(params, degrees, engine="compiled", **options):
    return simulate_batch(params, Step(math.radians(degrees)), engine=engine, **options)


@pytest.mark.parametrize("engine", ["compiled", "reference"])
@pytest.mark.parametrize("key, counts", [("sensors.counts_per_rev", 512),
                                         ("sensors.output_counts_per_rev", 4096)])
def test_the_position_loop_reads_whole_counts(engine, key, counts):
    kp = 2.0
    changes = {"position_loop.Kp": kp, "position_loop.Ki": 0.0, "position_loop.Kd": 0.0,
               key: counts}
    if key.startswith("sensors.output"):
        changes["position_loop.feedback"] = "output"
    p = _params(QT, **changes)
    assert p.counts_per_rev == (counts if key == "sensors.counts_per_rev" else None)
    result = _step(p, 2.0, engine, t_end=0.05, extend=False)
    # one count on the motor's scale: the output encoder's is N times its own
    q = 2.0 * math.pi / counts * (float(p.ratio[0]) if "output" in key else 1.0)
    command = result.command[0] * p.ratio[0]  # the motor-angle command
    current = result.current_command[0]
    after = (result.t > 1e-3) & (np.abs(current) < 0.999 * float(p.i_max[0]))
    counts_read = (command[after] - current[after] / kp) / q
    assert after.sum() > 1000
    np.testing.assert_allclose(counts_read, np.round(counts_read), atol=1e-6)
    # and it moves: the output travels several counts
    assert np.ptp(np.round(counts_read)) >= 3


def test_without_sensors_nothing_is_quantised():
    plain = _step(_params(QT), 10.0, t_end=0.05, extend=False)
    fine = _step(_params(QT, **{"sensors.counts_per_rev": 1e12}), 10.0, t_end=0.05,
                 extend=False)
    coarse = _step(_params(QT, **{"sensors.counts_per_rev": 64}), 10.0, t_end=0.05,
                   extend=False)
    np.testing.assert_allclose(fine.delta, plain.delta, rtol=0, atol=1e-9)
    assert np.max(np.abs(coarse.delta - plain.delta)) > 1e-3


@pytest.mark.parametrize("path, changes", [
    (QT, {"sensors.counts_per_rev": 256, "sampling.current_loop": 25e3,
          "sampling.position_loop": 2.5e3}),
    (AXIS, {"sensors.counts_per_rev": 1024, "sensors.output_counts_per_rev": 4096}),
])
def test_engines_agree_on_quantised_runs(path, changes):
    p = _params(path, **changes)
    ours = _step(p, 5.0, t_end=0.04, extend=False)
    reference = _step(p, 5.0, "reference", t_end=0.04, extend=False)
    np.testing.assert_allclose(ours.theta, reference.theta, rtol=0, atol=1e-9)


def _pid_on_pi_loop(omega, c):
    """L_p(j omega) of docs/model.md's PID-on-PI, written out from its equations."""
    s = 1j * omega
    mu_v = c["Km"] * c["I0"] / (c["n0"] * 2.0 * math.pi / 60.0)
    y = (c["J"] * s + mu_v) / ((c["L"] * s + c["R"]) * (c["J"] * s + mu_v) + c["Ke"] * c["Km"])
    l_i = (c["ci_Kp"] + c["ci_Ki"] / s) * np.exp(-s * c["tau_c"]) * y
    t_i = l_i / (1.0 + l_i)
    m = c["Km"] / (s * (c["J"] * s + mu_v))
    c_p = c["Kp"] + c["Kd"] * s / (c["Tf"] * s + 1.0)
    return c_p * np.exp(-s * c["tau_p"]) * t_i * m


def _quantiser_gain(amplitude, q):
    """The describing function N(A) of a midtread quantiser of step q."""
    levels = np.arange(1, int(amplitude / q + 0.5) + 1)
    return 4.0 * q / (math.pi * amplitude) * np.sum(
        np.sqrt(1.0 - ((2 * levels - 1) * q / (2.0 * amplitude)) ** 2))


@pytest.mark.parametrize("margin_db", [0.5, 1.0])
def test_limit_cycle_matches_the_describing_function(margin_db):
    catalog = {"R": 0.361, "L": 0.071e-3, "Km": 0.0105, "Ke": 0.0105, "J": 5.54e-7,
               "n0": 16300.0, "I0": 0.218, "ci_Kp": 0.6163, "ci_Ki": 2835.3,
               "tau_c": 0.06e-3, "Kp": 6.3435, "Kd": 0.0381, "Tf": 0.6e-3, "tau_p": 0.4e-3}
    phase = lambda w: np.angle(_pid_on_pi_loop(w, catalog)) + math.pi  # noqa: E731
    w180 = brentq(lambda w: math.remainder(phase(w), 2.0 * math.pi), 1000.0, 2500.0)
    scale = 10.0 ** (margin_db / 20.0) * abs(_pid_on_pi_loop(w180, catalog))
    gains = {"Kp": catalog["Kp"] / scale, "Kd": catalog["Kd"] / scale}
    counts = 256
    q = 2.0 * math.pi / counts
    n_wanted = 10.0 ** (margin_db / 20.0)  # N(A) |L(j w180)| = 1 at the scaled loop
    amplitude = brentq(lambda a: _quantiser_gain(a, q) - n_wanted, q / math.sqrt(2.0), 1.49 * q)
    p = _params(QT, **{"position_loop.Kp": gains["Kp"], "position_loop.Kd": gains["Kd"],
                       "position_loop.Ki": 0.0, "position_loop.Tf": catalog["Tf"],
                       "sensors.counts_per_rev": counts})
    result = _step(p, 10.0, t_end=0.6, extend=False, signals=("theta",))
    tail = result.t > 0.3
    t, x = result.t[tail], result.theta[0, tail] - np.mean(result.theta[0, tail])
    ups = np.flatnonzero(np.diff(np.sign(x)) > 0)
    period = float(np.median(np.diff(t[ups])))
    w = 2.0 * math.pi / period
    whole = t < t[ups[0]] + period * ((t[ups[-1]] - t[ups[0]]) // period)
    whole &= t >= t[ups[0]]
    fundamental = 2.0 * abs(np.mean(x[whole] * np.exp(-1j * w * t[whole])))
    assert w == pytest.approx(w180, rel=0.05)
    assert fundamental == pytest.approx(amplitude, rel=0.15)


def test_output_encoder_is_refused_at_a_linear_output():
    with pytest.raises(ConfigError, match="sensors.output_counts_per_rev"):
        cf.load(SCREW, set={"sensors.output_counts_per_rev": 4096})


def test_counts_must_be_whole():
    code, _, err = run_cli(["simulate", QT, "--step", "10 deg", "--set",
                            "sensors.output_counts_per_rev=100.5"])
    assert code == 2 and "sensors.output_counts_per_rev" in err and "100.5" in err


def test_noise_reads_the_encoder_the_position_loop_reads():
    motor = cf.load(QT, set={"sensors.counts_per_rev": 2048}).analyze().noise
    output = cf.load(QT, set={"sensors.output_counts_per_rev": 16384,
                              "position_loop.feedback": "output"}).analyze().noise
    missing = cf.load(QT, set={"sensors.counts_per_rev": 2048,
                               "position_loop.feedback": "output"}).analyze().noise
    assert motor.current_rms_A > 0 and output.current_rms_A > 0
    assert missing.current_rms_A is None and "output_counts_per_rev" in missing.note
    # the same loop read through 8x finer counts at the output (16384 / N = 819.2 per motor
    # turn against 2048): the noise current scales with the count on the motor's scale
    assert output.current_rms_A / motor.current_rms_A == pytest.approx(2048 * 20 / 16384,
                                                                       rel=1e-9)
