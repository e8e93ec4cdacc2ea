"""``cas-freq compare``'s library: labels, the parameter-difference table, the every-figure table
(readable labels in engineering units) with differences to the baseline, the verdict matrix and
the folder (fast settings, as in test_report.py)."""

import json
import math
import re

import pytest

from cas_freq.config import load_variant
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.numbers import round_significant
from cas_freq.core.parameters import PARAMETERS, parse_value
from cas_freq.report.compare import (
    SETTINGS,
    build_compare,
    compare_files,
    config_keys,
    default_compare_dir,
    difference_rows,
    entry_labels,
    figure_display,
    flat_figures,
    parameter_differences,
    table_figure,
    verdict_matrix,
)
from cas_freq.report.data import ReportSettings, gather_variant, variant_results
from cas_freq.report.outdir import write_directory_atomic

FAST = ReportSettings(
    amplitudes_rad=(math.radians(0.5), math.radians(10.0)),
    frequencies_rad_s=(600.0, 1200.0),
    pade_order=6,
)

VERDICTS = [
    {"id": "BW-1", "variant": "base", "metric": "closed_loop.bandwidth_rad_s", "value": 1385.0,
     "unit": "rad/s", "status": "PASS"},
    {"id": "BW-1", "variant": "relaxed", "metric": "closed_loop.bandwidth_rad_s",
     "value": 891.1, "unit": "rad/s", "status": "PASS"},
    {"id": "PM-P", "variant": "relaxed", "metric": "position_loop.phase_margin_deg",
     "value": 43.2, "unit": "deg", "status": "ADVISORY"},
]


@pytest.fixture(scope="module")
def pair():
    variants = [load_variant(None, "base"), load_variant(None, "relaxed")]
    return variants, [gather_variant(v, FAST, verdicts=VERDICTS) for v in variants]


def test_entry_labels_disambiguate_repeats():
    base = load_variant(None, "base")
    fitted = load_variant(None, "fitted")
    assert entry_labels([base, fitted, base]) == ["qt_cas/base", "qt_cas/fitted",
                                                  "qt_cas/base#2"]


def test_default_folder_is_sanitised():
    base = load_variant(None, "base")
    bad = type(base)(base.source, "base", base.params.model_copy(update={"name": "../x y"}))
    assert str(default_compare_dir([base, bad])) == "reports/compare-qt_cas-.._x_y"
    assert default_compare_dir([base], ["base", "fitted"]).name == "compare-qt_cas-base-fitted"


def test_every_figure_with_difference_to_baseline(pair):
    _, datas = pair
    results = [variant_results(d) for d in datas]
    rows, flats, keys = difference_rows(results)
    table = {key: row[1:] for key, row in zip(keys, rows, strict=True)}
    # the relaxed variant scales the position gains only: the current loop is the same ...
    assert table["analyze.current_loop.phase_margin_deg"][2] == "0"
    # ... and the bandwidth falls (analyze's own numbers, difference = value - baseline)
    key = "analyze.closed_loop.bandwidth_rad_s"
    assert table[key][0] == f"{round_significant(flats[0][key], 5):.5g}"  # 5 digits shown
    # the difference of the figures as results.json writes them (6 digits), shown with 4
    delta = round_significant(flats[1][key]) - round_significant(flats[0][key])
    assert delta < 0
    assert table[key][2].startswith(f"{round_significant(delta, 4):+.4g} (")
    assert "step 10°.overshoot_pct" in keys and "fit 10°.zeta" in keys
    assert "sinedwell.bandwidth_rad_s 0.5°" in keys
    assert all(not isinstance(v, (list, dict)) for v in flat_figures(results[0]).values())


def test_verdict_matrix(pair):
    _, datas = pair
    rows, header = verdict_matrix(datas, ["b", "r"])
    assert header == ("requirement", "metric", "b", "r")
    matrix = {row[0]: row[2:] for row in rows}
    assert matrix["BW-1"] == ("PASS (1385 rad/s)", "PASS (891.1 rad/s)")
    assert matrix["PM-P"] == ("—", "ADVISORY (43.2 deg)")


