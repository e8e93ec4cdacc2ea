"""``cas-freq export-model`` and ``Actuator.export_model`` (docs/model.md §15).

The exported JSON is reloaded in python-control, independently of cas_freq's own systems, and
must give analyze's closed-loop bandwidth and the tool's linear step to the accuracy the file
states (the Padé model's own error).
"""

import json
import math

import control
import numpy as np
import pytest

import cas_freq as cf
from cas_freq.cli import main
from cas_freq.report.data import linear_steps

#: A small, fast dwell grid (two amplitudes, three frequencies near the QT-CAS's ω_BW).
FAST = ["--amplitudes", "0.5deg,10deg", "--frequencies", "600,1200,2400"]


def _reloaded(data):
    m = data["linear"]
    return control.ss(m["A"], m["B"], m["C"], m["D"], m["dt"] or 0)


def _bandwidth(system, low, high):
    """ω_BW of a reloaded system by bisection of |T(jω)| = 1/sqrt(2) (T(0) = 1)."""
    from scipy.optimize import brentq

    def f(w):
        return abs(complex(np.squeeze(system(1j * w)))) - math.sqrt(0.5)

    return brentq(f, low, high, xtol=1e-10)


@pytest.mark.parametrize("pade", [2, 6])
def test_reloaded_model_gives_the_bandwidth_and_the_step(tmp_path, pade):
    out = tmp_path / "model.json"
    assert main(["export-model", "configs/qt_cas.yaml", "--pade", str(pade), "-o", str(out),
                 "-q", *FAST]) == 0
    data = json.loads(out.read_text())
    system = _reloaded(data)
    analysis = cf.load("configs/qt_cas.yaml").analyze()
    exact = analysis.closed_loop.bandwidth_rad_s
    ours = _bandwidth(system, 0.5 * exact, 1.5 * exact)
    stated = data["accuracy"]["bandwidth_rad_s"]
    assert ours == pytest.approx(stated, rel=1e-8)  # the file says what python-control gets
    # the Padé error bound the file states: |dT| <= e moves |T| = 0.7071 by at most e, so ω_BW
    # by at most e / |d|T|/dω| there; a relative 5 e covers the QT-CAS's slope (about -0.5/ω)
    error = data["accuracy"]["closed_loop_max_error"]
    assert abs(ours - exact) / exact <= 5 * error + 1e-9
    # the zeros/poles/gain form is the same system (evaluated as the products it states)
    zeros = np.array([complex(*z) for z in data["linear"]["zeros"]])
    poles = np.array([complex(*p) for p in data["linear"]["poles"]])
    w = np.array([10.0, exact, 5 * exact])
    s = 1j * w[:, None]
    zpk = data["linear"]["gain"] * np.prod(s - zeros, axis=1) / np.prod(s - poles, axis=1)
    np.testing.assert_allclose(zpk, np.squeeze(system(1j * w)), rtol=1e-6)
    if pade == 2:  # a low order: python-control's own zpk reads it too
        tf = control.zpk(zeros, poles, data["linear"]["gain"])
        np.testing.assert_allclose(np.squeeze(tf(1j * w)), zpk, rtol=1e-4)
    # the step of the reloaded model against the tool's linear step (Padé 6, the report's)
    accuracy = data["accuracy"]  # on the grid the file states
    t = np.linspace(0.0, accuracy["step_horizon_s"], accuracy["step_points"])
    step = control.step_response(system, T=t).outputs
    tool = linear_steps(cf.load("configs/qt_cas.yaml").params, [t], [1.0], 6)[0]
    assert np.max(np.abs(step - tool)) <= accuracy["step_max_error"] + 1e-9
    if pade == 6:
        assert np.max(np.abs(step - tool)) < 1e-9  # the same model: round-off only
    # the rest of the file: the dwell table and the fits per amplitude, the envelope
    table = data["sine_dwell"]
    assert np.shape(table["magnitude_db"]) == (2, 3)
    assert [row["amplitude_deg"] for row in data["low_order"]] == pytest.approx([0.5, 10.0])
    assert data["low_order"][0]["rate_limit_rad_s"] == pytest.approx(
        data["envelope"]["no_load_rate_rad_s"])
    assert data["envelope"]["stall_torque_N_m"] == pytest.approx(4.2)


def test_api_returns_the_same_object():
    act = cf.load("configs/qt_cas.yaml")
    model = act.export_model(pade=4, amplitudes=[math.radians(0.5)], frequencies=[1200.0])
    data = model.to_dict()
    assert data["linear"]["pade_order"] == 4
    assert isinstance(model.system, control.StateSpace)
    json.dumps(data, allow_nan=False)


def test_sampled_variant_exports_the_discrete_T(tmp_path):
    out = tmp_path / "sampled.json"
    assert main(["export-model", "--variant", "sampled", "-o", str(out), "-q",
                 "--amplitudes", "0.5deg", "--frequencies", "1200"]) == 0
    data = json.loads(out.read_text())
    assert data["linear"]["sampled"] and data["linear"]["dt"] == pytest.approx(1 / 2500)
    system = _reloaded(data)
    assert system.isdtime(strict=True)
    # the discrete T is the sampled loop itself (no Padé): analyze's sampled ω_BW
    sampled = cf.load("configs/qt_cas.yaml", variant="sampled").analyze()
    assert data["accuracy"]["bandwidth_rad_s"] == pytest.approx(
        sampled.closed_loop.bandwidth_rad_s, rel=1e-6)
    assert data["envelope"]["basis"].startswith("continuous loops (the controllers are sampled")


@pytest.mark.parametrize("argv, words", [
    (["--variant", "nope"], "unknown variant 'nope'"),
    (["--pade", "0"], "--pade: must be 1.."),
])
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, argv, words):
    out = tmp_path / "x.json"
    assert main(["export-model", *argv, "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "\n" not in err
    assert not out.exists()


def test_bad_output_path_exits_2(tmp_path, capsys):
    blocker = tmp_path / "file.txt"
    blocker.write_text("not a folder")
    assert main(["export-model", "-o", str(blocker / "x.json"), "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert "is not a folder" in err and "\n" not in err
    assert main(["export-model", "-o", str(tmp_path), "-q"]) == 2
    assert "is a folder" in capsys.readouterr().err


def test_bandwidth_is_taken_from_the_models_own_dc_gain():
    # the cascade axis carries a load spring without integral action at the output: |T(0)| < 1,
    # and ω_BW is 3.01 dB below |T(0)| (docs/model.md §7), not below 1 (which gave 41.80 rad/s
    # for analyze's 42.64 before the fix)
    act = cf.load("configs/cascade_axis.yaml")
    model = act.export_model(pade=6, amplitudes=[math.radians(0.5)], frequencies=[100.0])
    exact = act.analyze().closed_loop.bandwidth_rad_s
    assert abs(complex(np.squeeze(model.system(0.0)))) == pytest.approx(0.990, abs=1e-3)
    assert model.accuracy["bandwidth_rad_s"] == pytest.approx(exact, rel=1e-8)
