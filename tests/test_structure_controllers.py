"""The simulators' numbers of each controller come from the declared structure.

`structure.build` gives every loop's controller its gains (Kp, Ki, Kd, Tf) and every loop its
output clamp (`Loop.limit`), so the simulators read one declaration instead of the parameter
names of each architecture. Checked here against the parameters by name, as docs/model.md lists
them per architecture: PID-on-PI (current PI clamped at v_max, position PID at i_max) and the
cascade (current PI at v_max, velocity PI at i_max, position PI at omega_max, a PI's Kd 0).
"""

import numpy as np
import pytest

from cas_freq.config.loader import load_variant, shipped_configs_dir
from cas_freq.core.parameters import LoopParameters
from cas_freq.model import structure
from cas_freq.simulation import architecture


def _params(config=None):
    return LoopParameters.from_config(load_variant(config, "base").params)


def _expected(p):
    current = (p.ci_Kp, p.ci_Ki, 0.0, 1.0, p.v_max)
    if not p.cascade:
        return [current, (p.cp_Kp, p.cp_Ki, p.cp_Kd, p.Tf, p.i_max)]
    return [current, (p.cv_Kp, p.cv_Ki, 0.0, 1.0, p.i_max),
            (p.cp_Kp, p.cp_Ki, 0.0, 1.0, p.omega_max)]


@pytest.mark.parametrize("config", [None, "cascade_axis.yaml"])
def test_each_loop_declares_its_controller_and_clamp(config):
    p = _params(config and shipped_configs_dir() / config)
    loops = structure.build(p).loops
    expected = _expected(p)
    assert len(loops) == len(expected)
    for loop, values in zip(loops, expected, strict=True):
        got = architecture.controller(loop, p.n_runs)
        for a, b in zip(got, values, strict=True):
            np.testing.assert_array_equal(a, np.broadcast_to(b, (p.n_runs,)))
        # a filter is not a controller
        assert all(block.gains is None for block in loop.path + loop.sensor)
