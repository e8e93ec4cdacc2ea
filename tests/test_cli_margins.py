"""Margins as the commands report them (issue 24): a loop whose phase starts on the other side
of -180° (an aiding hinge), a valid config whose stable-hinge scan passes the hinge key's
range, and the text's delay margins, each with its own crossover."""

import json
import math

import pytest
from clirun import run_cli

from cas_freq.core.figures import FIGURES
from cas_freq.core.numbers import number

# The made-up DC servo of configs/dc_servo.yaml with an aiding hinge (K_h = -15 N*m/rad at
# the output: a statically unstable plant), a slow current-loop integral and a small Kd: the
# closed loop is stable, and L_p's first samples lie just above +180° (the lag of the current
# loop outweighs the derivative's lead there), so its continuous phase runs one turn above the
# -180° line it crosses: the old engine read PM 379.36° (and verify passed PM >= 30°).
AIDING = """
name: aiding_hinge
motor: {R: 2.5 ohm, L: 1.2 mH, Km: 0.05 N*m/A, Ke: 0.05 V*s/rad, J: 2e-5 kg*m^2,
        mu_v: 2e-6 N*m*s/rad}
gear: {ratio: 50}
load: {hinge_stiffness: -15 N*m/rad}
current_loop: {Kp: 0.9 V/A, Ki: 9 V/(A*s), v_max: 24 V, delay: 0.05 ms}
position_loop: {Kp: 6 A/rad, Ki: 30 A/(rad*s), Kd: 0.006 A*s/rad, i_max: 5 A, delay: DELAY ms}
requirements:
  - {id: PM-P, metric: position_loop.phase_margin_deg, min: 30 deg, severity: required,
     source: test}
"""


def _config(tmp_path, delay_ms=0.2):
    path = tmp_path / f"aiding_{delay_ms:g}.yaml"
    path.write_text(AIDING.replace("DELAY", repr(delay_ms)))
    return str(path)


def test_aiding_hinge_margin_and_verify(tmp_path):
    code, out, _ = run_cli(["analyze", _config(tmp_path), "--json"])
    assert code == 0
    data = json.loads(out)
    assert data["stable"] is True
    p = data["position_loop"]
    assert -180 < p["phase_margin_deg"] <= 180
    assert p["phase_margin_deg"] == pytest.approx(19.36, abs=0.01)
    (crossover,) = p["gain_crossovers"]
    assert crossover["phase_deg"] == pytest.approx(180 + p["phase_margin_deg"], abs=1e-9)
    wc, delay = p["crossover_rad_s"], p["delay_margin_s"]
    assert delay == pytest.approx(math.radians(p["phase_margin_deg"]) / wc, rel=1e-12)
    # Independent check of the margin's branch: the Padé-6 closed-loop verdict with the
    # position-loop delay raised by 0.9 and 1.1 times the delay margin (~6 ms; a 379° margin
    # would be ~118 ms). The delay only rotates L_p, so it is lost exactly when L_p passes
    # through -1 at its one crossover.
    for factor, verdict in ((0.9, "stable"), (1.1, "unstable")):
        path = _config(tmp_path, 0.2 + factor * delay * 1e3)
        code, out, _ = run_cli(["analyze", path, "--json"])
        assert json.loads(out)["stability"] == verdict, factor
    code, out, _ = run_cli(["verify", _config(tmp_path), "--json"])
    assert code == 1  # PM-P (required) >= 30° fails at 19.36°
    (verdict,) = json.loads(out)["verdicts"]
    assert verdict["status"] == "FAIL" and verdict["value"] == p["phase_margin_deg"]


def test_valid_config_past_the_hinge_keys_range(tmp_path):
    # gear.ratio 1000 makes the loop's stiffness at the output Km Kp N^2 = 3e5 N*m/rad, so the
    # stable-K_h scan (+-1e4 of it) reaches 3e9, past load.hinge_stiffness's accepted 1e9: the
    # commands exited 2 naming a key the user never set. The range found is checked here by
    # the closed-loop verdict just inside and outside each bound (values a user may set).
    config = "configs/dc_servo.yaml"
    sets = ["--set", "gear.ratio=1000", "--set", "load.inertia=0.01"]
    code, out, err = run_cli(["analyze", config, *sets, "--json"])
    assert code == 0, err
    low, high = json.loads(out)["drivetrain"]["stable_hinge_stiffness_n_m_rad"]
    assert -1e9 < low < 0 < high < 1e9
    for value, verdict in ((1.01 * low, "unstable"), (0.99 * low, "stable"),
                           (0.99 * high, "stable"), (1.01 * high, "unstable")):
        code, out, _ = run_cli(["analyze", config, *sets, "--set",
                                f"load.hinge_stiffness={value!r}", "--json"])
        assert code == 0 and json.loads(out)["stability"] == verdict, value
    code, _, err = run_cli(["verify", config, *sets])
    assert code == 0, err


