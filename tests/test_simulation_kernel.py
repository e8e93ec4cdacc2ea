"""The compiled kernel gives the reference engine's trajectories, to 1e-9 of the command.

Reference: :class:`cas_freq.simulation.engine.Engine` (numpy, the simulator's reference path,
itself checked against python-control's nlsys in tests/test_simulation_nlsys.py and against the
linear Padé model in tests/test_simulation.py). The kernel (:mod:`cas_freq.simulation.kernel`)
performs the same floating-point operations in the same order per run; differences come only
from the order of the 3 x 3 products in numpy's einsum and from the reference's batch-wide
shortcuts (an ulp in a run of a batch), which the closed loop carries to about 1e-14 of the
step. 1e-9 of the command's scale leaves five orders of magnitude for that and still catches
any modelling slip (one step of delay moves a 10 deg step's trajectory by ~1e-3).

Each case runs both engines on the same batch with a short horizon where a long one adds
nothing (the reference costs ~50 us per step).
"""

import math
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest
import yaml

from cas_freq.config.loader import load_variant, variant_names
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import LoopParameters
from cas_freq.simulation import Ramp, Sine, Step, read_command_csv, simulate_batch
from cas_freq.simulation import simulator as simulator_module
from cas_freq.simulation.engine import Engine

pytest.importorskip("numba")

TOLERANCE = 1e-9  # of the scale of each signal (module notes)
SIGNALS = ("delta", "theta", "omega", "i", "V", "command", "current_command",
           "position_integral")
FLAGS = ("current_limited", "voltage_limited")


def pairs(overrides):
    """``["key=value", ...]`` as the loader's (key, value) pairs."""
    return [tuple(item.split("=", 1)) for item in overrides]


def parameters(path=None, variants=("base",), overrides=()):
    configs = [load_variant(path, variant=v, overrides=pairs(overrides)).params
               for v in variants]
    return LoopParameters.from_configs(configs)


def both(params, command, **options):
    """The batch by the compiled and the reference engine."""
    compiled = simulate_batch(params, command, engine="compiled", **options)
    reference = simulate_batch(params, command, engine="reference", **options)
    return compiled, reference


def assert_same(compiled, reference, scale_rad):
    """Equal within TOLERANCE of each signal's scale; same samples, horizon and flags."""
    assert np.array_equal(compiled.t, reference.t)
    assert compiled.t_end_s == reference.t_end_s and compiled.extended == reference.extended
    if reference.settled is None:
        assert compiled.settled is None
    else:
        assert np.array_equal(compiled.settled, reference.settled)
        assert np.array_equal(compiled.t_end_runs, reference.t_end_runs)
    for name in SIGNALS:
        ours, theirs = getattr(compiled, name), getattr(reference, name)
        assert ours.shape == theirs.shape
        # scale: the command for angles, else the signal's own largest magnitude (per run)
        scale = np.max(np.abs(theirs), axis=1, keepdims=True)
        if name in ("delta", "command"):
            scale = np.full_like(scale, scale_rad)
        elif name == "theta":
            scale = scale_rad * reference.theta[:, -1:] / reference.delta[:, -1:]
        error = np.max(np.abs(ours - theirs) / np.maximum(scale, 1e-300))
        assert error <= TOLERANCE, f"{name}: {error:.3g} of its scale"
    for name in FLAGS:
        ours, theirs = getattr(compiled, name), getattr(reference, name)
        # a clamp flag where an output rests exactly at its limit depends on the last bit
        assert np.mean(ours != theirs) <= 1e-4, name


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
@pytest.mark.parametrize("path", [None, "configs/dc_servo.yaml"])
def test_ten_degree_step_of_every_variant(path):
    # every variant of the config on the motor encoder in one batch, default horizon with its
    # extension (a batch has one loop structure: the QT-CAS's fin_encoder, closed on the
    # output, is compared engine against engine in tests/test_simulation_architectures.py, the
    # sampled variant in tests/test_simulation_sampled.py)
    with open(path or "configs/qt_cas.yaml", encoding="utf-8") as stream:
        raw = yaml.safe_load(stream)
    variants = raw.get("variants") or {}
    names = [name for name in variant_names(raw)
             if variants.get(name, {}).get("position_loop.feedback", "motor") == "motor"
             and not any(key.startswith("sampling") for key in variants.get(name, {}))]
    amplitude = math.radians(10.0)
    compiled, reference = both(parameters(path, names), Step(amplitude))
    assert_same(compiled, reference, amplitude)
    assert compiled.current_limited.any()  # docs/model.md §10: the 20 A clamp acts


