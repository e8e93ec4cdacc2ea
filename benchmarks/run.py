"""cas_freq against python-control, measured in one run on one machine (``python
benchmarks/run.py``; not part of the test suite).

Every time is a median (of 3 unless the row says otherwise) and every row logs the load
average (``os.getloadavg()``, 1 minute) before and after it: the machine may be shared. Whole
processes are timed after a warm-up run (numba's cache filled), with their CPU time (user +
system of the process and the workers it waits for) beside the wall time.

1. the headline table (the README's rows: the toolbox's speed goals): ``cas-freq montecarlo
   --samples 10000`` with the shipped requirements (a step and a fit per sample) and ``cas-freq
   report`` of the shipped config as whole processes (wall and CPU); one 10 deg step of 60 ms
   in-process (the compiled kernel, median of 21) against python-control's
   ``input_output_response`` of an ``nlsys`` of the same loop (tests/nlsys_reference.py; Padé-8
   delays at LSODA rtol 1e-9, atol 1e-10, the cross-check of tests/test_simulation_nlsys.py, and
   its fastest run, Padé-1 at LSODA's default tolerances), in three rounds each timing both (the
   ratio: the median of the rounds'), with the RMS difference of the output angles; the
   sine-dwell map of 8 amplitudes x 30 frequencies; each beside its goal;
2. margins + bandwidth of 10,000 variants (a 100 x 100 grid of Kp and Kd; and random
   gains and motor values, ±10 % around the shipped config), one run each: cas_freq's batch
   (exact delays, Padé-6 stability) vs the strongest fair baseline, a careful python-control
   loop with exact delays (benchmarks/baselines.py, ``CarefulBaseline``; every variant timed),
   and a numpy floor (benchmarks/numpy_floor.py; the Kp x Kd rows are headline rows), and,
   labelled, two weaker python-control loops with Padé-6 delays: the naive one
   (transfer-function arithmetic, ``stability_margins`` of both loops, ``bandwidth`` of T,
   timed on a sample of 100 and extrapolated) and an improved one (numpy polynomials, the
   current loop cached, a fixed-grid bandwidth; timed on 1,000);
3. the 10 deg step in a batch of 256 (per run), with the numpy reference engine, at the
   default horizon, and ``cas-freq simulate --step 10deg`` as a whole process with either
   engine; ``cas-freq report`` of base, fitted and relaxed; ``cas-freq verify``;
4. peak memory (tracemalloc) of the frequency-domain batch for 100,000 variants.

Options: ``--quick`` (fewer variants, for a smoke run), ``--skip-memory``, ``--only CASE``
(repeatable: ``headline``, ``margins``, ``step``, ``sinedwell``, ``verify``, ``montecarlo``,
``report``), ``--write-docs`` (the table, as printed, replaces the one between the
``speed-table`` markers of README.md and docs/speed.md: the one source of both).
"""

import argparse
import dataclasses
import json
import math
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

# BLAS at one thread, as the cas-freq CLI runs it (set before numpy loads): the toolbox's
# linear algebra is many small matrices, where BLAS threads only contend (and OpenBLAS's
# worker spins on a core for ~0.1 s after each call, taking it from the simulation kernel).
from cas_freq.cli import limit_blas_threads

limit_blas_threads()

import numpy as np  # noqa: E402
import numpy_floor  # noqa: E402
from baselines import CarefulBaseline, ImprovedBaseline  # noqa: E402

from cas_freq.analysis.analyze import DEFAULT_CHUNK, batch_analyze  # noqa: E402
from cas_freq.analysis.frequency import (  # noqa: E402
    DEFAULT_POINTS_PER_DECADE,
    DEFAULT_RANGE_RAD_S,
    frequency_grid,
)
from cas_freq.config import load_variant  # noqa: E402
from cas_freq.core.parameters import variant_parameters  # noqa: E402
from cas_freq.model.loops import Selector  # noqa: E402
from cas_freq.model.structure import total_delay  # noqa: E402