def test_text_gives_each_crossover_its_own_delay_margin():
    # The loaded variant's current loop crosses 0 dB three times (the hinge mode near 100 rad/s
    # and the roll-off near 8.4 krad/s); the smallest delay margin belongs to the roll-off, not
    # to the headline crossover (smallest |PM|), and was printed under the headline as its own.
    code, out, _ = run_cli(["analyze", "--variant", "loaded", "--json"])
    current = json.loads(out)["current_loop"]
    crossovers = current["gain_crossovers"]
    assert len(crossovers) == 3
    code, text, _ = run_cli(["analyze", "--variant", "loaded"])
    assert code == 0
    block = text.split("current loop L_i")[1].split("position loop L_p")[0]
    lines = block.splitlines()

    def ms(seconds):
        return number(seconds * 1e3, 4, "ms")

    (headline,) = [c for c in crossovers if c["frequency_rad_s"] == current["crossover_rad_s"]]
    # the labels are the figure table's, in a column as wide as the longest of a loop's
    labels = {name: FIGURES[f"current_loop.{name}"].label
              for name in ("crossover_rad_s", "phase_margin_deg", "delay_margin_s")}
    width = len(labels["crossover_rad_s"])
    start = lines.index(f"    {labels['crossover_rad_s']:<{width}} "
                        f"{number(headline['frequency_rad_s'], 4, 'rad/s')}"
                        f" (smallest |{labels['phase_margin_deg']}| of 3)")
    pm = number(headline["phase_margin_deg"], 4, "deg")
    assert lines[start + 1] == f"    {labels['phase_margin_deg']:<{width}} {pm}"
    assert lines[start + 2] == (f"    {labels['delay_margin_s']:<{width}} "
                                f"{ms(headline['delay_margin_s'])} (at this crossover)")
    for c in crossovers:
        if c is not headline:
            assert (f"{number(c['frequency_rad_s'], 4, 'rad/s')}: phase margin "
                    f"{number(c['phase_margin_deg'], 4, 'deg')}, delay margin "
                    f"{ms(c['delay_margin_s'])}") in block
    smallest = min(crossovers, key=lambda c: c["delay_margin_s"])
    assert smallest is not headline
    assert current["delay_margin_s"] == smallest["delay_margin_s"]
    assert current["delay_margin_crossover_rad_s"] == smallest["frequency_rad_s"]
    assert (f"    {labels['delay_margin_s']:<{width}} {ms(smallest['delay_margin_s'])} "
            f"(the smallest, at {number(smallest['frequency_rad_s'], 4, 'rad/s')})") in lines


def test_headline_is_the_crossover_nearest_minus_one():
    # The fitted variant under an opposing hinge of 20 N*m/rad: L_p crosses 0 dB three times;
    # at 49.9 rad/s L_p is near +1 (phase +2.8°: PM -177.2° in (-180°, 180°], the farthest a
    # crossover can be from -1). The headline is the crossover nearest -1, as python-control
    # picks it: checked against |1 + L| = 2 sin(|PM|/2) computed here from the loop itself.
    import numpy as np

    from cas_freq.config.loader import load_variant
    from cas_freq.model import ActuatorLoops

    overrides = [("load.hinge_stiffness", 20.0)]
    code, out, _ = run_cli(["analyze", "--variant", "fitted", "--set",
                            "load.hinge_stiffness=20", "--json"])
    p = json.loads(out)["position_loop"]
    loop = ActuatorLoops(load_variant(variant="fitted", overrides=overrides).params).position_loop
    w = np.array([c["frequency_rad_s"] for c in p["gain_crossovers"]])
    distance = np.abs(1.0 + loop(1j * w))
    pm = np.radians([c["phase_margin_deg"] for c in p["gain_crossovers"]])
    np.testing.assert_allclose(distance, 2 * np.sin(np.abs(pm) / 2), rtol=1e-9)
    assert len(w) == 3 and min(pm) < math.radians(-170)  # the crossover near +1
    assert p["crossover_rad_s"] == w[np.argmin(distance)]
    assert p["phase_margin_deg"] == pytest.approx(40.57, abs=0.01)
