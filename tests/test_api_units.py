"""Every API argument with a unit takes a string with its unit, as ``simulate(step="10 deg")``
does; and to_control names the position loop's measurement as the structure declares it."""

import math

import numpy as np
import pytest

import cas_freq as cf
from cas_freq.core.exceptions import CasFreqError


@pytest.fixture(scope="module")
def act():
    return cf.load("configs/qt_cas.yaml")


def test_export_model_reads_amplitudes_and_frequencies_with_units(act, monkeypatch):
    # Before: export_model(amplitudes=["1 deg"]) failed with numpy's "could not convert string
    # to float". The model itself (a sine-dwell, minutes) is not run: what the engine is handed
    # is checked, against the SI values worked out by hand (1 deg = pi/180 rad; 3 rev/s =
    # 6 pi rad/s), to rounding.
    import cas_freq.studies.exported_model as exported

    handed = {}

    def engine(loaded, pade, amplitudes, frequencies, feedforward):
        handed.update(amplitudes=amplitudes, frequencies=frequencies)
        return "model"

    monkeypatch.setattr(exported, "export_model", engine)
    assert act.export_model(amplitudes=["1 deg", 0.01], frequencies=["3 rev/s", 100.0]) \
        == "model"
    assert handed["amplitudes"] == pytest.approx([math.pi / 180, 0.01], rel=1e-15)
    assert handed["frequencies"] == pytest.approx([6 * math.pi, 100.0], rel=1e-15)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"amplitudes": ["1 mm"]}, "amplitudes: 1 mm is a length; this actuator's output is rotary"),
    ({"amplitudes": ["one"]}, "amplitudes: expected an angle with a unit"),
    ({"frequencies": ["1 mm"]}, r"frequencies: '1 mm' is not accepted; accepted: a number "
                                r"\[rad/s\]"),
])
def test_export_model_names_a_bad_quantity(act, kwargs, message):
    with pytest.raises(CasFreqError, match=message):
        act.export_model(**kwargs)


def test_frequency_response_and_analyze_read_frequencies_with_units(act):
    # the same numbers as given in rad/s (1 rev/s = 2 pi rad/s): the same responses, exactly
    # up to the rounding of 2 pi x (1e-15 relative)
    given = act.frequency_response(["1 rev/s", "100 rad/s", 1000.0])
    numbers = act.frequency_response([2 * math.pi, 100.0, 1000.0])
    np.testing.assert_allclose(given.position_loop, numbers.position_loop, rtol=1e-13)
    ranged = act.analyze(frequency_range=("0.01 rad/s", "1e6 rad/s"))
    assert ranged.position_loop.phase_margin_deg == act.analyze().position_loop.phase_margin_deg


def test_to_control_names_the_output_encoders_measurement_delta():
    # Before: L_p was labelled e -> theta when the position loop is closed on the output
    # encoder (the fin_encoder variant measures delta, the output angle).
    motor = cf.load("configs/qt_cas.yaml", variant="loaded").to_control(pade=2)
    output = cf.load("configs/qt_cas.yaml", variant="fin_encoder").to_control(pade=2)
    assert (motor.position_loop.input_labels, motor.position_loop.output_labels) == \
        (["e"], ["theta"])
    assert (output.position_loop.input_labels, output.position_loop.output_labels) == \
        (["e"], ["delta"])
    assert output.sensitivity.input_labels == ["delta_cmd"]
    assert motor.sensitivity.input_labels == ["theta_cmd"]
