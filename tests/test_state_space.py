"""The one closed-loop state-space assembly (:func:`cas_freq.model.state_space.closings`)
against an independent evaluation of the same loops: their frequency responses.

The assembly's systems are evaluated as :math:`C (sI - A)^{-1} B + D` (a linear solve per
frequency) and compared with :func:`cas_freq.model.loops.responses` (the recurrence over the
blocks' own values, no state space) with the same Padé delay model; sampled loops at
:math:`z = e^{sT}` against :func:`cas_freq.model.sampled.responses` (the plant's modes, the
hold-equivalent in closed form, the decimation sum). Checked: every loop broken at its error
with the loops inside closed (:meth:`Closing.loop`) and T, on the report's PID-on-PI (with the
derivative on the error and on the measurement: the command path of its own), the velocity
cascade with its notch and the position loop on the output encoder, and a sampled config.

Tolerance 1e-9 relative: measured at most 3e-11 (the cascade's position loop at 1e4 rad/s,
where |L_p| ~ 5e-7 is a difference of far larger terms; the PID-on-PI's at most 3e-13, the
sampled loops' 5e-15). A block left out or misplaced (a filter, the output encoder) moves T by
1e-3 and more (:func:`test_the_declared_blocks_are_all_there`); the sampled T without the
derivative-on-measurement's command path is 7 times off.
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from cas_freq.config import load_variant
from cas_freq.core.parameters import LoopParameters
from cas_freq.model import loops, sampled, state_space
from cas_freq.model.delay import DelayModel
from cas_freq.model.parts import one_variant
from cas_freq.model.structure import build

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
OMEGA = np.array([3.0, 40.0, 500.0, 3000.0, 1e4])  # [rad/s]
RTOL = 1e-9  # see the module docstring


def _params(config, variant="base", overrides=(), **changes):
    loaded = load_variant(CONFIGS / config, variant, list(overrides))
    return one_variant(dataclasses.replace(LoopParameters.from_config(loaded.params), **changes))


def _evaluated(system, x):
    """C (x I - A)^-1 B + D of a single-input single-output (A, B, C, D) at each x."""
    a, b, c, d = system
    eye = np.eye(a.shape[0])
    return np.array([(c @ np.linalg.solve(value * eye - a, b) + d)[0, 0] for value in x])


def _closed_loop(closing, structure):
    a, b, c, d = closing.closed
    row = state_space.SIGNAL_ROWS[structure.output]
    return a, b, c[row:row + 1], d[row:row + 1]


CONTINUOUS = {
    "pid_on_pi": ("qt_cas.yaml", "fitted", ()),
    "pid_on_pi_derivative_on_measurement": (
        "qt_cas.yaml", "base", (("position_loop.derivative_on", "measurement"),)),
    "cascade_notch_output_encoder": (
        "cascade_axis.yaml", "base", (("position_loop.feedback", "output"),)),
}


@pytest.mark.parametrize("order", [2, 6])
@pytest.mark.parametrize("case", list(CONTINUOUS))
def test_continuous_loops_and_t_are_the_responses_with_pade_delays(case, order):
    config, variant, overrides = CONTINUOUS[case]
    p = _params(config, variant, overrides)
    structure = build(p)
    s = 1j * OMEGA
    expected = loops.responses(p, s, delay=DelayModel(order))
    closings = state_space.closings(p, order)
    assert list(closings) == list(structure.names)
    for name, closing in closings.items():
        assert closing.period is None
        np.testing.assert_allclose(_evaluated(closing.loop(), s), expected.loops[name],
                                   rtol=RTOL)
    top = closings[structure.names[-1]]
    np.testing.assert_allclose(_evaluated(_closed_loop(top, structure), s),
                               expected.closed_loop, rtol=RTOL)


def test_the_declared_blocks_are_all_there():
    # the cascade has a notch on its velocity loop's path, a low-pass and a first-order filter
    # on its measured speed and an output encoder: each is in the assembly (T moves by far
    # more than the tolerance without it)
    p = _params("cascade_axis.yaml", overrides=(("position_loop.feedback", "output"),))
    structure = build(p)
    assert [block.name for block in structure.loop("velocity_loop").path] == ["notch"]
    assert structure.loops[-1].feedback == "output_angle"
    s = 1j * OMEGA
    with_all = _evaluated(_closed_loop(state_space.closings(p, 6)["position_loop"], structure), s)
    for other in (_params("cascade_axis.yaml", "no_notch",
                          (("position_loop.feedback", "output"),)),
                  _params("cascade_axis.yaml"),
                  _params("cascade_axis.yaml", overrides=(("position_loop.feedback", "output"),),
                          tau_vf=np.array([0.0]))):
        found = _evaluated(_closed_loop(state_space.closings(other, 6)["position_loop"],
                                        build(other)), s)
        assert np.max(np.abs(found / with_all - 1)) > 1e-3


SAMPLED = {
    "qt_cas_sampled": ("qt_cas.yaml", "sampled", ()),
    "qt_cas_sampled_derivative_on_measurement": (
        "qt_cas.yaml", "sampled", (("position_loop.derivative_on", "measurement"),)),
}


@pytest.mark.parametrize("case", list(SAMPLED))
def test_sampled_loops_and_t_are_the_sampled_responses(case):
    config, variant, overrides = SAMPLED[case]
    p = _params(config, variant, overrides)
    structure = build(p)
    omega = OMEGA[OMEGA < 0.99 * math.pi * 2.5e3]  # below the position loop's Nyquist
    expected = sampled.responses(loops.Selector(p)(), 1j * omega)
    closings = state_space.closings(p, sampled=True)
    for name, closing in closings.items():
        z = np.exp(1j * omega * closing.period)
        np.testing.assert_allclose(_evaluated(closing.loop(), z), expected.loops[name],
                                   rtol=RTOL)
    top = closings[structure.names[-1]]
    z = np.exp(1j * omega * top.period)
    np.testing.assert_allclose(_evaluated(_closed_loop(top, structure), z),
                               expected.closed_loop, rtol=RTOL)
    if structure.loops[-1].reference is not None:  # the command path acts
        plain = state_space.closings(p, sampled=True, command=False)[structure.names[-1]]
        found = _evaluated(_closed_loop(plain, structure), z)
        assert np.max(np.abs(found / expected.closed_loop - 1)) > 1e-3


def test_a_stack_of_runs_holds_each_runs_matrices():
    # runs that realise alike are assembled as one stack: the same numbers as each run alone
    # (every product has an inner dimension of 1), continuous and sampled
    for config, variant in (("qt_cas.yaml", "base"), ("cascade_axis.yaml", "base")):
        base = LoopParameters.from_config(load_variant(CONFIGS / config, variant).params)
        runs = base.take([0, 0, 0]).replace(ci_Kp=base.ci_Kp * np.array([1.0, 1.4, 0.6]),
                                            J=base.J * np.array([1.0, 0.8, 1.3]))
        for sampled_loops, p in ((False, runs), (True, dataclasses.replace(
                runs, sample_rates=tuple((name, 20e3) for name in build(runs).names),
                sampling_method="tustin"))):
            groups = state_space.run_groups(p, sampled=sampled_loops)
            assert [list(rows) for rows in groups] == [[0, 1, 2]]
            stack = state_space.closings(p, 6, n=3, sampled=sampled_loops)
            for run in range(3):
                alone = state_space.closings(p.take([run]), 6, sampled=sampled_loops)
                for name, closing in alone.items():
                    for ours, theirs in zip(stack[name].closed, closing.closed, strict=True):
                        np.testing.assert_array_equal(np.broadcast_to(
                            ours, (3, *ours.shape[-2:]))[run], theirs)


def test_the_reduced_plant_closes_the_current_loop_alone():
    # the current loop without the modes the current does not see has the same L_i, with
    # one state (theta) fewer
    p = _params("qt_cas.yaml")
    full = state_space.closings(p, 6, loops=1)["current_loop"]
    reduced = state_space.closings(p, 6, loops=1, reduced=True)["current_loop"]
    assert reduced.closed[0].shape[0] == full.closed[0].shape[0] - 1
    s = 1j * OMEGA
    np.testing.assert_allclose(_evaluated(reduced.loop(), s), _evaluated(full.loop(), s),
                               rtol=RTOL)