def test_folder(pair, tmp_path):
    _, datas = pair
    target = tmp_path / "cmp"
    labels = ["qt_cas/base", "qt_cas/relaxed"]
    write_directory_atomic(target, compare_files(datas, labels, FAST))
    names = sorted(p.relative_to(target).as_posix() for p in target.rglob("*") if p.is_file())
    assert names == [".cas-freq-output", "figures/bandwidth_overlay.svg",
                     "figures/bode_overlay.svg", "figures/step_overlay.svg", "index.html",
                     "report.md", "results.json"]
    results = json.loads((target / "results.json").read_text())
    assert results["baseline"] == "qt_cas/base"
    assert [e["label"] for e in results["entries"]] == labels
    row = next(r for r in results["figures_table"]
               if r["figure"] == "analyze.closed_loop.bandwidth_rad_s")
    assert row["differences"][0] == 0.0 and row["differences"][1] < 0
    # the differences are those of the figures as written (6 significant digits)
    assert row["differences"][1] == round_significant(row["values"][1] - row["values"][0])
    # scaling every position-loop gain leaves the phase, so the phase crossovers are the same
    # up to the root finder's tolerance: as written they are equal and differ by exactly 0
    row = next(r for r in results["figures_table"]
               if r["figure"] == "analyze.position_loop.phase_crossover_rad_s")
    assert row["values"][0] == row["values"][1] and row["differences"] == [0.0, 0.0]
    text = (target / "report.md").read_text()
    assert "| BW-1 | closed_loop.bandwidth_rad_s | PASS (1385 rad/s) |" in text
    # the parameters that differ come first; the every-figure table has labels, not JSON keys
    sections = [line for line in text.splitlines() if line.startswith("## ")]
    assert sections[0] == "## Parameters that differ"
    assert "| position_loop.Kp | position-loop proportional gain | 6.3435 A/rad | 3.8061 A/rad |" \
        in text
    assert "| current loop: delay margin [ms] |" in text
    assert "analyze.current_loop.delay_margin_s" not in text
    page = (target / "index.html").read_text()
    assert page.count("<svg") == 3 and 'class="ADVISORY"' in page


def test_needs_two_variants():
    with pytest.raises(CasFreqError, match="at least two"):
        build_compare([load_variant(None, "base")], settings=FAST)


# ---- the parameter-difference table ------------------------------------------------------------


def _flat(prefix, node, out):
    for key, value in node.items():
        dotted = f"{prefix}.{key}" if prefix else key
        if isinstance(value, dict):
            _flat(dotted, value, out)
        else:
            out[dotted] = value
    return out


def _yaml_values(raw, variant):
    """Each compared key's value in a variant as the YAML writes it, converted to SI: the base
    sections, then the variant's keys (a variant that gives ``motor.mu_v`` drops the no-load
    point, and the other way round, as docs and the loader state). Absent keys are missing."""
    values = _flat("", {k: v for k, v in raw.items() if k in ("motor", "gear", "current_loop",
                                                                "position_loop", "simulation")},
                   {})
    changes = _flat("", raw["variants"][variant] or {}, {}) if variant != "base" else {}
    for key, dropped in (("motor.mu_v", "motor.no_load."), ("motor.no_load.", "motor.mu_v")):
        if any(k.startswith(key) for k in changes):
            values = {k: v for k, v in values.items() if not k.startswith(dropped)}
    values.update(changes)
    return {k: parse_value(k, v) if k in PARAMETERS else v for k, v in values.items()
            if k in PARAMETERS or k in SETTINGS}


def _differ(values):
    first = values[0]
    if any(v is None for v in values):
        return not all(v is None for v in values)
    if isinstance(first, float):
        return not all(math.isclose(first, v, rel_tol=1e-9) for v in values)
    return any(v != first for v in values)