SEED = 20261122
ROOT = Path(__file__).resolve().parents[1]
#: The files whose speed table ``--write-docs`` replaces (between these markers), each with
#: whether it shows the headline rows only (the README) or every row.
DOCS = {ROOT / "README.md": True, ROOT / "docs" / "speed.md": False}
TABLE_START, TABLE_END = "<!-- speed-table:start -->", "<!-- speed-table:end -->"
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


@dataclasses.dataclass
class Row:
    """One row of the table: what cas_freq took, the baseline, their ratio, the goal, the load
    average before and after; ``headline``: a row of the headline table (the README's)."""

    case: str
    ours: str
    theirs: str = "–"
    ratio: float | None = None
    goal: str = "–"
    load: str = ""
    headline: bool = False


class Load:
    """The 1-minute load average before and after a block (``with Load() as load: ...``;
    ``load.text``)."""

    def __enter__(self):
        self.before = os.getloadavg()[0]
        return self

    def __exit__(self, *exc):
        self.after = os.getloadavg()[0]
        return False

    @property
    def text(self):
        return f"{self.before:.1f}–{self.after:.1f}"


def cas_freq_command():
    """The CLI as a command line: ``cas-freq`` if installed, else ``python -m cas_freq``."""
    executable = shutil.which("cas-freq")
    return [executable] if executable else [sys.executable, "-m", "cas_freq"]


def _median(function, repeats):
    """Median wall time of ``repeats`` calls [s] and the last call's result."""
    wall, _, result = _timed(function, repeats)
    return wall, result


def _timed(function, repeats):
    """Median wall time and median CPU time (every thread of this process) of ``repeats``
    calls [s], and the last call's result."""
    walls, cpus = [], []
    for _ in range(repeats):
        cpu, start = time.process_time(), time.perf_counter()
        result = function()
        walls.append(time.perf_counter() - start)
        cpus.append(time.process_time() - cpu)
    return statistics.median(walls), statistics.median(cpus), result


def process_times(argv, repeats=3, engine=None):
    """Median wall and median CPU time [s] of ``argv`` run as a process ``repeats`` times after
    one warm-up run (which may compile the kernels into numba's cache); CPU is user + system
    time of the process and of the children it waited for (``RUSAGE_CHILDREN``); ``engine``
    sets ``CAS_FREQ_ENGINE``. None when a run fails."""
    env = {**os.environ, **({"CAS_FREQ_ENGINE": engine} if engine else {})}
    walls, cpus = [], []
    for attempt in range(repeats + 1):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        done = subprocess.run(argv, capture_output=True, text=True, check=False, env=env)
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if done.returncode != 0:
            return None
        if attempt:
            walls.append(wall)
            cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return statistics.median(walls), statistics.median(cpus)


def variants(params, n, rng):
    """Random variants: each key uniform within ±10 % of the config's value."""
    from cas_freq.core.parameters import base_values

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


def bench_margins(params, changes, label, sample, rows, headline=False):
    with Load() as load:
        differences = _margins(params, changes, label, sample, rows, headline)
    for row in rows[-4:]:
        row.load = load.text
    return differences


def _margins(params, changes, label, sample, rows, headline=False):
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
    naive = Row("same (a weaker baseline)", f"{ours:.2f} s",
                f"naive, Padé-6 {extrapolated:.0f} s ({per_variant * 1e3:.1f} ms × {n:,})",
                extrapolated / ours, "≥ 100×")
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
    improved_row = Row("same (a weaker baseline)", f"{ours:.2f} s", f"improved, Padé-6 "
                       f"{per_variant * n:.0f} s ({per_variant * 1e3:.2f} ms × {n:,})",
                       per_variant * n / ours, "≥ 10×")
    # the strongest fair baseline (benchmarks/baselines.py, CarefulBaseline): exact delays,
    # frequency_response on cas_freq's own grid, the figures interpolated there; every variant
    omega = frequency_grid(*DEFAULT_RANGE_RAD_S, DEFAULT_POINTS_PER_DECADE,
                           total_delay(Selector(loop)()))
    careful = CarefulBaseline(params, omega)
    careful.figures(changes, 0)
    start = time.perf_counter()
    best = [careful.figures(changes, i) for i in range(n)]
    strongest = time.perf_counter() - start
    for name in best[0]:
        differences[f"{name} (careful, exact delays)"] = max(
            abs(best[i][name] - result.figures[name][i]) / abs(result.figures[name][i])
            for i in range(n))
    careful_row = Row(f"margins + bandwidth, {n:,} variants ({label}; one run)",
                      f"{ours:.2f} s", f"careful, exact delays {strongest:.2f} s "
                      f"({strongest / n * 1e3:.2f} ms × {n:,})", strongest / ours, "≥ 2×",
                      headline=headline)
    # the numpy floor (benchmarks/numpy_floor.py): the same figures on the same grid, all
    # variants at once, nothing refined and no stability verdict
    numpy_floor.figures(variant_parameters(params, {k: v[:64] for k, v in changes.items()}))
    start = time.perf_counter()
    numpy_floor.figures(loop)
    floor = time.perf_counter() - start
    floor_row = Row("same", f"{ours:.2f} s", f"numpy floor {floor:.2f} s (not python-control: "
                    "grid figures only, no stability verdict)", floor / ours, "–",
                    headline=headline)
    rows.extend([careful_row, floor_row, naive, improved_row])
    return differences


