"""The frequency-domain batch of each drive architecture, in one run on one machine
(``python benchmarks/architectures.py``; not part of the test suite).

The check: 10,000 frequency-domain variants of the cascade (configs/cascade_axis.yaml,
P -> PI velocity -> PI current, compliant coupling, notch) cost at most 1.2 times, over the
PID-on-PI's, what they cost a plain numpy evaluation of the same loops (:mod:`numpy_floor`, the
floor, timed in the same rounds). Both are ``batch_analyze`` of a 100 x 100 grid of two gains
of the base variant:

- PID-on-PI (configs/qt_cas.yaml): position_loop.Kp x position_loop.Kd, x0.5..x1.5 (the grid
  of ``benchmarks/run.py``'s first case);
- cascade: position_loop.Kp x velocity_loop.Kp, x0.8..x1.2 (every variant stable: the grid
  stays inside the shipped design's margins);

each with ``loop_at_a_time=False`` (each loop's figures with the loops outside it open) and
``True`` (the inner loops' figures with every other loop closed as well), alternated round by
round so that a change of the machine's load falls on both. Each time is the median of
``--repeats`` batches (default 3); the load average is printed before and after, with the
process's CPU time beside the wall time (the machine is shared).

``--baseline-tree PATH`` also times the PID-on-PI batch of another checkout of cas_freq (an
earlier commit, in a worktree) in a child process each round, for a before/after comparison in
the same run. Options: ``--variants N`` (default 10,000), ``--workers N`` (threads of
``batch_analyze``, default 1: one core, the steadiest figure on a shared machine).
"""

import argparse
import inspect
import json
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

# BLAS at one thread, as the cas-freq CLI runs it (set before numpy loads)
from cas_freq.cli import limit_blas_threads

limit_blas_threads()

import numpy as np  # noqa: E402

from cas_freq.analysis.analyze import batch_analyze  # noqa: E402
from cas_freq.config import load_variant  # noqa: E402
from cas_freq.core.parameters import variant_parameters  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numpy_floor  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: The cascade's cost over the PID-on-PI's may be at most this times the numpy floor's ratio.
GOAL = 1.2

#: name -> (config, first key and its span, second key and its span)
CASES = {
    "PID-on-PI": ("configs/qt_cas.yaml", ("position_loop.Kp", 0.5), ("position_loop.Kd", 0.5)),
    "cascade": ("configs/cascade_axis.yaml", ("position_loop.Kp", 0.2),
                ("velocity_loop.Kp", 0.2)),
}


def grid(case, n, root=ROOT):
    """The case's loop parameters: a side x side grid of its two keys (about n variants)."""
    config, (first, span1), (second, span2) = CASES[case]
    params = load_variant(str(Path(root) / config)).params
    side = int(round(math.sqrt(n)))
    base = {key: _value(params, key) for key in (first, second)}
    x, y = np.meshgrid(base[first] * np.linspace(1 - span1, 1 + span1, side),
                       base[second] * np.linspace(1 - span2, 1 + span2, side), indexing="ij")
    changes = {first: x.ravel(), second: y.ravel()}
    return (variant_parameters(params, changes),
            variant_parameters(params, {key: value[:64] for key, value in changes.items()}))


def _value(params, key):
    section, name = key.split(".")
    return float(getattr(getattr(params, section), name))


def timed(loop, workers, loop_at_a_time):
    """(wall, CPU) time of one batch [s]; ``loop_at_a_time`` None: the code's default (for a
    checkout whose batch_analyze has no such option)."""
    options = {"workers": workers}
    if loop_at_a_time is not None:
        options["loop_at_a_time"] = loop_at_a_time
    wall, cpu = time.perf_counter(), time.process_time()
    result = batch_analyze(loop, **options)
    elapsed = time.perf_counter() - wall, time.process_time() - cpu
    if len(result) != loop.n_runs:  # pragma: no cover (a sanity check)
        raise RuntimeError("batch_analyze returned the wrong number of runs")
    return elapsed


def timed_floor(loop):
    """(wall, CPU) time of the numpy floor's figures of one batch [s]
    (:mod:`numpy_floor`)."""
    wall, cpu = time.perf_counter(), time.process_time()
    numpy_floor.figures(loop)
    return time.perf_counter() - wall, time.process_time() - cpu


def child(args):
    """``--child``: time the PID-on-PI batch of this process's cas_freq once (after a warm
    batch) and print {"wall": s, "cpu": s} (run with PYTHONPATH set to another checkout)."""
    loop, warm = grid("PID-on-PI", args.variants, args.child_root)
    has_option = "loop_at_a_time" in inspect.signature(batch_analyze).parameters
    aat = False if has_option else None
    timed(warm, args.workers, aat)
    wall, cpu = timed(loop, args.workers, aat)
    print(json.dumps({"wall": wall, "cpu": cpu, "option": has_option}))


