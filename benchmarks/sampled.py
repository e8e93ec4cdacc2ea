"""The frequency-domain batch of sampled controllers against the same batch continuous, in one
run on one machine (``python benchmarks/sampled.py``; not part of the test suite).

Issue 26's check: 10,000 sampled variants in the frequency-domain benchmark within 3x of the
continuous ones. Both are ``batch_analyze`` of the Kp x Kd grid of ``benchmarks/run.py``'s
first case (100 x 100, x0.5..x1.5 of the shipped gains) with ``loop_at_a_time=False`` (the
figures python-control computes there):

- continuous: configs/qt_cas.yaml, variant ``base``;
- sampled: the variant ``sampled`` (the same loop with the EPOS4's rates, current loop
  25 kHz, position loop 2.5 kHz: multirate);
- sampled, single rate: ``sampled`` with both loops at 25 kHz (``--set``-equivalent).

The cases alternate round by round so that a change of the machine's load falls on all; each
time is the median of ``--repeats`` batches (default 3), with the process's CPU time beside the
wall time and the load average before and after (the machine is shared). Options:
``--variants N`` (default 10,000), ``--workers N`` (threads of ``batch_analyze``, default 1).
"""

import argparse
import dataclasses
import math
import os
import statistics
import sys
import time

# BLAS at one thread, as the cas-freq CLI runs it (set before numpy loads)
from cas_freq.cli import limit_blas_threads

limit_blas_threads()

import numpy as np  # noqa: E402

from cas_freq.analysis.analyze import batch_analyze  # noqa: E402
from cas_freq.config import load_variant  # noqa: E402
from cas_freq.core.parameters import variant_parameters  # noqa: E402

#: case -> (variant, sampling rates replacing the variant's, or None to keep them)
CASES = {
    "continuous (base)": ("base", None),
    "sampled 25 kHz / 2.5 kHz (sampled)": ("sampled", None),
    "sampled, both loops 25 kHz": ("sampled", (("current_loop", 25e3), ("position_loop", 25e3))),
}


def grid(variant, rates, n):
    """The Kp x Kd grid of ``benchmarks/run.py`` (about n variants) and 64 of them to warm."""
    params = load_variant(None, variant).params
    side = int(round(math.sqrt(n)))
    kp, kd = np.meshgrid(params.position_loop.Kp * np.linspace(0.5, 1.5, side),
                         params.position_loop.Kd * np.linspace(0.5, 1.5, side), indexing="ij")
    changes = {"position_loop.Kp": kp.ravel(), "position_loop.Kd": kd.ravel()}
    loop = variant_parameters(params, changes)
    warm = variant_parameters(params, {key: value[:64] for key, value in changes.items()})
    if rates is not None:
        loop, warm = (dataclasses.replace(x, sample_rates=rates) for x in (loop, warm))
    return loop, warm


def timed(loop, workers):
    """(wall, CPU) time of one batch [s]."""
    wall, cpu = time.perf_counter(), time.process_time()
    result = batch_analyze(loop, workers=workers, loop_at_a_time=False)
    elapsed = time.perf_counter() - wall, time.process_time() - cpu
    if len(result) != loop.n_runs:  # pragma: no cover (a sanity check)
        raise RuntimeError("batch_analyze returned the wrong number of runs")
    return elapsed


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", type=int, default=10_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args(argv)
    loops = {case: grid(*spec, args.variants) for case, spec in CASES.items()}
    for _, warm in loops.values():  # numba's cache loaded, every chunk path taken once
        timed(warm, args.workers)
    before = os.getloadavg()
    times = {}
    for _ in range(args.repeats):
        for case, (loop, _) in loops.items():
            times.setdefault(case, []).append(timed(loop, args.workers))
    after = os.getloadavg()
    median = {case: (statistics.median(w for w, _ in values),
                     statistics.median(c for _, c in values)) for case, values in times.items()}
    n = next(iter(loops.values()))[0].n_runs
    print(f"{os.cpu_count()} CPUs, Python {sys.version.split()[0]}, numpy {np.__version__}; "
          f"workers {args.workers}; {n:,} variants; medians of {args.repeats}")
    print(f"load average before: {' '.join(f'{v:.2f}' for v in before)}, after: "
          f"{' '.join(f'{v:.2f}' for v in after)}")
    print()
    print(f"| {'batch_analyze':40s} | {'wall':>8s} | {'CPU':>8s} | {'each (wall)':>20s} |")
    print(f"|{'-' * 42}|{'-' * 10}|{'-' * 10}|{'-' * 22}|")
    for case, (wall, cpu) in median.items():
        each = ", ".join(f"{w:.2f}" for w, _ in times[case])
        print(f"| {case:40s} | {wall:>6.2f} s | {cpu:>6.2f} s | {each:>20s} |")
    print()
    reference = median["continuous (base)"]
    for case in list(CASES)[1:]:
        ratio, cpu = (median[case][i] / reference[i] for i in (0, 1))
        verdict = "ok" if ratio <= 3.0 else "NOT met"
        print(f"{case} / continuous: {ratio:.2f} (CPU {cpu:.2f}); goal <= 3: {verdict}")


if __name__ == "__main__":
    main()
