"""A bench recording is held to the bounds ``--step`` has: a 1e300 deg command or a 1e308
position column is refused in one line (exit 2), no RuntimeWarning first, instead of a
"success": true fit with ζ 2.6e10 and a bandwidth of 1e-15 rad/s."""

import math
import warnings

import numpy as np
import pytest
from clirun import run_cli

from cas_freq.core.exceptions import ConfigError
from cas_freq.identification import read_recording
from cas_freq.identification.recordings import MAX_EXCURSION_RAD, MAX_STEP_RAD


def _recording(tmp_path, step_deg=10.0, position_scale=1.0, header="time_s,command_deg,"
               "position_deg"):
    """A 10 deg step at t = 10 ms sampled at 1 kHz, the position a first-order response
    (time constant 5 ms) scaled by ``position_scale``."""
    t = np.arange(0.0, 0.1, 1e-3)
    command = np.where(t >= 0.01, step_deg, 0.0)
    position = position_scale * step_deg * np.where(
        t >= 0.01, 1 - np.exp(-(t - 0.01) / 5e-3), 0.0)
    lines = [header, *(f"{a!r},{b!r},{c!r}" for a, b, c in zip(t.tolist(), command.tolist(),
                                                               position.tolist(),
                                                               strict=True))]
    path = tmp_path / "step.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_a_recording_within_the_bounds_is_read(tmp_path):
    recording = read_recording(_recording(tmp_path))
    assert recording.step_rad == pytest.approx(math.radians(10.0), rel=1e-12)


@pytest.mark.parametrize(("step_deg", "scale", "match"), [
    (1e300, 1.0, r"column 'command_deg': .* is not an output angle"),
    (10.0, 1e307, r"column 'position_deg': .* is not an output angle"),
    (120.0, 1.0, r"the command steps by 120 deg; a step is non-zero and within ±90 deg"),
    # 10 deg step, the response 20 times it: 200 deg from the level, beyond twice 90 deg
    (10.0, 20.0, r"column 'position_deg': the position is .* deg from its pre-trigger level"),
])
def test_a_recording_beyond_the_bounds_is_refused_without_warnings(tmp_path, step_deg, scale,
                                                                   match):
    path = _recording(tmp_path, step_deg, scale)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an overflow warning would fail here
        with pytest.raises(ConfigError, match=match):
            read_recording(path)


def test_the_bounds_are_those_of_a_step():
    assert MAX_STEP_RAD == pytest.approx(math.radians(90.0), rel=1e-15)  # --step's bound
    assert MAX_EXCURSION_RAD == 2 * MAX_STEP_RAD


def test_a_cell_beyond_the_float_range_in_si_is_refused(tmp_path):
    # 1e308 rev is finite as written but 6.3e308 rad, beyond the largest float
    path = _recording(tmp_path, header="time_s,command_deg,position [rev]")
    text = path.read_text(encoding="utf-8").splitlines()
    text[20] = text[20].rsplit(",", 1)[0] + ",1e308"
    path.write_text("\n".join(text) + "\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"line 21: column .position \[rev\].: 1e308 rev is not "
                                          "finite in SI"):
        read_recording(path)


def test_fit_data_with_a_huge_command_is_one_line_exit_2(tmp_path):
    path = _recording(tmp_path, step_deg=1e300)
    code, out, err = run_cli(["fit", "configs/qt_cas.yaml", "--data", str(path)])
    assert code == 2, err
    assert err.count("\n") == 1 and "Warning" not in err and "not an output angle" in err
    assert out == ""
