"""``cas-freq montecarlo``: tolerance parsing, reproducibility, yields, outputs, exit codes."""

import json

import numpy as np
import pytest

from cas_freq.cli import main
from cas_freq.config import load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.tolerances import parse_tolerance
from cas_freq.studies.montecarlo import draw

ARGS = ["montecarlo", "--samples", "40", "--tolerance", "motor.Km=10%",
        "--tolerance", "current_loop.delay=0.01 ms", "--seed", "7", "--no-step"]


def _strict(text):
    def reject(name):
        raise ValueError(f"non-strict JSON constant {name}")

    return json.loads(text, parse_constant=reject)


def test_tolerance_parsing():
    relative = parse_tolerance("motor.Km=10%")
    assert (relative.key, relative.relative, relative.absolute) == ("motor.Km", 0.1, None)
    absolute = parse_tolerance("current_loop.delay=0.02ms")
    assert absolute.relative is None and absolute.absolute == pytest.approx(2e-5, rel=1e-12)
    assert parse_tolerance("motor.J=1e-8").absolute == 1e-8  # plain number: SI
    for bad in ("motor.Km", "motor.Km=", "motor.Km=ten", "motor.Km=-5%", "motor.Km=1 s",
                "nothing.x=1%"):
        with pytest.raises(ConfigError):
            parse_tolerance(bad)


def test_draws_are_reproducible_and_scaled():
    params = load_variant().params
    tolerances = [parse_tolerance("motor.Km=10%")]
    a, seed_a = draw(params, tolerances, 20000, "uniform", seed=3)
    b, _ = draw(params, tolerances, 20000, "uniform", seed=3)
    np.testing.assert_array_equal(a["motor.Km"], b["motor.Km"])
    assert seed_a == 3
    km = params.motor.Km
    assert a["motor.Km"].min() >= 0.9 * km and a["motor.Km"].max() <= 1.1 * km
    normal, _ = draw(params, tolerances, 20000, "normal", seed=3)
    # sigma = tolerance / 3: sample std within 3 % of 0.1 km / 3 for 20000 draws
    assert np.std(normal["motor.Km"]) == pytest.approx(0.1 * km / 3, rel=0.03)


def test_json_reproducible_with_yields_and_unevaluated_requirements(capsys):
    assert main([*ARGS, "--json"]) == 0
    first = _strict(capsys.readouterr().out)
    assert main([*ARGS, "--json"]) == 0
    second = _strict(capsys.readouterr().out)
    assert first == second
    assert first["seed"] == 7 and first["samples"] == 40
    stats = first["figures"]["closed_loop.bandwidth_rad_s"]
    assert stats["count"] == 40 and stats["p5"] <= stats["p50"] <= stats["p95"]
    by_id = {r["id"]: r for r in first["requirements"]}
    assert by_id["BW-1"]["evaluated"] and 0 <= by_id["BW-1"]["yield_pct"] <= 100
    assert len(by_id["BW-1"]["worst"]) == 5
    # step requirements are listed, explicitly not evaluated, with --no-step
    assert not by_id["OS-1"]["evaluated"]
    assert by_id["OS-1"]["reason"].startswith("not evaluated in montecarlo")


def test_text_and_report(tmp_path, capsys):
    report = tmp_path / "mc"
    assert main([*ARGS, "-o", str(report)]) == 0
    text = capsys.readouterr().out
    assert "seed 7" in text and "BW-1" in text and "not evaluated in montecarlo" in text
    names = sorted(p.name for p in report.iterdir())
    assert names == [".cas-freq-output", "histograms.svg", "montecarlo.json", "samples.csv"]
    assert len((report / "samples.csv").read_text().splitlines()) == 41


