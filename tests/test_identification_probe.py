"""The fit's intervals checked against what moves the simulated output (``fit --params``).

Sources of the expected values:
- a quantised delay and a key the output ignores, through an analytic second-order step (the
  replayer replaced by its closed form): every delay in the same whole period gives the same
  output, so the interval must hold that period; the ignored key moves nothing;
- a rotor inertia J and a load inertia J_L behind a rigid gear of ratio N = 20 and efficiency
  eta = 1: the reflected inertia J + J_L/(eta N^2) (docs/model.md) is all the output sees, so
  the sum's coefficient is 1/400 and its value that of the truth;
- a notch frequency recovered from a recording the simulator made with the config's own value.
"""

import math

import numpy as np
import pytest

import cas_freq.identification.physical as physical
from cas_freq.cli.fit_params import fit_dict, table
from cas_freq.config import load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import variant_parameters
from cas_freq.identification.free_keys import free_keys, parse_model_spec
from cas_freq.identification.recordings import Recording
from cas_freq.identification.replay import RecordingReplayer, Replay

STEP = math.radians(5.0)
QUANTUM = 50e-6  # [s] the closed form's delay is rounded down to whole periods of 50 us
OMEGA, ZETA = 400.0, 0.6  # [rad/s], [-] of the closed form


def _recording(time, position, current=None, source="synthetic"):
    return Recording(time_s=time, command_rad=np.where(time >= 0, STEP, 0.0),
                     position_rad=position, current_a=current, voltage_v=None, step_rad=STEP,
                     trigger_s=0.0, position_offset_rad=0.0, command_offset_rad=0.0,
                     source=source)


def _second_order(t, delay):
    """Unit step response of OMEGA, ZETA delayed by ``delay`` rounded down to QUANTUM."""
    lag = np.floor(delay / QUANTUM + 1e-9) * QUANTUM
    s = np.maximum(t - lag, 0.0)
    wd = OMEGA * math.sqrt(1 - ZETA ** 2)
    return 1 - np.exp(-ZETA * OMEGA * s) * (np.cos(wd * s) + ZETA / math.sqrt(1 - ZETA ** 2)
                                            * np.sin(wd * s))


class _Quantised:
    """A replayer of the closed form: it reads position_loop.delay, rounded down to whole
    periods, and ignores every other key."""

    def __init__(self, config, recordings, steps_rad):
        self.recordings, self.steps = list(recordings), list(steps_rad)
        self.masks = [r.after for r in self.recordings]

    def replay(self, changes):
        delays = np.asarray(changes["position_loop.delay"], dtype=float)
        position = [np.stack([step * _second_order(r.time_s[m], d) for d in delays])
                    for r, m, step in zip(self.recordings, self.masks, self.steps, strict=True)]
        none = np.zeros((delays.size, len(self.recordings)), dtype=bool)
        # a current that follows the position, 1 A per step (what current data would add)
        return Replay(position=position, current=[p / STEP for p in position],
                      current_limited=none, voltage_limited=none)


def test_a_quantised_key_gets_no_interval_narrower_than_its_period(monkeypatch):
    """Data of a delay of 0.8 ms (16 whole periods), fitted from there: the difference quotient
    straddles the step down to 15 periods and claims an interval of +-0.006 % (the base code's
    [0.79995, 0.80005] ms). Every delay in [0.80, 0.85) ms gives the same output, so the
    interval must hold all of them; and a key the output ignores is not identifiable."""
    monkeypatch.setattr(physical, "RecordingReplayer", _Quantised)
    time = np.arange(-100, 400) * 1e-4  # 10 kHz, 10 ms before the trigger, 40 ms after
    noise = np.random.default_rng(7).normal(0.0, 1e-3 * STEP, time.size)
    recordings = [_recording(time, STEP * _second_order(time, 0.8e-3) + noise)]
    spec = parse_model_spec("position_loop.delay=0.8ms,motor.coulomb_friction=1mN*m")
    fit = physical.fit_physical(load_variant(None, "base"), recordings, [STEP], spec)
    estimate = fit.estimate[0]
    low, high = fit.interval[0]
    period = math.floor(estimate / QUANTUM + 1e-9) * QUANTUM  # the estimate's whole periods
    assert low <= period and high >= period + QUANTUM, (low, high, estimate)
    # the widening stops where the output moves: within an eighth of an octave (9 %) past the
    # period's end, in the key's coordinate (its logarithm)
    assert math.log(high / estimate) <= 1.1 * math.log((period + QUANTUM) / estimate)
    assert fit.probes["keys"][0].widened
    keys = fit.identifiability["fitted"].keys
    assert keys[1].verdict == "not identifiable" and np.isnan(fit.interval[1]).all()
    # its ends, a factor 100 either way, moved the output by nothing at all
    assert fit.probes["keys"][1].moved == (0.0, 0.0)


# --- keys that enter only as a sum ------------------------------------------------------------

J_ROTOR, J_LOAD, RATIO = 7.19e-7, 2e-5, 20.0  # the `fitted` variant's J, a load, its gear


def _simulated(loaded, changes, time, noise_rad, noise_a, seed):
    """A recording the simulator makes of ``loaded`` with ``changes``, plus noise."""
    probe = _recording(time, np.zeros_like(time), np.zeros_like(time))
    replay = RecordingReplayer(loaded.params, [probe], [STEP]).replay(
        {key: np.array([value]) for key, value in changes.items()})
    rng = np.random.default_rng(seed)
    position = np.zeros_like(time)
    current = np.zeros_like(time)
    position[time >= 0] = replay.position[0][0]
    current[time >= 0] = replay.current[0][0]
    return _recording(time, position + rng.normal(0, noise_rad, time.size),
                      current + rng.normal(0, noise_a, time.size))