def test_each_variant_alone_is_the_same_run():
    # a single run takes the kernel's path for one run (no batch-wide shortcuts in the
    # reference): the base variant's 10 deg step over 30 ms
    amplitude = math.radians(10.0)
    compiled, reference = both(parameters(), Step(amplitude), t_end=0.03, extend=False)
    assert_same(compiled, reference, amplitude)


def test_saturating_step_with_anti_windup():
    # 40 deg with a 12 V supply: the current command sits on ±20 A and the voltage on ±12 V,
    # both integrators held by the anti-windup (the clamps release during the run)
    amplitude = math.radians(40.0)
    params = parameters(variants=("base", "fitted"), overrides=["current_loop.v_max=12 V"])
    compiled, reference = both(params, Step(amplitude), t_end=0.04, extend=False)
    assert_same(compiled, reference, amplitude)
    for name in FLAGS:
        flags = getattr(compiled, name)
        assert flags.any(axis=1).all() and not flags[:, -1].any(), name


def test_sampled_controllers():
    # EPOS4 rates (docs/model.md §9 item 8), zero-order hold, backward-difference derivative
    amplitude = math.radians(10.0)
    compiled, reference = both(
        parameters(variants=("base", "fitted")), Step(amplitude), t_end=0.03, extend=False,
        current_rate_hz=25e3, position_rate_hz=2.5e3,
    )
    assert_same(compiled, reference, amplitude)


@pytest.mark.parametrize("case", ["ramp", "sine", "table"])
def test_commands_with_feed_forward(case, tmp_path):
    # the shipped feed-forward (FFv, FFa of report Table 2) acts on ramps, sines and tables
    params = parameters(variants=("base", "fitted"))
    assert (params.ff_v > 0).all() and (params.ff_a > 0).all()
    if case == "ramp":
        command, scale, options = Ramp(math.radians(200.0), 0.002, 0.012), math.radians(2), {}
    elif case == "sine":
        command = Sine(math.radians(2.0), 300.0, 0.001)
        scale, options = math.radians(2.0), {"t_end": 0.03}
    else:
        path = tmp_path / "command.csv"
        path.write_text("time,angle\n0.001,0\n0.004,3\n0.006,3\n0.008,-1\n0.02,0\n")
        command, scale, options = read_command_csv(path), math.radians(3.0), {}
    compiled, reference = both(params, command, max_t_end=0.1, **options)
    assert_same(compiled, reference, scale)


@pytest.mark.parametrize("rates_hz", [(None, None), (25e3, 2.5e3), (20e3, None), (None, 5e3)],
                         ids=["continuous", "both-sampled", "current-sampled", "position-sampled"])
def test_mixed_batch_with_per_run_delays_and_commands(rates_hz):
    # runs that differ in delays (whole, fractional, shorter than one step, none), derivative
    # on the measurement or no derivative, each with its own command; every 3rd sample kept;
    # each delay line interpolating (continuous controller) or holding (sampled), as the
    # kernel reads them by separate branches
    configs = [load_variant(variant=v).params for v in ("base", "fitted", "relaxed")]
    configs += [load_variant(overrides=pairs(o)).params for o in (
        ["current_loop.delay=0.0625 ms", "position_loop.delay=0.4125 ms"],
        ["current_loop.delay=0.003 ms", "position_loop.delay=0.002 ms"],
        ["current_loop.delay=0 ms", "position_loop.delay=0 ms"],
        ["position_loop.derivative_on=measurement", "position_loop.delay=0.2 ms"],
        ["position_loop.Kd=0"],
    )]
    params = LoopParameters.from_configs(configs)
    assert len(set(params.tau_c)) == 4 and len(set(params.tau_p)) == 5
    commands = [Step(math.radians(a)) for a in (10, 5, 1, 10, 2, 10, -10, 3)]
    current_rate_hz, position_rate_hz = rates_hz
    compiled, reference = both(params, commands, dt=5e-6, t_end=0.03, extend=False,
                               record_every=3, current_rate_hz=current_rate_hz,
                               position_rate_hz=position_rate_hz)
    assert_same(compiled, reference, math.radians(10.0))


def test_one_command_with_per_run_amplitudes():
    # one command object whose amplitudes broadcast over the runs (a sine-dwell batch)
    params = parameters(variants=("base", "fitted", "relaxed"))
    amplitude = np.radians([0.5, 5.0, 10.0])
    command = Sine(amplitude, np.array([200.0, 800.0, 1500.0]))
    compiled, reference = both(params, command, t_end=0.02)
    assert_same(compiled, reference, math.radians(10.0))