@pytest.mark.parametrize("extra", [
    ["--tolerance", "motor.Km=abc"],
    ["--tolerance", "motor.Km=300%"],   # normal draws with sigma 100 %: negative Km samples
    ["--distribution", "gauss"],
])
def test_bad_input_exits_2(capsys, extra):
    argv = ["montecarlo", "--samples", "50", "--seed", "1", "--no-step",
            "--tolerance", "motor.J=5%", *extra]
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own usage errors
        code = exc.code
    assert code == 2
    assert capsys.readouterr().err.strip()


def test_step_requirements_are_evaluated_with_the_step(capsys):
    # the shipped config's OS-1 (step.overshoot_pct) and BW-2 (fit.*) need a 10 deg step:
    # montecarlo simulates it (and fits) for every sample
    assert main(["montecarlo", "--samples", "2", "--seed", "5", "--tolerance", "motor.J=5%",
                 "--json"]) == 0
    data = _strict(capsys.readouterr().out)
    assert data["step_deg"] == pytest.approx(10.0)
    by_id = {r["id"]: r for r in data["requirements"]}
    assert by_id["OS-1"]["evaluated"] and by_id["BW-2"]["evaluated"]
    assert data["figures"]["step.overshoot_pct"]["count"] == 2


# --- several variants (issue 11: one grammar) ---------------------------------------------


def test_single_variant_output_unchanged_by_the_variant_options(capsys):
    outputs = []
    for extra in ([], ["--variant", "base"]):
        assert main([*ARGS, *extra, "--json"]) == 0
        outputs.append(capsys.readouterr().out)
    assert outputs[0] == outputs[1] and isinstance(_strict(outputs[0]), dict)


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_several_variants_share_the_draws(tmp_path, capsys):
    report = tmp_path / "mc"
    argv = ["montecarlo", "--samples", "6", "--tolerance", "motor.Km=10%", "--no-step"]
    assert main([*argv, "--all-variants", "--json", "-o", str(report)]) == 0
    data = _strict(capsys.readouterr().out)
    assert [item["variant"] for item in data] == ["base", "fitted", "relaxed", "loaded",
                                                  "fin_encoder", "sampled"]
    # no --seed: one fresh seed, used for every variant (and printed with each)
    assert len({item["seed"] for item in data}) == 1
    assert _strict((report / "montecarlo.json").read_text()) == data
    assert sorted(p.name for p in report.iterdir()) == [
        ".cas-freq-output", "histograms.base.svg", "histograms.fin_encoder.svg",
        "histograms.fitted.svg", "histograms.loaded.svg", "histograms.relaxed.svg",
        "histograms.sampled.svg",
        "montecarlo.json", "samples.csv"]
    lines = (report / "samples.csv").read_text().splitlines()
    assert lines[0].startswith("variant,sample,motor.Km [")
    rows = [line.split(",") for line in lines[1:]]
    assert [row[0] for row in rows] == (["base"] * 6 + ["fitted"] * 6 + ["relaxed"] * 6
                                        + ["loaded"] * 6 + ["fin_encoder"] * 6 + ["sampled"] * 6)
    # the same standard-normal numbers around each variant's own Km: the relative deviations
    # of the samples agree, to the CSV's 10 significant digits (a sample's rounding, <= 5e-11
    # of it, is below 1e-9 of the deviation's scale 1)
    nominal = {item.variant: item.params.motor.Km for item in
               [load_variant(None, name)
                for name in ("base", "fitted", "relaxed", "loaded", "fin_encoder", "sampled")]}
    deviations = {}
    for row in rows:
        deviations.setdefault(row[0], []).append(float(row[2]) / nominal[row[0]] - 1.0)
    np.testing.assert_allclose(deviations["fitted"], deviations["base"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(deviations["relaxed"], deviations["base"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(deviations["loaded"], deviations["base"], rtol=0, atol=1e-9)

    assert main([*argv, "--variant", "base", "--variant", "relaxed", "--seed", "4"]) == 0
    text = capsys.readouterr().out
    assert text.count("seed 4") == 2 and "qt_cas (relaxed)" in text
