"""The first ``cas-freq report`` after an install against a warm one (``python
benchmarks/first_run.py``; not part of the test suite).

Issue 28's goal: the first report, whose numba kernels are not in any cache yet, takes at most
2.5 x a warm report + 10 s. Measured as whole processes of ``cas-freq report`` of the shipped
config into a temporary folder:

1. cold: ``NUMBA_CACHE_DIR`` a fresh empty folder (numba then neither reads nor writes the
   ``__pycache__`` next to the kernels), so every kernel the report uses compiles;
2. warm: ``--runs`` more reports with the same folder (the kernels load from it); their median.

Printed: the times, the compilation time the first report states on stderr, the load average
before and after (the machine is shared: a loaded machine slows the cold run most), the ratio
cold / warm and the goal; exit status 1 when the cold report misses the goal.
"""

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def report(cache, out):
    """Wall time [s] and stderr of one ``cas-freq report -o out`` with numba's cache in
    ``cache``."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache),
               PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "cas_freq", "report", "-o", str(out)],
                          env=env, capture_output=True, text=True, check=True)
    return time.perf_counter() - start, done.stderr


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="warm reports (default 3)")
    args = parser.parse_args()
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "numba"
        cache.mkdir()
        cold, stderr = report(cache, Path(tmp) / "cold")
        warm = [report(cache, Path(tmp) / f"warm{i}")[0] for i in range(args.runs)]
    load_after = os.getloadavg()
    compiled = re.search(r"compiled the numerical kernels in ([\d.]+) s", stderr)
    median = statistics.median(warm)
    goal = 2.5 * median + 10.0
    print(f"load average before: {load_before[0]:.2f} {load_before[1]:.2f} {load_before[2]:.2f},"
          f" after: {load_after[0]:.2f} {load_after[1]:.2f} {load_after[2]:.2f}")
    print("| case                                   |     time |")
    print("|----------------------------------------|----------|")
    print(f"| first report (empty NUMBA_CACHE_DIR)   | {cold:6.1f} s |")
    seconds = compiled.group(1) if compiled else "-"
    print(f"|   of which compiling (its own message) | {seconds:>6} s |")
    print(f"| warm report, median of {len(warm)}               | {median:6.1f} s |")
    print(f"|   (each: {', '.join(f'{w:.1f}' for w in warm)} s)")
    print(f"| goal: 2.5 x warm + 10 s                | {goal:6.1f} s |")
    print(f"cold / warm = {cold / median:.2f}; cold / goal = {cold / goal:.2f}: "
          f"{'ok' if cold <= goal else 'MISSED'}")
    return 0 if cold <= goal else 1


if __name__ == "__main__":
    sys.exit(main())