@pytest.fixture(scope="module")
def sum_fit():
    loaded = load_variant(None, "fitted", [("load.inertia", J_LOAD)])  # rigid gear, eta = 1
    assert loaded.params.gear.ratio == RATIO and loaded.params.gear.efficiency == 1.0
    time = np.arange(-50, 600) * 1e-4  # 10 kHz, 5 ms before the trigger, 60 ms after
    # the simulator's own recording without noise, as `simulate --csv` writes it: the residual
    # is then round-off, where the base code called each key well determined (J +-0.2 %)
    recording = _simulated(loaded, {}, time, 0.0, 0.0, 3)
    spec = parse_model_spec("motor.J=6e-7,load.inertia=3e-5")
    return physical.fit_physical(loaded, [recording], [STEP], spec, ("position", "current"))


def test_keys_entering_as_a_sum_are_reported_as_their_sum(sum_fit):
    found = sum_fit.identifiability["fitted"]
    # neither key alone: trading one for the other at a constant sum moves nothing
    assert [k.verdict for k in found.keys] == ["not identifiable"] * 2
    assert np.isnan(sum_fit.interval).all()
    (total,) = [c for c in found.determined if c.coefficients is not None]
    # the coefficient of J_L is 1/(eta N^2) = 1/400: measured where the output held still
    # along the sum (F's own estimate is 1e-4 off, the curvature its finite differences see);
    # noise-free data leave it to the simulator's round-off: 1e-6
    assert total.coefficients == pytest.approx((1.0, 1.0 / RATIO ** 2), rel=1e-6)
    truth = J_ROTOR + J_LOAD / RATIO ** 2
    assert abs(math.log(total.value / truth)) <= total.half_width, (total.value, truth)
    assert total.verdict == "well determined" and total.text == "J + 0.0025·inertia"
    # and the estimates keep the sum, wherever along it the fit stopped
    j, j_load = sum_fit.estimate
    assert j + j_load / RATIO ** 2 == pytest.approx(truth, rel=3 * total.half_width)
    text = table({"config_path": "c", "variant": "fitted", "recordings": ["r"],
                  "models": [fit_dict(sum_fit, 1.0)], "written": None})
    line = ("motor.J: not identifiable (trading it for the others at a constant "
            "J + 0.0025·inertia does not change the simulated output)")
    assert text.count(line) == 2  # from both signals, and from the position alone


# --- every numeric key the simulation reads ----------------------------------------------------

def test_a_filter_number_is_fitted():
    """The notch of configs/cascade_axis.yaml at 800 rad/s: from a start at 1000 rad/s, the fit
    returns it within its interval (the recording is the simulator's own, with noise)."""
    loaded = load_variant("configs/cascade_axis.yaml", "base")
    time = np.arange(-50, 500) * 2e-4  # 5 kHz, 10 ms before, 0.1 s after
    recording = _simulated(loaded, {}, time, math.radians(0.005), 0.01, 5)
    spec = parse_model_spec("filters.0.frequency=1000")
    fit = physical.fit_physical(loaded, [recording], [STEP], spec, ("position", "current"))
    low, high = fit.interval[0]
    assert low <= 800.0 <= high, (low, high, fit.estimate)
    assert fit.identifiability["fitted"].keys[0].verdict == "well determined"


def test_the_no_load_point_is_a_free_key_where_the_config_reads_it():
    base = load_variant(None, "base").params  # mu_v derived from the no-load point
    (speed,) = free_keys(parse_model_spec("motor.no_load.speed"), variant_parameters(base, {}),
                         "base", base)
    assert speed.start == pytest.approx(base.motor.no_load.speed) and speed.log
    fitted = load_variant(None, "fitted").params  # gives mu_v directly
    with pytest.raises(ConfigError, match="motor.no_load.speed: the config gives motor.mu_v"):
        free_keys(parse_model_spec("motor.no_load.speed"), variant_parameters(fitted, {}),
                  "fitted", fitted)


# --- the probe itself, analytic ---------------------------------------------------------------

def test_the_probe_of_a_linear_model_confirms_its_intervals():
    """r(x) = A x: the chi^2 change at x + t d is t^2 d^T A^T A d, exactly q^2 at the ends of
    each interval of C = (A^T A)^-1 (s^2 = 1), for keys and for a combination alike; and a
    column of zeros (a key the output ignores) is not identifiable."""
    from cas_freq.identification.probe import probe

    a = np.array([[3.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.5, -1.0, 0.0], [0.0, 1.0, 0.0]])
    fisher = a.T @ a
    covariance = np.linalg.pinv(fisher)
    covariance[2, 2] = 1e14  # the ignored key: F's floored eigenvalue
    q = 2.0

    def change(rows):
        return np.sum((np.atleast_2d(rows) @ a.T) ** 2, axis=1)

    directions = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [1.0, -1.0, 0]])
    halves = np.array([q * math.sqrt(e @ covariance @ e) for e in directions])
    limits = np.full(4, math.log(100.0))
    bounds = (np.full(3, -50.0), np.full(3, 50.0))
    found = probe(change, np.zeros(3), covariance, directions, halves, limits, bounds, q)
    for item in found[:2] + found[3:]:
        assert item.moved == pytest.approx((q * q, q * q), rel=1e-12)  # round-off only
        assert not item.widened
    assert not found[2].identifiable and found[2].moved == (0.0, 0.0)
