"""``cas-freq fit`` on degenerate step recordings: the text output says what ``--json`` says.

Five kinds of recording the second-order fit cannot determine well (issue 24): a position that
never moves, only 10 or 11 samples from the trigger on, pure noise, a staircase command and a
first-order step. ``--json`` always handled them (absent figures as null); the text output
raised ``TypeError`` on a null (exit 1, the status of a failed requirement). Each is written as
``cas-freq simulate --csv`` writes a recording (``t [s]``, ``command_fin [deg]``,
``delta [deg]``) and fitted both ways ``fit`` reads recordings (``fit FILE --step`` and
``fit --data FILE``): each must exit 0, and every figure of the JSON must be in the text, a
null as "—", with the reason for an unbounded interval or a fit that did not converge.
"""

import json
import math

import numpy as np
import pytest
from clirun import run_cli

#: Sampling of the synthetic recordings [s]: 5 ms before the trigger, 60 ms after.
_DT = 1e-4
_T = np.arange(-50, 600) * _DT


def _write(path, t, command, position):
    """A recording as ``simulate --csv`` writes one (degrees; no command column if None)."""
    columns, header = [t], ["t [s]"]
    if command is not None:
        columns.append(command)
        header.append("command_fin [deg]")
    columns.append(position)
    header.append("delta [deg]")
    np.savetxt(path, np.column_stack(columns), delimiter=",", header=",".join(header),
               comments="")
    return str(path)


def _step(t, size=10.0):
    return np.where(t >= 0, size, 0.0)


def _recording(kind, path):
    """(file, --step option or None) of one degenerate kind."""
    if kind == "constant position":
        return _write(path, _T, _step(_T), np.zeros(_T.size)), "10deg"
    if kind in ("10 samples", "11 samples"):
        t = _T[:50 + int(kind.split()[0])]  # 50 before the trigger
        return _write(path, t, _step(t), _step(t)), "10deg"  # the output jumps with it
    if kind == "pure noise":
        noise = np.random.default_rng(24).standard_normal(_T.size)
        return _write(path, _T, _step(_T), noise), "10deg"
    if kind == "staircase command":
        stairs = 2.0 * np.clip(np.floor(_T / 0.01) + 1, 0, 5)  # 2, 4, ... 10 deg every 10 ms
        return _write(path, _T, stairs, stairs), "10deg"
    assert kind == "first-order step"
    # 10 deg with a 5 ms time constant: no overshoot, and the fit's zeta runs off to infinity
    return _write(path, _T, None, _step(_T) * (1 - np.exp(-np.clip(_T, 0, None) / 5e-3))), \
        "10deg"


KINDS = ("constant position", "10 samples", "11 samples", "pure noise", "staircase command",
         "first-order step")


def _shown(value):
    """How the text output shows a JSON figure (4 significant digits, null as '—')."""
    return "—" if value is None else f"{value:.4g}"


def _check_fit(text, fit):
    """Every figure of a JSON fit is in the text, and the reasons for nulls and failures."""
    for key in ("wn_rad_s", "zeta", "bandwidth_closed_form_rad_s"):
        assert _shown(fit[key]) in text, key
    for key in ("wn_ci_rad_s", "zeta_ci"):
        low, high = fit[key]
        if low is None:
            assert "[—]" in text and "unbounded" in text, key
        else:
            assert f"[{_shown(low)}, {_shown(high)}]" in text, key
    if not fit["success"]:
        assert "not converged" in text


@pytest.mark.parametrize("kind", KINDS)
def test_fit_file_text_says_what_json_says(tmp_path, kind):
    path, step = _recording(kind, tmp_path / "r.csv")
    code, out, err = run_cli(["fit", path, "--step", step, "--json"])
    assert code == 0, err
    data = json.loads(out)
    code, text, err = run_cli(["fit", path, "--step", step])
    assert code == 0, err
    _check_fit(text, data["fit"])
    for key in ("rise_time_s", "settling_time_s"):
        if data["step"][key] is None:
            assert "—" in text


@pytest.mark.parametrize("kind", KINDS)
def test_fit_data_text_says_what_json_says(tmp_path, kind):
    path, step = _recording(kind, tmp_path / "r.csv")
    options = ["--step", step] if kind == "first-order step" else []
    code, out, err = run_cli(["fit", "--data", path, *options, "--json"])
    assert code == 0, err
    data = json.loads(out)
    code, text, err = run_cli(["fit", "--data", path, *options])
    assert code == 0, err
    recording = data["recordings"][0]
    head, _, model = text.partition("\n\nmodel ")
    _check_fit(head, recording["fit"])
    assert f"{recording['samples']} samples from the trigger" in head
    share = recording["fit"]["rms_residual_of_step"]
    assert f"rms residual {100 * share:.3g} % of the step" in head


def test_joint_fit_of_degenerate_recordings(tmp_path):
    """Several degenerate recordings at once: the joint fit and the spread print as in JSON."""
    paths = [_recording(kind, tmp_path / f"{i}.csv")[0]
             for i, kind in enumerate(("constant position", "pure noise", "10 samples"))]
    code, out, err = run_cli(["fit", "--data", *paths, "--json"])
    assert code == 0, err
    joint = json.loads(out)["joint"]
    code, text, err = run_cli(["fit", "--data", *paths])
    assert code == 0, err
    block = text.split("joint fit of 3 recordings")[1].split("\n\nmodel ")[0]
    _check_fit(block, joint)
    assert math.isfinite(joint["rms_residual_of_step"])
