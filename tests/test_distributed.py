"""Studies on a dask.distributed cluster give the local numbers (issue 12).

A local cluster of worker processes (``local:N``) evaluates a Monte Carlo draw cut into chunks;
every figure and verdict must equal the local run's exactly (not to a tolerance): each sample's
figures are computed from that sample alone, in step batches of the same composition, so the
only way to differ would be a bug in the cutting or the joining. Skipped without the
``distributed`` extra.
"""

import contextlib
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cas_freq.config import load_variant
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.tolerances import parse_tolerance
from cas_freq.studies.distributed import chunk_slices, parse_scheduler
from cas_freq.studies.montecarlo import draw
from cas_freq.studies.sweep import evaluate_figures, evaluate_figures_distributed

distributed = pytest.importorskip("distributed", reason="the 'distributed' extra is not installed")

#: Local clusters of worker processes cost seconds each: run by .ci/run (the suite keeps its CPU
#: budget), with ``-m slow``.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def draw_of_40():
    loaded = load_variant(None, "base")
    tolerances = [parse_tolerance(text) for text in
                  ("motor.Km=10%", "motor.J=20%", "current_loop.delay=0.02ms")]
    values, _ = draw(loaded.params, tolerances, 40, "normal", 7)
    return loaded.params, values


def _assert_same(local, remote):
    figures, stability = local
    assert list(remote[0]) == list(figures)
    for name, values in figures.items():
        np.testing.assert_array_equal(remote[0][name], values, err_msg=name)
    np.testing.assert_array_equal(remote[1], stability)


@pytest.mark.parametrize(("workers", "options"), [
    (1, {}),  # frequency-domain figures only
    (2, {"step_rad": math.radians(10), "fit": True}),  # and the nonlinear step with its fit
])
def test_a_local_cluster_gives_the_local_figures_exactly(draw_of_40, workers, options):
    params, values = draw_of_40
    local = evaluate_figures(params, values, **options)
    seen = []
    remote = evaluate_figures_distributed(params, values, f"local:{workers}", chunk_samples=32,
                                          progress=lambda done, total: seen.append(done),
                                          **options)
    _assert_same(local, remote)
    assert sorted(seen) == seen and seen[-1] == 40 and len(seen) == 2  # 32 + 8 samples


def test_chunks_cover_every_sample_once():
    parts = chunk_slices(70, 32)
    assert [(p.start, p.stop) for p in parts] == [(0, 32), (32, 64), (64, 70)]
    assert chunk_slices(0, 32) == []


@pytest.mark.parametrize("text", ["local:0", "local:x", "tcp://", "somewhere", "local:100000",
                                  "8786"])
def test_a_bad_scheduler_is_refused_with_what_is_accepted(text):
    with pytest.raises(CasFreqError, match="--scheduler"):
        parse_scheduler(text)


@pytest.mark.parametrize("text", ["local:4", "tcp://10.0.0.5:8786", "cluster.lab:8786"])
def test_scheduler_forms(text):
    kind, _ = parse_scheduler(text)
    assert kind == ("local" if text.startswith("local") else "address")


def test_a_scheduler_that_does_not_answer_is_a_clear_error(draw_of_40, monkeypatch):
    import cas_freq.studies.distributed as module

    monkeypatch.setattr(module, "CONNECT_TIMEOUT_S", 1.0)
    params, values = draw_of_40
    with pytest.raises(CasFreqError, match="no dask scheduler answers"):
        evaluate_figures_distributed(params, values, "tcp://127.0.0.1:9")


def test_cli_sweep_on_a_local_cluster_prints_what_a_local_run_prints():
    from clirun import run_cli

    argv = ["sweep", "--set", "position_loop.Kp=4:8:40", "--json", "-q"]
    code, local, _ = run_cli(argv)
    assert code == 0
    code, remote, _ = run_cli([*argv, "--scheduler", "local:1"])
    assert code == 0 and remote == local


@pytest.mark.parametrize("command", [["sweep", "--set", "position_loop.Kp=4:8:3"],
                                     ["montecarlo", "--tolerance", "motor.Km=5%", "--no-step"]])
