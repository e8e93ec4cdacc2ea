"""How fast a signalled ``cas-freq report`` ends, against its goal (``python
benchmarks/signals.py``; Linux; not part of the test suite, which checks that it ends and how:
tests/test_outputs_and_interrupts.py).

Each run starts ``python -m cas_freq report -o TMP`` in a process group of its own, waits until
its two figure workers run, then ``--delay`` seconds more (default 1, 3 and 6: the first
variant's computation), and sends

- Ctrl-C: SIGINT to the process group, as a terminal does; measured until the report exits
  (goal: 1 s);
- SIGTERM to the report alone, as ``kill`` does; measured until no process of the group is
  alive (goal: 2 s);
- SIGKILL to the report alone; measured until no process of the group is alive (goal: 2 s;
  the workers get SIGKILL from the kernel at their parent's death).

With ``--local-cluster`` the process is ``montecarlo --scheduler local:2`` (two dask worker
processes; the same goals). With ``--first-run`` each report starts with an empty
``NUMBA_CACHE_DIR`` and the signal goes ``--delay`` seconds after its "compiling the numerical
kernels" line (default 1, 3, 6), while it compiles: its stderr must then be that line and the
one line of the signal, nothing else (no "Exception ignored", no traceback). A process killed
but not yet reaped by init (a zombie) counts as ended. Printed: per signal,
the median and the slowest time over the runs; exit status 1 when a median misses its goal.
"""

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: (name, signal, to the group, measured until: "exit" or "gone", goal [s]).
CASES = (("Ctrl-C (SIGINT to the group) -> exit", signal.SIGINT, True, "exit", 1.0),
         ("SIGTERM -> no process left", signal.SIGTERM, False, "gone", 2.0),
         ("SIGKILL -> no process left", signal.SIGKILL, False, "gone", 2.0))

#: Longest wait for the workers to start, and for the processes to end [s].
START_S, END_S = 180.0, 30.0


def live_group(pgid):
    """Pids of the live (not zombie) processes of process group ``pgid``."""
    pids = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat", encoding="ascii", errors="replace") as stream:
                    fields = stream.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[2]) == pgid and fields[0] not in ("Z", "X"):
                pids.append(int(entry))
    return pids


def _default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # also when started as a background job


#: The study ``--local-cluster`` signals: its two workers simulate a step per sample.
LOCAL_CLUSTER = ("montecarlo", "-q", "--samples", "4000", "--tolerance", "motor.Km=5%",
                 "--scheduler", "local:2")


#: The first line of a run that compiles kernels (cas_freq.core.jit), and the lines that may follow
#: it
#: before the signal's: the time so far, the report's progress.
COMPILING = "cas-freq: compiling the numerical kernels"
PROGRESS = ("cas-freq: still compiling", "report: ")


def one_run(number, to_group, until, delay, folder, local_cluster=False, first_run=False):
    """Seconds from the signal to the process's exit (``until="exit"``) or to no process of it
    alive (``"gone"``)."""
    command = LOCAL_CLUSTER if local_cluster else ("report", "-q", "-o", str(folder / "report"))
    env = None
    if first_run:  # the compiling told on stderr (no -q), an empty cache of its own
        command = ("report", "-o", str(folder / "report"))
        env = dict(os.environ, NUMBA_CACHE_DIR=tempfile.mkdtemp(dir=folder))
    process = subprocess.Popen(
        [sys.executable, "-m", "cas_freq", *command],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True,
        preexec_fn=_default_sigint, env=env, text=True)
    try:
        deadline = time.monotonic() + START_S
        if first_run:
            first = process.stderr.readline()
            if not first.startswith(COMPILING):
                raise RuntimeError(f"no compiling line: {first!r}")
        while not first_run and len(live_group(process.pid)) < 3:
            if process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"the workers did not start: "
                                   f"{process.communicate()[1][-400:]!r}")
            time.sleep(0.01)
        time.sleep(delay)
        sent = time.monotonic()
        if to_group:
            os.killpg(process.pid, number)
        else:
            process.send_signal(number)
        while (process.poll() is None if until == "exit" else live_group(process.pid)):
            if time.monotonic() - sent > END_S:
                raise RuntimeError(f"still running {END_S:g} s after the signal")
            time.sleep(0.005)
        took = time.monotonic() - sent
        if first_run and number != signal.SIGKILL:
            stderr = process.communicate()[1]
            lines = [line for line in stderr.splitlines() if not line.startswith(PROGRESS)]
            if len(lines) != 1 or not lines[0].startswith("cas-freq report: "):
                raise RuntimeError(f"stderr after the signal is not its one line: {lines!r}")
        return took
    finally:
        for pid in live_group(process.pid):
            os.kill(pid, signal.SIGKILL)
        if not process.stderr.closed:  # not read to its end above
            process.communicate()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--delay", type=float, action="append",
                        help="seconds after the workers start (repeatable; default 1, 3, 6)")
    parser.add_argument("--local-cluster", action="store_true",
                        help="signal a Monte Carlo study on a local dask cluster instead")
    parser.add_argument("--first-run", action="store_true",
                        help="signal first reports (empty numba cache) while they compile")
    args = parser.parse_args(argv)
    delays = args.delay or [1.0, 3.0, 6.0]
    missed = False
    print(f"| {'signal':<38} | runs | median | slowest | goal |      |")
    print(f"|{'-' * 40}|------|--------|---------|------|------|")
    with tempfile.TemporaryDirectory() as folder:
        for name, number, to_group, until, goal in CASES:
            times = [one_run(number, to_group, until, delay, Path(folder), args.local_cluster,
                             args.first_run)
                     for delay in delays]
            median = statistics.median(times)
            missed |= median > goal
            print(f"| {name:<38} | {len(times):>4} | {median:>4.2f} s | {max(times):>5.2f} s "
                  f"| {goal:g} s | {'ok' if median <= goal else 'MISS':<4} |", flush=True)
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
