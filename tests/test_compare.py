"""``cas-freq compare``'s library: labels, the every-figure table with differences to the
baseline, the verdict matrix and the folder (fast settings, as in test_report.py)."""

import json
import math

import pytest

from cas_freq.config import load_variant
from cas_freq.exceptions import CasFreqError
from cas_freq.report.compare import (
    build_compare,
    compare_files,
    default_compare_dir,
    difference_rows,
    entry_labels,
    flat_figures,
    verdict_matrix,
)
from cas_freq.report.data import ReportSettings, gather_variant, variant_results
from cas_freq.report.numbers import round_significant
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
    table = {row[0]: row[1:] for row in rows}
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
    page = (target / "index.html").read_text()
    assert page.count("<svg") == 3 and 'class="ADVISORY"' in page


def test_needs_two_variants():
    with pytest.raises(CasFreqError, match="at least two"):
        build_compare([load_variant(None, "base")], settings=FAST)
