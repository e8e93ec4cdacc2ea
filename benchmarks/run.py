"""cas_freq against python-control, measured in one run on one machine (``python
benchmarks/run.py``; not part of the test suite).

1. margins + bandwidth of 10,000 variants (a 100 x 100 grid of Kp and Kd; and random
   gains and motor values, ±10 % around the shipped config): cas_freq's batch (exact delays,
   Padé-6 stability) vs two python-control loops, both with Padé-6 delays: the naive one
   (transfer-function arithmetic, ``stability_margins`` of both loops, ``bandwidth`` of T,
   timed on a sample of 100 and extrapolated) and an improved one (benchmarks/baselines.py:
   numpy polynomials, the current loop cached, a fixed-grid bandwidth; timed on 1,000);
2. a 10 deg nonlinear step of 60 ms: cas_freq's simulator (the compiled kernel, and the numpy
   reference engine) in batch mode (per run) and alone vs python-control
   ``input_output_response`` of an ``nlsys`` of the same loop (Padé-8 delays, LSODA rtol 1e-9,
   the cross-check of tests/test_simulation_nlsys.py), with the RMS difference of the two fin
   angles; the step at the default horizon, and ``cas-freq simulate --step 10deg`` as a whole
   process with either engine (after a first run, so the kernel loads from numba's cache);
3. a sine-dwell map of 8 amplitudes x 30 frequencies (cas_freq);
4. ``cas-freq verify`` of the shipped config as a whole process; ``cas-freq montecarlo`` of
   10,000 samples with the shipped requirements (steps and fits) as a whole process;
5. peak memory (tracemalloc) of the frequency-domain batch for 100,000 variants.

Options: ``--quick`` (fewer variants, for a smoke run), ``--skip-memory``.
"""

import argparse
import math
import os
import platform
import shutil
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

# BLAS at one thread, as the cas-freq CLI runs it (set before numpy loads): the toolbox's
# linear algebra is many small matrices, where BLAS threads only contend (and OpenBLAS's
# worker spins on a core for ~0.1 s after each call, taking it from the simulation kernel).
from cas_freq.cli import limit_blas_threads

limit_blas_threads()

import numpy as np  # noqa: E402
from baselines import ImprovedBaseline  # noqa: E402

from cas_freq.analysis.analyze import DEFAULT_CHUNK, batch_analyze  # noqa: E402
from cas_freq.config import load_variant  # noqa: E402
from cas_freq.parameters import variant_parameters  # noqa: E402

SEED = 20261122
KEYS = ("position_loop.Kp", "position_loop.Ki", "position_loop.Kd", "current_loop.Kp",
        "motor.Km", "motor.J")


def machine():
    """One line naming the machine."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as stream:
            for line in stream:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return (f"{cpu}, {os.cpu_count()} CPUs, {platform.system()} {platform.release()}, "
            f"Python {platform.python_version()}, numpy {np.__version__}")


def variants(params, n, rng):
    """Random variants: each key uniform within ±10 % of the config's value."""
    from cas_freq.parameters import base_values

    base = base_values(params)
    return {key: base[key] * rng.uniform(0.9, 1.1, n) for key in KEYS}


def control_figures(params, changes, index, order=6):
    """Margins of both loops and the bandwidth of T by python-control (one variant)."""
    import control

    def value(key, default):
        return float(changes[key][index]) if key in changes else default

    motor, cur, pos = params.motor, params.current_loop, params.position_loop
    km, j = value("motor.Km", motor.Km), value("motor.J", motor.J)
    mu = motor.viscous_friction * km / motor.Km if motor.mu_v is None else motor.mu_v
    kp_i, ki_i = value("current_loop.Kp", cur.Kp), cur.Ki
    kp, ki, kd = (value("position_loop.Kp", pos.Kp), value("position_loop.Ki", pos.Ki),
                  value("position_loop.Kd", pos.Kd))
    tf = pos.Tf if pos.Tf is not None else kd / (10 * kp)
    s = control.tf("s")
    ci = kp_i + ki_i / s
    y = (j * s + mu) / ((motor.L * s + motor.R) * (j * s + mu) + motor.Ke * km)
    dc = control.tf(*control.pade(cur.delay, order))
    dp = control.tf(*control.pade(pos.delay, order))
    li = ci * dc * y
    ti = control.feedback(li, 1)
    m = km / (s * (j * s + mu))
    cp = kp + ki / s + kd * s / (tf * s + 1)
    lp = cp * dp * ti * m
    t = control.feedback(lp, 1)
    # python-control finds the margins of a transfer function from polynomials in jw; at this
    # order its polyval overflows harmlessly in one branch (the margins still agree to 5e-12)
    with np.errstate(over="ignore"):
        gm_i, pm_i, _, _, wc_i, _ = control.stability_margins(li)
        gm_p, pm_p, _, _, wc_p, _ = control.stability_margins(lp)
    return {"current_loop.phase_margin_deg": pm_i, "position_loop.phase_margin_deg": pm_p,
            "position_loop.crossover_rad_s": wc_p, "closed_loop.bandwidth_rad_s":
            # cas_freq's -3.0103 dB (half power, docs/model.md), not python-control's -3.00 dB
            # default, which alone makes the two bandwidths differ by ~9e-4
            control.bandwidth(t, dbdrop=20 * math.log10(1 / math.sqrt(2)))}