def _ms(seconds):
    return f"{seconds * 1e3:.2f} ms" if seconds < 0.01 else f"{seconds * 1e3:.0f} ms"


def _control_step(params, t, amplitude, pade_order, **solver):
    """python-control's ``input_output_response`` of the loop's ``nlsys`` (Padé delays of
    ``pade_order``) to a step of ``amplitude`` [rad] at the output on the grid ``t``: the
    output angle [rad]."""
    import control

    system = actuator_nlsys(params, pade_order)
    theta_cmd = np.full(t.size, params.gear.ratio * amplitude)
    response = control.input_output_response(
        system, t, theta_cmd, np.zeros(system.nstates), t_eval=t, solve_ivp_method="LSODA",
        **({"solve_ivp_kwargs": solver} if solver else {}))
    return response.states[2] / params.gear.ratio


def bench_api_step(rows, repeats=21):
    """One step from the Python API, as a user calls it: ``cas_freq.load().simulate(step="10
    deg")`` on the shipped base variant (the default horizon with its extension, the step
    figures and the second-order fit; the linear verdict found at the first call), median of
    ``repeats`` calls after a warm-up."""
    import cas_freq

    actuator = cas_freq.load(str(ROOT / "configs" / "qt_cas.yaml"))
    with Load() as load:
        actuator.simulate(step="10 deg")  # warm: the kernel loaded, the verdict found
        seconds, _ = _median(lambda: actuator.simulate(step="10 deg"), repeats)
    rows.append(Row(f"one 10° step from the API, `simulate(step=\"10 deg\")` with figures and "
                    f"fit (median of {repeats})", _ms(seconds), goal="≤ 2 ms", load=load.text,
                    headline=True))


def bench_headline_step(params, rows, repeats, rounds=3):
    """Headline row 3: one 10 deg step of 60 ms at the default 5 us, in-process (the
    compiled kernel, median of ``repeats``), against python-control's nlsys with Padé-8 delays
    (LSODA rtol 1e-9, atol 1e-10: the cross-check of tests/test_simulation_nlsys.py) and its
    fastest run (Padé-1, LSODA at its default tolerances).

    ``rounds`` rounds, each timing ours and then one run of each python-control case: a shared
    machine's speed changes over seconds (this one's has a slow state, in which our step
    takes ~1.9 times as long), so each round's ratio compares the two in the same state; the
    row shows the median times and the median of the rounds' ratios.
    """
    from cas_freq.core.parameters import LoopParameters
    from cas_freq.simulation import Step, simulate_batch

    amplitude = math.radians(10.0)
    one = LoopParameters.from_config(params)

    def step():  # recording the output only: what the comparison reads
        return simulate_batch(one, Step(amplitude), engine="compiled", t_end=0.06, extend=False,
                              signals=("theta",))

    ours, accurate, fastest = [], [], []
    with Load() as load:
        t = step().t  # warm-up (loads the kernel from numba's cache); the time grid
        for _ in range(rounds):
            wall, result = _median(step, repeats)
            ours.append(wall)
            wall, theirs = _median(
                lambda: _control_step(params, t, amplitude, 8, rtol=1e-9, atol=1e-10), 1)
            accurate.append(wall)
            wall, rough = _median(lambda: _control_step(params, t, amplitude, 1), 1)
            fastest.append(wall)
    delta = result.delta[0]
    rms = [float(np.sqrt(np.mean((other - delta) ** 2)) / amplitude) for other in (theirs, rough)]
    ours_ms = _ms(statistics.median(ours))
    case = (f"one 10° step in-process, 60 ms at 5 µs (median of {repeats}; {rounds} rounds, "
            "each with python-control's)")
    for name, order, walls, difference, goal in (
            (case, 8, accurate, rms[0], "≤ 0.3 ms, ≥ 1,000×"),
            ("same", 1, fastest, rms[1], "≥ 50×")):
        ratio = statistics.median([their / our for their, our in zip(walls, ours, strict=True)])
        theirs_text = f"nlsys Padé-{order} {_ms(statistics.median(walls))}"
        rows.append(Row(name, ours_ms, f"{theirs_text} (RMS diff {difference:.0e})", ratio, goal,
                        load.text, headline=True))


