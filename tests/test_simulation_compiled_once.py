"""One compilation of the simulation kernels serves every architecture and every variant.

The kernels take the architecture as data (:mod:`cas_freq.simulation.architecture`'s tables:
float64 2-D tables, int64 index arrays, the same tuple whatever the loops), so numba types
every call alike: after simulating the report's PID-on-PI, the velocity cascade with its
filters, a sampled cascade and a loaded drivetrain, with one run (the serial kernel) and two
(the parallel one), each kernel's dispatcher holds one signature (the loop over one run's
steps, ``_advance_run``, too). A kernel typed once per architecture (an argument None for one
and an array for another, a tuple of another length) holds two or more here, and a fresh
install compiles each of them again.
"""

import dataclasses
import math

import numba
import pytest

from cas_freq.config.loader import load_variant, shipped_configs_dir
from cas_freq.core.filters_config import Filter
from cas_freq.core.parameters import LoopParameters
from cas_freq.simulation import Step, simulate_batch
from tests.test_simulation import with_sampling

pytest.importorskip("numba")


def _runs(config=None, variant="base"):
    path = None if config is None else shipped_configs_dir() / config
    return LoopParameters.from_config(load_variant(path, variant).params)


def architectures():
    """The runs of four architectures (one run each)."""
    pid = _runs()
    notched = dataclasses.replace(pid, filters=(
        Filter("current_command", "notch", 3000.0, width=1500.0, depth_db=-20.0),
        Filter("position_feedback", "lowpass1", 20000.0)))
    cascade = _runs("cascade_axis.yaml")
    sampled = with_sampling(cascade, (("current_loop", 20e3), ("velocity_loop", 5e3),
                                      ("position_loop", 2.5e3)), "tustin")
    loaded = _runs(None, "loaded")
    return {"pid_on_pi": pid, "pid_with_filters": notched, "cascade_with_filters": cascade,
            "sampled_cascade": sampled, "loaded_drivetrain": loaded}


def test_one_compilation_serves_every_architecture():
    from cas_freq.simulation import kernel

    for runs in architectures().values():
        for batch in (runs.take([0]), runs.take([0, 0])):  # the serial and parallel kernels
            result = simulate_batch(batch, Step(math.radians(1.0)), t_end=2e-3, extend=False,
                                    engine="compiled")
            assert result.theta.shape[0] == batch.n_runs
    kernels = [kernel.start_batch, kernel.advance_serial]
    if numba.get_num_threads() > 1:  # batches of two runs ran the parallel kernel
        kernels.append(kernel.advance_parallel)
    for dispatcher in kernels:
        assert len(dispatcher.signatures) == 1, (dispatcher.__name__, dispatcher.signatures)
    # the loop over a run's steps too: a loaded and an unloaded run are one machine code (it
    # has none of its own where its callers' machine code came from numba's cache)
    assert len(kernel._advance_run.signatures) <= 1, kernel._advance_run.signatures