def test_unstable_loop():
    # position_loop.Kd = 0.5 A*s/rad (tests/test_unstable_and_limits.py: the linear loop is
    # unstable); the nonlinear loop oscillates between the clamps
    amplitude = math.radians(1.0)
    params = parameters(overrides=["position_loop.Kd=0.5"])
    compiled, reference = both(params, Step(amplitude), t_end=0.02, max_t_end=0.04)
    assert_same(compiled, reference, amplitude)
    assert not compiled.settled.any() and compiled.extended


def test_progress_and_chunks_do_not_change_the_result():
    # the simulator advances the kernel in pieces (progress reports, horizon extension): the
    # state between calls is complete
    amplitude = math.radians(10.0)
    calls = []
    pieces = simulate_batch(parameters(), Step(amplitude), t_end=0.01, extend=False,
                            progress=lambda done, planned: calls.append(done))
    whole = simulate_batch(parameters(), Step(amplitude), t_end=0.01, extend=False)
    assert len(calls) == 50
    for name in SIGNALS + FLAGS:
        assert np.array_equal(getattr(pieces, name), getattr(whole, name)), name


def test_engine_choice(monkeypatch):
    from cas_freq.simulation.compiled import CompiledEngine

    monkeypatch.delenv(simulator_module.ENGINE_ENV, raising=False)
    assert simulator_module.engine_class() is CompiledEngine
    assert simulator_module.engine_class("reference") is Engine
    monkeypatch.setenv(simulator_module.ENGINE_ENV, "reference")
    assert simulator_module.engine_class() is Engine
    monkeypatch.setenv(simulator_module.ENGINE_ENV, "fortran")
    with pytest.raises(ConfigError, match="CAS_FREQ_ENGINE"):
        simulator_module.engine_class()
    with pytest.raises(ConfigError, match="engine"):
        simulate_batch(parameters(), Step(0.1), engine="fast")


def test_without_numba_the_reference_runs(monkeypatch):
    # numba missing: the kernel module fails to import; the simulator warns and falls back
    monkeypatch.delenv(simulator_module.ENGINE_ENV, raising=False)
    monkeypatch.setitem(sys.modules, "numba", None)
    monkeypatch.delitem(sys.modules, "cas_freq.simulation.kernel", raising=False)
    monkeypatch.delitem(sys.modules, "cas_freq.simulation.compiled", raising=False)
    with pytest.warns(UserWarning, match="compiled engine is unavailable"):
        assert simulator_module.engine_class() is Engine
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert simulator_module.engine_class("reference") is Engine


def test_without_a_writable_cache_the_kernel_compiles_in_process():
    # numba caches next to the module, else in NUMBA_CACHE_DIR or the user's cache; where no
    # place is writable, numba refuses cache=True: the kernel is then compiled without a
    # cache (in a fresh process: the check needs the decorators to run again)
    code = (
        "import numba.core.caching as caching\n"
        "def deny(self):\n"
        "    raise OSError('read-only')\n"
        "caching._CacheLocator.ensure_cache_path = deny\n"
        "from numba.core.caching import NullCache\n"
        "from cas_freq.simulation import kernel\n"
        "assert isinstance(kernel.advance_serial._cache, NullCache)\n"
        "assert isinstance(kernel.advance_parallel._cache, NullCache)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_batches_from_several_threads():
    # numba's workqueue layer refuses concurrent parallel launches (it aborts the process):
    # batches simulated side by side from threads (a dask worker's) must still run and agree
    from concurrent.futures import ThreadPoolExecutor

    amplitude = math.radians(10.0)
    params = parameters(variants=("base", "fitted", "relaxed"))

    def batch(_):
        return simulate_batch(params, Step(amplitude), t_end=0.005, extend=False)

    with ThreadPoolExecutor(max_workers=3) as pool:
        results = list(pool.map(batch, range(6)))
    for result in results[1:]:
        assert np.array_equal(result.delta, results[0].delta)


def test_batches_in_forked_processes():
    # a process forked after the parallel kernel ran (a multiprocessing pool) can simulate:
    # numba's GNU OpenMP layer would terminate it, the workqueue layer the kernel picks does not
    code = (
        "import math, multiprocessing\n"
        "from cas_freq.config.loader import load_variant\n"
        "from cas_freq.core.parameters import LoopParameters\n"
        "from cas_freq.simulation import Step, simulate_batch\n"
        "params = LoopParameters.from_configs([load_variant().params] * 2)\n"
        "def batch(_):\n"
        "    return float(simulate_batch(params, Step(math.radians(10.0)), t_end=0.002,\n"
        "                                extend=False).delta[0, -1])\n"
        "if __name__ == '__main__':\n"
        "    first = batch(0)\n"
        "    with multiprocessing.get_context('fork').Pool(2) as pool:\n"
        "        assert pool.map(batch, range(2)) == [first, first]\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          timeout=240)
    assert done.returncode == 0, done.stderr