def baseline(tree, args):
    """(wall, CPU) of the PID-on-PI batch of the checkout ``tree`` in a child process."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), "--child", "--variants",
         str(args.variants), "--workers", str(args.workers), "--child-root", str(tree)],
        capture_output=True, text=True, env=env, cwd=str(tree), check=False)
    if done.returncode != 0:
        raise RuntimeError(f"baseline tree {tree}: {done.stderr.strip()[-400:]}")
    values = json.loads(done.stdout.strip().splitlines()[-1])
    return values["wall"], values["cpu"]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", type=int, default=10_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--baseline-tree", type=Path, default=None,
                        help="another checkout of cas_freq: its PID-on-PI batch, same run")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--child-root", type=Path, default=ROOT, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        return child(args)
    loops = {case: grid(case, args.variants) for case in CASES}
    n = {case: loop.n_runs for case, (loop, _) in loops.items()}
    for _, warm in loops.values():  # numba's cache loaded, every chunk path taken once
        for aat in (False, True):
            timed(warm, args.workers, aat)
    before = os.getloadavg()
    times = {}
    for _ in range(args.repeats):
        for aat in (False, True):
            for case, (loop, _) in loops.items():
                times.setdefault((case, aat), []).append(timed(loop, args.workers, aat))
        for case, (loop, _) in loops.items():
            times.setdefault((case, "numpy"), []).append(timed_floor(loop))
        if args.baseline_tree is not None:
            times.setdefault(("baseline", False), []).append(baseline(args.baseline_tree, args))
    after = os.getloadavg()
    median = {key: (statistics.median(w for w, _ in values),
                    statistics.median(c for _, c in values)) for key, values in times.items()}
    print(f"{os.cpu_count()} CPUs, Python {sys.version.split()[0]}, numpy {np.__version__}; "
          f"workers {args.workers}; medians of {args.repeats}")
    print(f"load average before: {' '.join(f'{v:.2f}' for v in before)}, after: "
          f"{' '.join(f'{v:.2f}' for v in after)}")
    print()
    print(f"| {'batch_analyze':46s} | {'variants':>8s} | {'wall':>8s} | {'CPU':>8s} | "
          f"{'each (wall)':>24s} |")
    print(f"|{'-' * 48}|{'-' * 10}|{'-' * 10}|{'-' * 10}|{'-' * 26}|")
    for (case, aat), (wall, cpu) in median.items():
        label = (f"{case}, older checkout" if case == "baseline" else
                 f"{case}, numpy floor" if aat == "numpy" else
                 f"{case}, loop_at_a_time={aat}")
        each = ", ".join(f"{w:.2f}" for w, _ in times[(case, aat)])
        count = n["PID-on-PI"] if case == "baseline" else n[case]
        print(f"| {label:46s} | {count:>8,} | {wall:>6.2f} s | {cpu:>6.2f} s | {each:>24s} |")
    print()
    floor = median[("cascade", "numpy")][0] / median[("PID-on-PI", "numpy")][0]
    floor_cpu = median[("cascade", "numpy")][1] / median[("PID-on-PI", "numpy")][1]
    print(f"numpy floor, cascade / PID-on-PI: {floor:.2f} (CPU {floor_cpu:.2f})")
    for aat in (False, True):
        ratio = median[("cascade", aat)][0] / median[("PID-on-PI", aat)][0]
        cpu = median[("cascade", aat)][1] / median[("PID-on-PI", aat)][1]
        verdict = "ok" if ratio <= GOAL * floor else "NOT met"
        print(f"cascade / PID-on-PI, loop_at_a_time={aat}: {ratio:.2f} (CPU {cpu:.2f}), "
              f"{ratio / floor:.2f} x the numpy floor's ratio; goal <= {GOAL}: {verdict}")
    for case in CASES:
        ratio = median[(case, True)][0] / median[(case, False)][0]
        print(f"{case}: loop_at_a_time=True / False: {ratio:.2f}")
    if args.baseline_tree is not None:
        ratio = median[("PID-on-PI", False)][0] / median[("baseline", False)][0]
        cpu = median[("PID-on-PI", False)][1] / median[("baseline", False)][1]
        print(f"PID-on-PI (loop_at_a_time=False) / older checkout ({args.baseline_tree}): "
              f"{ratio:.2f} (CPU {cpu:.2f})")
    return None


if __name__ == "__main__":
    main()
