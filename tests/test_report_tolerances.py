"""The report's tolerance section (issue 42): a config with ``tolerances:`` shows each
requirement's nominal value, its worst case over the box and its Monte Carlo yield side by
side, and the worst point's Bode of T and step beside the nominal; tried on the DC servo (not the
QT-CAS). The worst values are those of ``cas-freq worstcase`` (the same search), the yields
those of ``cas-freq montecarlo --distribution uniform --seed 0``; without ``tolerances:``
there is no section (the shipped reports are unchanged)."""

import json

import pytest
import yaml
from clirun import run_cli

from cas_freq.config import load_variant
from cas_freq.studies.worstcase import worst_case

DC = "configs/dc_servo.yaml"


def _toleranced_report(folder, source, tolerances):
    """(config, report folder) of ``cas-freq report`` on ``source``'s base variant with
    ``tolerances:`` added, written in ``folder``."""
    data = yaml.safe_load(open(source))
    data["tolerances"] = tolerances
    data.pop("variants", None)
    config = folder / "toleranced.yaml"
    config.write_text(yaml.safe_dump(data, sort_keys=False))
    out = folder / "report"
    code, _, err = run_cli(["report", str(config), "-o", str(out), "-q"])
    assert code == 0, err
    return config, out


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    return _toleranced_report(tmp_path_factory.mktemp("tolerances"), DC,
                              {"motor.R": "15%", "motor.J": "10%"})


@pytest.mark.slow
def test_the_section_shows_nominal_worst_and_yield(report):
    config, out = report
    text = (out / "report.md").read_text()
    assert "## Tolerances: nominal, worst case and yield" in text
    results = json.loads((out / "results.json").read_text())["tolerances"]
    assert [entry["variant"] for entry in results] == ["base"]
    found = worst_case(load_variant(config))
    ours = results[0]["worst_case"]
    for row, theirs in zip(ours["requirements"], found["requirements"], strict=True):
        # results.json holds six significant digits (docs/ci.md)
        assert row["worst"] == pytest.approx(theirs["worst"], rel=1e-5)
        assert f"| {row['id']} | base |" in text
    assert all(item["evaluated"] for item in results[0]["yield"])
    assert (out / "figures" / "base" / "worst_case.svg").read_text().startswith("<?xml")
    assert "The worst point of" in text


def test_no_section_without_tolerances(tmp_path):
    out = tmp_path / "plain"
    code, _, err = run_cli(["report", DC, "--variant", "base", "-o", str(out), "-q"])
    assert code == 0, err
    assert "Tolerances:" not in (out / "report.md").read_text()
    assert "tolerances" not in json.loads((out / "results.json").read_text())


@pytest.mark.slow
def test_a_linear_output_s_worst_point_steps_in_millimetres(tmp_path):
    """The ball screw (a linear output) with tolerances: the worst point's figure steps the
    output's example step, 5 mm (not 10 deg read as 0.17 m), shown in mm."""
    _, out = _toleranced_report(tmp_path, "configs/ball_screw.yaml",
                                {"motor.R": "5%", "motor.J": "5%"})
    text = (out / "report.md").read_text()
    section = text.split("## Tolerances")[1].split("\n## ")[0]
    assert "T's Bode and the 5 mm step" in section and "°" not in section
    svg = (out / "figures" / "base" / "worst_case.svg").read_text()
    assert "position [mm]" in svg and "∠T [deg]" in svg
