"""Server-side time per change of ``cas-freq design`` (``python benchmarks/design.py``; not part
of the test suite).

Issue 29's budget (this 2-core machine): the frequency figures within 100 ms per change, with
the nonlinear step within 300 ms. Each change is what the server does for one request
(:meth:`cas_freq.design.server.Design.state`: check the values, load the config with them as
``--set`` overrides, :func:`cas_freq.design.compute.design_state`, the JSON text), the gain
``position_loop.Kp`` moved to a new value each time (x0.6..x1.6 of the variant's), first
without the nonlinear step, then with it. The times are medians of ``--changes`` changes
(default 30) after ``--warm`` (default 3) not counted (the numba kernels' load); the CPU time
of the process and the load average before and after are printed beside them (the machine is
shared). ``--config`` and ``--variant`` choose another design (default: the shipped qt_cas
base); ``--key`` another gain.
"""

import argparse
import json
import os
import statistics
import time

from cas_freq.cli import limit_blas_threads

limit_blas_threads()


def changes(design, key, count, nonlinear, session):
    """(wall [s], CPU [s]) of each of ``count`` requests moving ``key``."""
    base = next(c["value"] for c in design.controls if c["key"] == key)
    times = []
    for index in range(count):
        value = base * (0.6 + index / max(count - 1, 1))
        start, cpu = time.perf_counter(), time.process_time()
        answer = design.state({"session": session, "seq": index, "nonlinear": nonlinear,
                               "values": {key: f"{value:.6g}"}})
        json.dumps(answer)
        times.append((time.perf_counter() - start, time.process_time() - cpu))
        assert "errors" not in answer, answer
    return times


def main():
    """Print the medians."""
    from cas_freq.config import default_config_path
    from cas_freq.design.server import Design

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default=str(default_config_path()))
    parser.add_argument("--variant", default="base")
    parser.add_argument("--key", default="position_loop.Kp")
    parser.add_argument("--changes", type=int, default=30)
    parser.add_argument("--warm", type=int, default=3)
    args = parser.parse_args()
    design = Design(args.config, args.variant)
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    for nonlinear, budget in ((False, 0.100), (True, 0.300)):
        what = "with the nonlinear step" if nonlinear else "frequency figures + linear step"
        changes(design, args.key, args.warm, nonlinear, f"warm-{nonlinear}")
        times = changes(design, args.key, args.changes, nonlinear, f"bench-{nonlinear}")
        wall = statistics.median(t for t, _ in times)
        cpu = statistics.median(c for _, c in times)
        print(f"{what}: median {wall * 1e3:.1f} ms wall, {cpu * 1e3:.1f} ms CPU per change "
              f"({args.changes} changes; budget {budget * 1e3:.0f} ms: "
              f"{'met' if wall <= budget else 'NOT met'})")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