def test_cli_refuses_a_bad_scheduler_before_work(command):
    from clirun import run_cli

    code, _, err = run_cli([*command, "--scheduler", "local:zero"])
    assert code == 2 and "--scheduler" in err and err.count("\n") == 1


def test_several_variants_share_one_cluster(monkeypatch):
    """montecarlo --all-variants --scheduler local:1 starts one local cluster, not one per
    variant, and gives the local output."""
    from clirun import run_cli

    import cas_freq.studies.distributed as module

    started = []
    original = module._new_client

    def counting(scheduler):
        started.append(scheduler)
        return original(scheduler)

    monkeypatch.setattr(module, "_new_client", counting)
    argv = ["montecarlo", "--all-variants", "--samples", "20", "--tolerance", "motor.Km=5%",
            "--no-step", "--seed", "3", "--json", "-q"]
    code, local, _ = run_cli(argv)
    assert code == 0 and started == []
    code, remote, _ = run_cli([*argv, "--scheduler", "local:1"])
    assert code == 0 and remote == local and started == ["local:1"]


def test_losing_every_worker_mid_study_says_the_cluster_was_lost(draw_of_40):
    """Every worker of a local cluster killed (SIGKILL) once the first chunk is back: the
    config scattered to them is lost with them, and so is every chunk still to run. The study
    ends with one CasFreqError (exit 2 from the CLI) saying so, not dask's
    FutureCancelledError traceback (exit 1). Losing one worker recovers (dask reschedules)."""
    import os
    import signal

    import cas_freq.studies.distributed as module

    params, values = draw_of_40
    values = {key: np.tile(column, 16) for key, column in values.items()}  # 20 chunks of 32
    killed = []

    def kill_every_worker(done, total):
        if not killed:
            client = module._OPEN["local:2"]
            for pid in client.run(os.getpid).values():
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)

    with module.session("local:2"), \
            pytest.raises(CasFreqError, match=r"^--scheduler local:2: the dask cluster was "
                          r"lost mid-study after [0-9,]+ of 640 samples: every worker") as info:
        evaluate_figures_distributed(params, values, "local:2", chunk_samples=32,
                                     progress=kill_every_worker)
    assert len(killed) == 2 and "\n" not in str(info.value)


@pytest.mark.skipif(not os.path.exists("/proc/self/stat"), reason="needs Linux's /proc")
def test_sigterm_ends_a_study_on_a_local_cluster_at_once_with_one_line():
    """SIGTERM (handled as Ctrl-C) to ``montecarlo --scheduler local:2`` while both workers
    simulate: closed as usual, the local cluster gave each busy worker the nanny's 4 s grace
    and dask logged two warnings per worker before the one line. Now the workers are killed:
    the command ends with exit 143 and only its line, and no process of its group is left
    (how fast: ``python benchmarks/signals.py --local-cluster``, 0.1 s here, 4.2 s before)."""
    from test_outputs_and_interrupts import _live_group, _wait_group_gone

    process = subprocess.Popen(
        [sys.executable, "-m", "cas_freq", "montecarlo", "--samples", "4000", "--tolerance",
         "motor.Km=5%", "--scheduler", "local:2", "-q"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        cwd=Path(__file__).resolve().parents[1], start_new_session=True)
    try:
        deadline = time.monotonic() + 180
        while len(_live_group(process.pid)) < 3 and process.poll() is None:
            assert time.monotonic() < deadline, "the local cluster's workers did not start"
            time.sleep(0.05)
        time.sleep(3.0)  # the workers are given their chunks and simulate the steps
        assert process.poll() is None, process.communicate()
        process.send_signal(signal.SIGTERM)
        _, err = process.communicate(timeout=30)  # a hang guard, not a speed goal
        _wait_group_gone(process.pid)
    finally:
        for pid in _live_group(process.pid):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        process.communicate()
    assert (process.returncode, err) == (143, "cas-freq montecarlo: terminated (SIGTERM)\n")