def bench_step(params, runs, rows, notes):
    """10 deg steps: the compiled kernel and the numpy reference engine (batch and one run)."""
    from cas_freq.core.parameters import LoopParameters
    from cas_freq.simulation import Step, simulate_batch

    amplitude = math.radians(10.0)
    one = LoopParameters.from_config(params)
    batch = LoopParameters.from_configs([params] * runs)

    def step(loop, engine, **options):
        options = {"t_end": 0.06, "extend": False, **options}
        return simulate_batch(loop, Step(amplitude), engine=engine, **options)

    with Load() as load:
        step(one, "compiled", t_end=0.002)  # warm-up (loads the kernel from numba's cache)
        step(batch, "compiled", t_end=0.002)
        ours_batch = _median(lambda: step(batch, "compiled"), 3)[0] / runs
        ours_single, single = _median(lambda: step(one, "compiled"), 5)
        ref_single, reference = _median(lambda: step(one, "reference"), 3)
        ref_batch = _median(lambda: step(batch, "reference"), 1)[0] / runs
        # the default horizon with its extension, as cas-freq simulate runs it
        ours_default = _median(lambda: step(one, "compiled", t_end=None, extend=True), 5)[0]
        ref_default = _median(lambda: step(one, "reference", t_end=None, extend=True), 1)[0]
    rows.append(Row(f"10° step, 60 ms, batch of {runs} (per run; median of 3)",
                    _ms(ours_batch), load=load.text))
    rows.append(Row("same, numpy reference engine (per run; one batch)", _ms(ref_batch),
                    load=load.text))
    rows.append(Row("10° step, 60 ms, numpy reference engine (one run)", _ms(ref_single),
                    load=load.text))
    rows.append(Row("10° step, default horizon (0.1 s + extension, one run; median of 5)",
                    _ms(ours_default), load=load.text))
    rows.append(Row("same, numpy reference engine (one run)", _ms(ref_default), load=load.text))
    with Load() as load:
        for engine in ("compiled", "reference"):
            times = process_times([*cas_freq_command(), "simulate", "--step", "10deg"],
                                  engine=engine)
            rows.append(Row(f"`cas-freq simulate --step 10deg` (whole process, {engine})",
                            _process_text(times), goal="< 0.5 s" if engine == "compiled"
                            else "–"))
    for row in rows[-2:]:
        row.load = load.text
    difference = float(np.max(np.abs(single.delta - reference.delta)) / amplitude)
    notes.append(
        f"10° step, compiled kernel vs numpy reference engine: {ref_single / ours_single:.0f}× "
        f"(one run), {ref_batch / ours_batch:.0f}× (batch of {runs}, per run), "
        f"{ref_default / ours_default:.0f}× (default horizon); largest difference of the "
        f"output angle {difference:.1e} of the step; numba threads {_numba_threads()}"
    )


def _numba_threads():
    try:
        import numba
    except ImportError:
        return "- (numba not installed)"
    return numba.get_num_threads()