def test_parameter_table_lists_exactly_the_keys_that_differ(shipped_raw):
    names = ["base", *shipped_raw["variants"]]
    per_variant = [_yaml_values(shipped_raw, name) for name in names]
    keys = set().union(*per_variant)
    expected = {k for k in keys if _differ([values.get(k) for values in per_variant])}
    # what the YAML says: the fitted motor (Km, J, mu_v replacing the no-load point), the
    # relaxed position gains, the loaded variant's load and drivetrain, and the sampled
    # variant's controller rates
    assert expected == {"motor.Km", "motor.J", "motor.mu_v", "motor.no_load.speed",
                        "motor.no_load.current", "position_loop.Kp", "position_loop.Ki",
                        "position_loop.Kd", "motor.coulomb_friction", "gear.efficiency",
                        "gear.backdrive_efficiency", "gear.stiffness", "gear.damping",
                        "load.inertia", "load.hinge_stiffness", "load.hinge_bias",
                        "sampling.current_loop", "sampling.position_loop"}
    rows, equal = parameter_differences([load_variant(None, name) for name in names])
    assert [row[0] for row in rows] == [k for k in config_keys() if k in expected]
    assert equal == len(config_keys()) - len(expected)


def test_parameter_values_carry_the_units_the_config_writes():
    rows, _ = parameter_differences([load_variant(None, name)
                                     for name in ("base", "fitted", "relaxed")])
    table = {row[0]: row[2:] for row in rows}
    meaning = {row[0]: row[1] for row in rows}
    assert table["position_loop.Kp"] == ("6.3435 A/rad", "6.3435 A/rad", "3.8061 A/rad")
    assert table["motor.J"] == ("5.54e-07 kg*m^2", "7.19e-07 kg*m^2", "5.54e-07 kg*m^2")
    # written as 16300 rpm, stored as 1706.9 rad/s: shown as written; absent where mu_v is set
    assert table["motor.no_load.speed"] == ("16300 rpm", "—", "16300 rpm")
    # mu_v derived from the no-load point (Km I0 / w0) unless set
    mu_v = 0.0105 * 0.218 / (16300 * 2 * math.pi / 60)
    assert table["motor.mu_v"][0] == f"{mu_v:.6g} N*m*s/rad (derived)"
    assert table["motor.mu_v"][1] == "1.2e-06 N*m*s/rad"
    assert meaning["position_loop.Kp"] == "position-loop proportional gain"
    for cells in table.values():
        for cell in cells:
            assert cell == "—" or cell.split(" ")[1], cell  # a number and its unit


def test_parameter_table_converts_to_the_baseline_unit(write_config, shipped_raw):
    raw = shipped_raw
    raw.pop("load_envelope")  # it names the shipped variants replaced here
    raw["variants"] = {
        "same_in_us": {"current_loop.delay": "60 us"},  # = 0.06 ms: not a difference
        "slow": {"position_loop.delay": "500 us", "simulation": {"controllers": "sampled"}},
    }
    path = write_config(raw)
    variants = [load_variant(path, name) for name in ("base", "same_in_us", "slow")]
    rows, equal = parameter_differences(variants)
    table = {row[0]: row[2:] for row in rows}
    # the older spelling of the sampling is compared as the sampling: section it declares
    assert set(table) == {"position_loop.delay", "sampling.current_loop", "sampling.position_loop"}
    # base writes 0.4 ms: the row is in ms, 500 us shown as 0.5 ms
    assert table["position_loop.delay"] == ("0.4 ms", "0.4 ms", "0.5 ms")
    assert table["sampling.position_loop"] == ("—", "—", "2500 Hz")
    assert equal == len(config_keys()) - 3
    # a --set override counts like a variant's value, in the unit it is written with
    override = load_variant(path, "base", overrides=[("position_loop.Tf", "0.7 ms")])
    rows, _ = parameter_differences([variants[0], override])
    assert [row[0] for row in rows] == ["position_loop.Tf"]
    assert rows[0][2:] == ("0.600615 ms (derived)", "0.7 ms")


def test_parameter_table_of_two_configs(shipped_config_path):
    qt = load_variant(shipped_config_path, "base")
    dc = load_variant(shipped_config_path.parent / "dc_servo.yaml", "base")
    rows, _ = parameter_differences([qt, dc])
    table = {row[0]: row[2:] for row in rows}
    assert table["current_loop.delay"] == ("0.06 ms", "0.05 ms")
    assert table["gear.ratio"] == ("20", "50")
    # Tf derived in both, Kd/(10 Kp): 0.0381/63.435 s and 0.08/60 s
    assert table["position_loop.Tf"] == ("0.600615 ms (derived)", "1.33333 ms (derived)")
    # dc_servo leaves the simulation section at its defaults, which qt_cas writes: equal
    assert not any(key.startswith("simulation.") for key in table)