def gain_grid(params, n):
    """A Kp x Kd grid of about n points (x0.5..x1.5 of the config's gains)."""
    side = int(round(math.sqrt(n)))
    kp, kd = np.meshgrid(params.position_loop.Kp * np.linspace(0.5, 1.5, side),
                         params.position_loop.Kd * np.linspace(0.5, 1.5, side), indexing="ij")
    return {"position_loop.Kp": kp.ravel(), "position_loop.Kd": kd.ravel()}


def bench_margins(params, changes, label, sample, rows):
    n = len(next(iter(changes.values())))
    loop = variant_parameters(params, changes)
    # the figures python-control computes: each loop's margins with the loops outside it open
    # (loop_at_a_time=False; the inner loop's margins with every loop closed cost another
    # margin search per run, see benchmarks/architectures.py)
    batch_analyze(variant_parameters(params, {k: v[:64] for k, v in changes.items()}),
                  loop_at_a_time=False)  # warm
    start = time.perf_counter()
    result = batch_analyze(loop, loop_at_a_time=False)
    ours = time.perf_counter() - start
    picks = np.linspace(0, n - 1, sample).astype(int)
    control_figures(params, changes, 0)  # warm-up (imports)
    start = time.perf_counter()
    theirs = [control_figures(params, changes, int(i)) for i in picks]
    per_variant = (time.perf_counter() - start) / sample
    extrapolated = per_variant * n
    # agreement: python-control's Padé-6 figures vs cas_freq's exact-delay ones
    differences = {
        name: max(abs(theirs[k][name] - result.figures[name][i]) / abs(result.figures[name][i])
                  for k, i in enumerate(picks))
        for name in theirs[0]
    }
    rows.append((f"margins + bandwidth, {n:,} variants ({label})", f"{ours:.2f} s",
                 f"{extrapolated:.0f} s ({per_variant * 1e3:.1f} ms x {n:,})",
                 extrapolated / ours))
    # the improved baseline (benchmarks/baselines.py): numpy polynomials, the current loop
    # cached, a fixed-grid bandwidth; timed on 10x the sample (it is faster)
    improved = ImprovedBaseline(params)
    improved.figures(changes, 0)
    picks = np.linspace(0, n - 1, min(n, 10 * sample)).astype(int)
    start = time.perf_counter()
    better = [improved.figures(changes, int(i)) for i in picks]
    per_variant = (time.perf_counter() - start) / picks.size
    for name in better[0]:
        differences[f"{name} (improved)"] = max(
            abs(better[k][name] - result.figures[name][i]) / abs(result.figures[name][i])
            for k, i in enumerate(picks))
    rows.append(("  same, against the improved python-control loop", f"{ours:.2f} s",
                 f"{per_variant * n:.0f} s ({per_variant * 1e3:.2f} ms x {n:,})",
                 per_variant * n / ours))
    return differences