def _process_text(times):
    """``"1.23 s (CPU 2.34 s)"`` of :func:`process_times`' result; "failed" for None."""
    if times is None:
        return "failed"
    wall, cpu = times
    return f"{wall:.2f} s (CPU {cpu:.2f} s)"


def bench_sinedwell(params, rows):
    """Headline row 4: the sine-dwell map of 8 amplitudes x 30 frequencies (100..5000
    rad/s) of the shipped config, median of 3 after a warm-up of the kernel."""
    from cas_freq.core.parameters import LoopParameters
    from cas_freq.simulation.sinedwell import sine_dwell

    amplitudes = np.radians([0.25, 0.5, 1, 2, 4, 6, 8, 10])
    frequencies = np.geomspace(100.0, 5000.0, 30)
    loop = LoopParameters.from_config(params)
    with Load() as load:
        sine_dwell(loop, amplitudes[:1], frequencies[-1:])  # warm-up
        wall, cpu, _ = _timed(lambda: sine_dwell(loop, amplitudes, frequencies), 3)
    rows.append(Row("sine-dwell map 8 × 30 (median of 3)", f"{wall:.2f} s (CPU {cpu:.2f} s)",
                    goal="≤ 1.5 s", load=load.text, headline=True))


def bench_verify(rows):
    with Load() as load:
        times = process_times([*cas_freq_command(), "verify"])
    rows.append(Row("`cas-freq verify` (whole process; the shipped config)",
                    _process_text(times), goal="< 1.5 s", load=load.text))


def bench_montecarlo(rows, samples):
    """Headline row 1: ``cas-freq montecarlo`` with the shipped requirements (each sample:
    the analysis, the nonlinear 10 deg step and its second-order fit), whole process."""
    argv = [*cas_freq_command(), "montecarlo", "--samples", str(samples), "--tolerance",
            "motor.Km=10%", "--tolerance", "motor.J=10%", "--tolerance",
            "current_loop.delay=0.01ms", "--seed", "1", "-q"]
    with Load() as load:
        times = process_times(argv)
    rows.append(Row(f"`cas-freq montecarlo --samples {samples}` (steps and fits; whole process)",
                    _process_text(times), goal="≤ 10 s" if samples == 10_000 else "–",
                    load=load.text, headline=True))


#: The 6-key box of the worst-case row (issue 42's benchmark).
WORST_CASE_BOX = ("motor.Km=10%", "motor.R=20%", "motor.J=10%", "motor.L=20%",
                  "current_loop.delay=0.01ms", "position_loop.Kp=5%")


def bench_worstcase(rows):
    """The worst case of every requirement of the shipped config over a 6-key box (corners,
    256 samples, the compass search), whole process, with the evaluations it counted."""
    argv = [*cas_freq_command(), "worstcase", "--json", "-q"]
    for text in WORST_CASE_BOX:
        argv += ["--tolerance", text]
    with Load() as load:
        times = process_times(argv)
        counted = json.loads(subprocess.run(argv, capture_output=True, text=True,
                                            check=True).stdout)["search"]["evaluations"]
    rows.append(Row(f"`cas-freq worstcase`, 6-key box ({counted['analyze']} loop evaluations, "
                    f"{counted['step']} steps; whole process)", _process_text(times),
                    goal="≤ 30 s", load=load.text, headline=True))


def bench_report(rows):
    """Headline row 2: ``cas-freq report`` of the shipped config (every variant, the load
    envelopes), whole process, wall and CPU; and of base, fitted and relaxed."""
    cases = (
        ("`cas-freq report` (shipped config: all variants, load envelopes; whole process)", [],
         "≤ 6 s wall, ≤ 7 s CPU", True),
        ("`cas-freq report --variant base --variant fitted --variant relaxed`",
         ["--variant", "base", "--variant", "fitted", "--variant", "relaxed"], "–", False),
    )
    for label, options, goal, headline in cases:
        with Load() as load, tempfile.TemporaryDirectory() as folder:
            times = process_times([*cas_freq_command(), "report", *options, "-o",
                                   str(Path(folder) / "report"), "-q"])
        rows.append(Row(label, _process_text(times), goal=goal, load=load.text,
                        headline=headline))


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