# ---- the every-figure table's labels and units ------------------------------------------------


def test_every_figure_has_a_label_and_a_unit(pair):
    _, datas = pair
    keys = list(flat_figures(variant_results(datas[0])))
    # every figure of the table is one of the figure table's (cas_freq.core.figures): none falls
    # back to its raw name
    assert [key for key in keys if table_figure(re.sub(r" [\d.]+°$", "", key)) is None] == []
    labels = [figure_display(key)[0] for key in keys]
    assert len(set(labels)) == len(labels)
    assert figure_display("analyze.current_loop.delay_margin_s") == (
        "current loop: delay margin [ms]", "ms", 1e3)
    assert figure_display("sinedwell.bandwidth_rad_s 10°")[0] == (
        "sine-dwell: bandwidth ω_BW (−3.01 dB) at 10° [rad/s]")
    assert figure_display("fit 0.5°.rms_residual")[:2] == (
        "fit to the 0.5° step: RMS residual [deg]", "deg")
    # a linear step's figure is the step figure of the table, measured on the linear model
    assert figure_display("linear step 10°.rise_time_s") == (
        "linear step 10°: rise time 10–90 % [ms]", "ms", 1e3)
    assert figure_display("analyze.position_loop.new_figure_db") == (
        "position loop: new figure [dB]", "dB", 1.0)


def _results(delay_margin_s, rise_time_s, rms_residual_rad, bandwidth_rad_s):
    """A minimal results entry holding one figure of each kind (SI, as results.json)."""
    return {
        "analyze": {"current_loop": {"delay_margin_s": delay_margin_s}},
        "simulate": [{"step": {"amplitude_deg": 10.0, "rise_time_s": rise_time_s},
                      "fit": {"rms_residual": rms_residual_rad}}],
        "linear_steps": [],
        "sinedwell": {"amplitudes": [{"amplitude_deg": 10.0, "bandwidth_rad_s": bandwidth_rad_s}],
                      "limit_onset_amplitude_deg": 2.0},
    }


#: The relative change keeps its "%" on the line of its number.
NBSP = "\N{NO-BREAK SPACE}"


def test_si_figures_are_shown_in_display_units_by_hand():
    base = _results(0.000126964, 0.0092446, 0.00344421, 426.094)
    other = _results(0.000128547, 0.00564711, 0.00274302, 423.183)
    rows, _, keys = difference_rows([base, other])
    table = dict(zip(keys, rows, strict=True))
    # 0.000126964 s = 0.126964 ms, shown with 5 significant digits; the difference
    # 0.128547 - 0.126964 = +0.001583 ms, and 0.001583 / 0.126964 = +1.25 %
    assert table["analyze.current_loop.delay_margin_s"] == (
        "current loop: delay margin [ms]", "0.12696", "0.12855", f"+0.001583 (+1.25{NBSP}%)")
    # 9.2446 ms and 5.64711 ms; 5.64711 - 9.2446 = -3.59749 ms (4 digits: -3.597), -38.9 %
    assert table["step 10°.rise_time_s"] == (
        "nonlinear step 10°: rise time 10–90 % [ms]", "9.2446", "5.6471",
        f"-3.597 (-38.9{NBSP}%)")
    # 0.00344421 rad x 180/pi = 0.197339 deg; 0.00274302 rad = 0.157163 deg
    assert table["fit 10°.rms_residual"][:3] == (
        "fit to the 10° step: RMS residual [deg]", "0.19734", "0.15716")
    # rad/s stay rad/s; 423.183 - 426.094 = -2.911, -0.683 %
    assert table["sinedwell.bandwidth_rad_s 10°"] == (
        "sine-dwell: bandwidth ω_BW (−3.01 dB) at 10° [rad/s]", "426.09", "423.18",
        f"-2.911 (-0.683{NBSP}%)")
    assert table["sinedwell.limit_onset_amplitude_deg"][1:] == ("2", "2", "0")