def _best(function, repeats):
    """Shortest wall time of ``repeats`` calls [s] and the last call's result."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return min(times), result


def bench_step(params, runs, rows, notes):
    """10 deg steps: the compiled kernel and the numpy reference engine vs python-control."""
    from cas_freq.parameters import LoopParameters
    from cas_freq.simulation import Step, simulate_batch

    amplitude = math.radians(10.0)
    one = LoopParameters.from_config(params)
    batch = LoopParameters.from_configs([params] * runs)

    def step(loop, engine, **options):
        options = {"t_end": 0.06, "extend": False, **options}
        return simulate_batch(loop, Step(amplitude), engine=engine, **options)

    step(one, "compiled", t_end=0.002)  # warm-up (loads the kernel from numba's cache)
    step(batch, "compiled", t_end=0.002)
    ours_batch, result = _best(lambda: step(batch, "compiled"), 3)
    ours_batch /= runs
    ours_single, single = _best(lambda: step(one, "compiled"), 5)
    ref_single, reference = _best(lambda: step(one, "reference"), 2)
    ref_batch = _best(lambda: step(batch, "reference"), 1)[0] / runs
    # the default horizon with its extension, as cas-freq simulate runs it
    ours_default = _best(lambda: step(one, "compiled", t_end=None, extend=True), 5)[0]
    ref_default = _best(lambda: step(one, "reference", t_end=None, extend=True), 1)[0]

    import control

    system = actuator_nlsys(params, 8)
    t = result.t
    theta_cmd = np.full(t.size, params.gear.ratio * amplitude)
    start = time.perf_counter()
    response = control.input_output_response(
        system, t, theta_cmd, np.zeros(system.nstates), t_eval=t,
        solve_ivp_method="LSODA", solve_ivp_kwargs={"rtol": 1e-9, "atol": 1e-10},
    )
    theirs = time.perf_counter() - start
    delta = response.states[2] / params.gear.ratio
    rms = float(np.sqrt(np.mean((delta - single.delta[0]) ** 2)) / amplitude)
    rows.append((f"10 deg step, 60 ms (batch of {runs}, per run)", f"{ours_batch * 1e3:.2f} ms",
                 f"{theirs:.2f} s", theirs / ours_batch))
    rows.append((f"  same, numpy reference engine (batch of {runs}, per run)",
                 f"{ref_batch * 1e3:.1f} ms", f"{theirs:.2f} s", theirs / ref_batch))
    rows.append(("10 deg step, 60 ms (one run alone)", f"{ours_single * 1e3:.1f} ms",
                 f"{theirs:.2f} s", theirs / ours_single))
    rows.append(("  same, numpy reference engine", f"{ref_single * 1e3:.0f} ms",
                 f"{theirs:.2f} s", theirs / ref_single))
    rows.append(("10 deg step, default horizon (0.1 s + extension, one run)",
                 f"{ours_default * 1e3:.1f} ms", "-", None))
    rows.append(("  same, numpy reference engine", f"{ref_default * 1e3:.0f} ms", "-", None))
    for engine in ("compiled", "reference"):
        elapsed = bench_simulate_process(engine)
        rows.append((f"cas-freq simulate --step 10deg (whole process, {engine})",
                     elapsed, "-", None))
    difference = float(np.max(np.abs(single.delta - reference.delta)) / amplitude)
    notes.append(
        f"10 deg step, compiled kernel vs numpy reference engine: {ref_single / ours_single:.0f}x "
        f"(one run), {ref_batch / ours_batch:.0f}x (batch of {runs}, per run), "
        f"{ref_default / ours_default:.0f}x (default horizon); largest difference of the fin "
        f"angle {difference:.1e} of the step; numba threads {_numba_threads()}"
    )
    return rms


def _numba_threads():
    try:
        import numba
    except ImportError:
        return "- (numba not installed)"
    return numba.get_num_threads()


def bench_simulate_process(engine):
    """Best of 3 of ``cas-freq simulate --step 10deg`` as a process (after one warm run)."""
    executable = shutil.which("cas-freq")
    command = [executable] if executable else [sys.executable, "-m", "cas_freq"]
    env = {**os.environ, "CAS_FREQ_ENGINE": engine}
    times = []
    for attempt in range(4):  # the first run may compile the kernel into numba's cache
        start = time.perf_counter()
        done = subprocess.run([*command, "simulate", "--step", "10deg"], capture_output=True,
                              text=True, check=False, env=env)
        if done.returncode != 0:
            return "failed"
        if attempt:
            times.append(time.perf_counter() - start)
    return f"{min(times):.2f} s"


def bench_sinedwell(params, rows):
    from cas_freq.parameters import LoopParameters
    from cas_freq.simulation.sinedwell import sine_dwell

    amplitudes = np.radians([0.25, 0.5, 1, 2, 4, 6, 8, 10])
    frequencies = np.geomspace(100.0, 5000.0, 30)
    start = time.perf_counter()
    sine_dwell(LoopParameters.from_config(params), amplitudes, frequencies)
    ours = time.perf_counter() - start
    rows.append(("sine-dwell map 8 x 30", f"{ours:.2f} s", "-", None))


def bench_verify(rows):
    executable = shutil.which("cas-freq")
    command = [executable] if executable else [sys.executable, "-m", "cas_freq"]
    probe = subprocess.run([*command, "verify", "--help"], capture_output=True, text=True,
                           check=False)
    if probe.returncode != 0:
        rows.append(("cas-freq verify (whole process)", "not available", "-", None))
        return
    times = []
    for _ in range(3):
        start = time.perf_counter()
        subprocess.run([*command, "verify"], capture_output=True, text=True, check=False)
        times.append(time.perf_counter() - start)
    rows.append(("cas-freq verify (whole process, best of 3)", f"{min(times):.2f} s", "-",
                 None))


def bench_montecarlo(rows, samples):
    """``cas-freq montecarlo`` with the shipped requirements (each sample: the analysis, the
    nonlinear 10 deg step and its second-order fit), whole process, once."""
    executable = shutil.which("cas-freq")
    command = [executable] if executable else [sys.executable, "-m", "cas_freq"]
    argv = [*command, "montecarlo", "--samples", str(samples), "--tolerance", "motor.Km=10%",
            "--tolerance", "motor.J=10%", "--tolerance", "current_loop.delay=0.01ms",
            "--seed", "1", "-q"]
    start = time.perf_counter()
    done = subprocess.run(argv, capture_output=True, text=True, check=False)
    elapsed = time.perf_counter() - start
    shown = f"{elapsed:.1f} s" if done.returncode == 0 else f"exit {done.returncode}"
    rows.append((f"cas-freq montecarlo --samples {samples:,} (steps + fits)", shown, "-", None))


def bench_report(rows):
    """Best and median of 3 of ``cas-freq report`` as a whole process, after one warm-up run
    (the kernel loads from numba's cache): the issue's three variants (base, fitted, relaxed;
    the report includes the fitted variant's load envelope) and the whole shipped config (four
    variants, the load envelopes of fitted and loaded)."""
    import statistics
    import tempfile

    executable = shutil.which("cas-freq")
    command = [executable] if executable else [sys.executable, "-m", "cas_freq"]
    cases = (
        ("cas-freq report (base, fitted, relaxed), whole process",
         ["--variant", "base", "--variant", "fitted", "--variant", "relaxed"]),
        ("cas-freq report (shipped config: 4 variants, 2 envelopes)", []),
    )
    for label, options in cases:
        times = []
        with tempfile.TemporaryDirectory() as folder:
            for attempt in range(4):  # the first run may compile the kernel into numba's cache
                start = time.perf_counter()
                done = subprocess.run([*command, "report", *options, "-o",
                                       str(Path(folder) / "report"), "-q"],
                                      capture_output=True, text=True, check=False)
                if done.returncode != 0:
                    rows.append((label, "failed", "-", None))
                    break
                if attempt:
                    times.append(time.perf_counter() - start)
        if times:
            rows.append((label, f"{min(times):.2f}/{statistics.median(times):.2f} s",
                         "best/median of 3", None))


def bench_memory(params, n):
    rng = np.random.default_rng(SEED)
    loop = variant_parameters(params, variants(params, n, rng))
    tracemalloc.start()
    start = time.perf_counter()
    batch_analyze(loop)
    elapsed = time.perf_counter() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak, elapsed


def actuator_nlsys(config, pade_order):
    """The loop of docs/model.md as a python-control ``nlsys`` with Padé delays: the reference
    implementation the tests check the simulator against (tests/nlsys_reference.py)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from nlsys_reference import actuator_nlsys as reference

    return reference(config, pade_order)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes (smoke run)")
    parser.add_argument("--skip-memory", action="store_true")
    args = parser.parse_args(argv)
    params = load_variant().params
    n = 1000 if args.quick else 10_000
    rows = []
    sample = 20 if args.quick else 100
    differences = bench_margins(params, gain_grid(params, n), "Kp x Kd grid", sample, rows)
    tolerance = variants(params, n, np.random.default_rng(SEED))
    bench_margins(params, tolerance, "6 keys ±10 %", sample, rows)
    notes = []
    rms = bench_step(params, 16 if args.quick else 256, rows, notes)
    bench_sinedwell(params, rows)
    bench_verify(rows)
    bench_montecarlo(rows, 1000 if args.quick else 10_000)
    bench_report(rows)
    print(f"machine: {machine()}")
    print()
    print(f"| {'case':56s} | {'cas_freq':>14s} | {'python-control':>28s} | {'ratio':>7s} |")
    print(f"|{'-' * 58}|{'-' * 16}|{'-' * 30}|{'-' * 9}|")
    for case, ours, theirs, ratio in rows:
        shown = f"{ratio:.0f}x" if ratio else "-"
        print(f"| {case:56s} | {ours:>14s} | {theirs:>28s} | {shown:>7s} |")
    print()
    print("agreement, python-control (Padé-6) vs cas_freq (exact delays), largest relative "
          "difference over the sample:")
    for name, value in differences.items():
        print(f"  {name}: {value:.1e}")
    print(f"10 deg step: RMS difference of the fin angle, python-control nlsys (Padé-8, LSODA "
          f"rtol 1e-9) vs cas_freq: {rms:.1e} of the step")
    for note in notes:
        print(note)
    if not args.skip_memory:
        count = 10_000 if args.quick else 100_000
        peak, elapsed = bench_memory(params, count)
        print(f"frequency-domain batch of {count:,} variants (chunk {DEFAULT_CHUNK}): "
              f"{elapsed:.1f} s under tracemalloc, peak traced memory {peak / 2**20:.0f} MiB")


if __name__ == "__main__":
    main()
