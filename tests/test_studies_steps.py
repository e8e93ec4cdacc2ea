"""Nonlinear steps of a batch against ``simulate`` of each variant alone.

Reference: :func:`cas_freq.studies.run.step_run` (what ``simulate --json`` prints) for the
same variant. Each run's arithmetic in the vectorised simulator is independent of the other
runs, and the batch takes each run's figures over the horizon the single run would have used,
so the figures agree to rounding (1e-9 relative).
"""

import math

import pytest

from cas_freq.config import load_variant
from cas_freq.core.parameters import variant_parameters
from cas_freq.studies.run import step_run, step_run_dict
from cas_freq.studies.steps import batch_steps


def test_batch_steps_match_simulate():
    # Kp 9 A/rad settles within 0.1 s, the shipped 6.3435 needs 0.2 s: the batch runs 0.2 s
    # for both, and must still give the 0.1 s run's own figures and fit.
    base = load_variant()
    gains = [9.0, 6.3435]
    amplitude = math.radians(10.0)
    figures = batch_steps(variant_parameters(base.params, {"position_loop.Kp": gains}),
                          amplitude)
    for index, kp in enumerate(gains):
        single = step_run_dict(step_run(
            load_variant(None, "base", [("position_loop.Kp", kp)]), amplitude))
        for name, values in figures.items():
            group, key = name.split(".")
            expected = single[group][key]
            expected = math.nan if expected is None else float(expected)
            if math.isnan(expected):
                assert math.isnan(values[index]), name
            else:
                assert values[index] == pytest.approx(expected, rel=1e-9, abs=1e-15), name