def table(rows):
    """The rows as a Markdown table (what ``--write-docs`` puts in the docs)."""
    lines = ["| case | cas_freq | python-control | ratio | goal | load |",
             "| --- | --- | --- | --- | --- | --- |"]
    for row in rows:
        ratio = "–" if not row.ratio else (
            f"{row.ratio:,.0f}×" if row.ratio >= 10 else f"{row.ratio:.2g}×")
        lines.append(f"| {row.case} | {row.ours} | {row.theirs} | {ratio} | {row.goal} | "
                     f"{row.load} |")
    return "\n".join(lines)


def write_docs(rows, heading, paths=DOCS):
    """Replace the text between :data:`TABLE_START` and :data:`TABLE_END` in each of ``paths``
    (path -> headline rows only) with ``heading`` and the table; a file without both markers is
    an error (nothing is written then)."""
    contents = {}
    for path, headline in paths.items():
        text = heading + table([row for row in rows if row.headline or not headline])
        old = path.read_text(encoding="utf-8")
        if old.count(TABLE_START) != 1 or old.count(TABLE_END) != 1:
            raise SystemExit(f"{path}: need one {TABLE_START} and one {TABLE_END} line")
        before, rest = old.split(TABLE_START)
        contents[path] = before + TABLE_START + "\n" + text + "\n" + TABLE_END + \
            rest.split(TABLE_END, 1)[1]
    for path, new in contents.items():
        path.write_text(new, encoding="utf-8")


CASES = ("headline", "margins", "step", "sinedwell", "verify", "montecarlo", "report",
         "worstcase")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes (smoke run)")
    parser.add_argument("--skip-memory", action="store_true")
    parser.add_argument("--only", action="append", choices=CASES,
                        help="run only these cases (repeatable; 'headline': the README's rows)")
    parser.add_argument("--write-docs", action="store_true",
                        help="put the table into README.md and docs/speed.md (between the "
                             "speed-table markers)")
    args = parser.parse_args(argv)
    chosen = set(args.only or CASES)
    if "headline" in chosen:
        chosen |= {"montecarlo", "report", "sinedwell", "margins"}
    params = load_variant().params
    n = 1000 if args.quick else 10_000
    rows, notes, differences = [], [], {}
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    # the headline table first
    if "montecarlo" in chosen:
        bench_montecarlo(rows, 1000 if args.quick else 10_000)
    if "report" in chosen:
        bench_report(rows)
    if {"headline", "step"} & chosen:
        bench_headline_step(params, rows, 5 if args.quick else 21)
        bench_api_step(rows, 5 if args.quick else 21)
    if "sinedwell" in chosen:
        bench_sinedwell(params, rows)
    if "margins" in chosen:
        sample = 20 if args.quick else 100
        differences = bench_margins(params, gain_grid(params, n), "Kp × Kd grid", sample, rows,
                                    headline=True)
        tolerance = variants(params, n, np.random.default_rng(SEED))
        bench_margins(params, tolerance, "6 keys ±10 %", sample, rows)
    if "step" in chosen:
        bench_step(params, 16 if args.quick else 256, rows, notes)
    if "verify" in chosen:
        bench_verify(rows)
    if "worstcase" in chosen:
        bench_worstcase(rows)
    text = table(rows)
    print(f"machine: {machine()}; {started}; BLAS at one thread")
    print()
    print(text)
    print()
    if differences:
        print("agreement, python-control (Padé-6) vs cas_freq (exact delays), largest relative "
              "difference over the sample:")
        for name, value in differences.items():
            print(f"  {name}: {value:.1e}")
    for note in notes:
        print(note)
    if not args.skip_memory and "margins" in chosen:
        count = 10_000 if args.quick else 100_000
        peak, elapsed = bench_memory(params, count)
        print(f"frequency-domain batch of {count:,} variants (chunk {DEFAULT_CHUNK}): "
              f"{elapsed:.1f} s under tracemalloc, peak traced memory {peak / 2**20:.0f} MiB")
    if args.write_docs:
        write_docs(rows, f"Measured {started} by `python benchmarks/run.py` on {machine()} "
                   "(BLAS at one thread; load: the 1-minute load average before–after each "
                   "row; whole processes after a warm-up run).\n\n")


if __name__ == "__main__":
    main()
