"""Every drive architecture against the independent reference (issue 25).

cas_freq composes every loop from one declared structure (cas_freq/model/structure.py: the
cascade recurrence E_k = b_k f_k E_(k-1) + c_k). tests/architecture_oracle.py computes the same
loops without cas_freq, by solving all signal equations of the block diagram at each frequency
(its derivation is in its docstrings, from the two-mass equations of docs/model.md), so the two
share no algebra. Both refine crossings by root finding on exact-delay responses: they agree
to ~1e-10; 1e-6 relative leaves room for different grids and root finders and still catches any
modelling difference (a filter's damping off by 1 %, a sign, the wrong sensor move them by far
more). The stability verdicts are compared with the oracle's python-control interconnect of
the blocks with Padé-6 delays.
"""

import numpy as np
import pytest
from architecture_oracle import (
    Filter,
    as_analyze_keys,
    closed_loop_poles,
    example_cascade,
    figures,
    is_stable,
    qt_cas_drive,
    replace,
)

import cas_freq as cf
from cas_freq.analysis.stability import closed_loop_poles as our_poles
from cas_freq.analysis.stability import loop_polynomials
from cas_freq.analysis.systems import linear_model
from cas_freq.core.parameters import LoopParameters
from cas_freq.model.delay import DelayModel
from cas_freq.model.loops import Selector, responses

AXIS = "configs/cascade_axis.yaml"


def _axis_drive(variant="base"):
    """configs/cascade_axis.yaml as the oracle's Drive (its numbers typed in from the YAML: the
    oracle's example_cascade with the shipped velocity gain; no_notch drops the notch)."""
    drive = example_cascade(cv_Kp=1.3)
    if variant == "no_notch":
        drive = replace(drive, filters=drive.filters[1:])
    return drive


def _compare(ours, reference):
    """Every figure the oracle computes, against analyze's JSON."""
    flat = as_analyze_keys(reference)
    for key, mine in flat.items():
        section, _, name = key.partition(".")
        theirs = ours[section]
        for part in name.split(".")[:-1]:
            theirs = theirs[part]
        theirs = theirs[name.split(".")[-1]]
        if key.startswith("closed_loop.") and not reference["stable"]:
            continue  # no closed-loop figures of an unstable loop
        if theirs is None or mine is None:
            assert mine is None and theirs is None, (key, mine, theirs)
        elif name == "dc_gain_db":  # ~0 dB: an absolute tolerance
            assert theirs == pytest.approx(mine, abs=1e-9), key
        else:
            assert theirs == pytest.approx(mine, rel=1e-6), key
    return flat


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
@pytest.mark.parametrize("variant", ["base", "no_notch"])
def test_the_shipped_cascade_axis_equals_the_reference(variant):
    # P -> PI -> PI with a compliant coupling, a spring load, a velocity feedback low-pass, a
    # second-order low-pass on the measured speed and (base) a notch at the current command:
    # every loop's margins in both views, and T
    ours = cf.load(AXIS, variant=variant).analyze().to_dict()
    reference = figures(_axis_drive(variant))
    assert (ours["stability"] == "stable") == reference["stable"]
    flat = _compare(ours, reference)
    assert any(key.startswith("velocity_loop.loop_at_a_time.") for key in flat)
    if variant == "no_notch":  # without the notch the velocity loop's resonance destabilises it
        assert ours["stability"] == "unstable" and ours["closed_loop"]["bandwidth_rad_s"] is None
        assert ours["velocity_loop"]["phase_margin_deg"] < 0
    else:
        assert ours["stability"] == "stable" and ours["velocity_loop"]["phase_margin_deg"] > 30


def test_the_notch_shapes_the_loop_it_sits_in():
    # the notch at the current command sits in the velocity loop: at its centre the loop with
    # the notch is the loop without it times the notch's depth (-20 dB = 0.1), exactly
    def velocity_loop(variant):
        loaded = cf.load(AXIS, variant=variant)
        p = Selector(LoopParameters.from_config(loaded.params))()
        return responses(p, np.array([800j])).loops["velocity_loop"][0]

    ratio = velocity_loop("base") / velocity_loop("no_notch")
    assert abs(ratio) == pytest.approx(0.1, rel=1e-12)
    assert np.angle(ratio) == pytest.approx(0.0, abs=1e-12)


def test_the_loaded_qt_cas_on_its_fin_encoder_with_a_notch_equals_the_reference():
    # the PID-on-PI closed on the output encoder (N delta) with the compliant gear inside the
    # position loop, and a notch at the current command
    notch = {"at": "current_command", "type": "notch", "frequency": "8000 rad/s",
             "width": "2000 rad/s", "depth": "-12 dB"}
    ours = cf.load("configs/qt_cas.yaml", variant="loaded",
                   set={"position_loop.feedback": "output", "filters": [notch]}).analyze()
    reference = figures(replace(qt_cas_drive("loaded"), feedback="output", filters=(
        Filter("current_command", "notch", 8000.0, width=2000.0, depth_db=-12.0),)))
    assert (ours.stability.verdict == "stable") == reference["stable"]
    _compare(ours.to_dict(), reference)


def test_a_rigid_gear_gives_the_same_figures_with_either_encoder():
    # with a rigid gear N delta = theta: the output encoder measures what the motor's does
    motor = cf.load("configs/dc_servo.yaml").analyze().to_dict()
    output = cf.load("configs/dc_servo.yaml",
                     set={"position_loop.feedback": "output"}).analyze().to_dict()
    for section in ("current_loop", "position_loop", "closed_loop"):
        for name, value in motor[section].items():
            if isinstance(value, float):
                assert output[section][name] == pytest.approx(value, rel=1e-12), name


@pytest.mark.parametrize("variant", ["base", "no_notch"])
def test_the_stability_verdict_and_poles_equal_the_reference_interconnect(variant):
    # the Padé-6 closed loop: our state matrix from the declared structure against the
    # oracle's python-control interconnect of the explicit blocks
    loaded = cf.load(AXIS, variant=variant)
    p = LoopParameters.from_config(loaded.params)
    mine = np.sort_complex(our_poles(p, 6))
    theirs = np.sort_complex(closed_loop_poles(_axis_drive(variant), 6))
    assert mine.size == theirs.size
    np.testing.assert_allclose(mine, theirs, rtol=1e-7, atol=1e-6)
    # the characteristic polynomial of the whole loop has the same roots (its Routh verdict)
    whole = np.trim_zeros(list(loop_polynomials(p, 6).values())[-1][0], "f")
    assert np.sum(np.roots(whole).real > 0) == np.sum(mine.real > 0)
    assert (np.sum(mine.real > 0) == 0) == is_stable(_axis_drive(variant))


def test_the_python_control_loops_are_the_structures_loops_with_pade_delays():
    # to_control's systems (state space composed from the structure) against the frequency
    # responses (the recurrence) with the same Padé-6 delays: two compositions of one model
    p = LoopParameters.from_config(cf.load(AXIS).params)
    model = linear_model(p, 6)
    omega = np.geomspace(1.0, 1e5, 60)
    s = 1j * omega
    reference = responses(Selector(p)(), s, delay=DelayModel(6))
    for name in ("current_loop", "velocity_loop", "position_loop"):
        theirs = getattr(model, name)(s)
        np.testing.assert_allclose(np.squeeze(theirs), reference.loops[name], rtol=1e-7)
    np.testing.assert_allclose(np.squeeze(model.closed_loop(s)), reference.closed_loop,
                               rtol=1e-7)
    assert model.velocity_loop.name == "L_v"
