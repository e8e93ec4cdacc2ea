"""Reports written at a stated precision: the rounding rules of :mod:`cas_freq.core.numbers`
on analytic examples, the SVG clean-up of :func:`cas_freq.plots.report.tidy_svg`, the
comparison of two results.json files within the written precision (what ``.ci/run`` checks
against the committed examples), and a report built twice on this machine byte for byte."""

import json
import math
import re

import numpy as np
import pytest

from cas_freq.config import load_variant
from cas_freq.core.numbers import (
    JSON_DIGITS,
    ZERO,
    difference,
    difference_value,
    json_differences,
    number,
    round_array,
    round_significant,
    rounded_json,
)
from cas_freq.plots.report import tidy_svg
from cas_freq.report.build import build_report
from cas_freq.report.data import ReportSettings

FAST = ReportSettings(
    amplitudes_rad=(math.radians(0.5), math.radians(10.0)),
    frequencies_rad_s=(600.0, 1200.0),
    pade_order=6,
)


# ---- rounding ---------------------------------------------------------------------------------

def test_round_significant():
    assert round_significant(1385.0312345678) == 1385.03  # 6 significant digits
    assert round_significant(1385.0312345678, 4) == 1385.0
    assert round_significant(0.1 + 0.2) == 0.3
    assert round_significant(2.0 / 3.0) == 0.666667
    assert round_significant(-123456789.0) == -123457000.0
    assert round_significant(1.2345e-6) == 1.2345e-6  # small but far above zero: kept
    assert round_significant(7) == 7 and isinstance(round_significant(7), int)
    for absent in (None, math.nan, math.inf, -math.inf):
        assert round_significant(absent) is None


@pytest.mark.parametrize("tiny", [7.142233997188651e-52, 1.928654933106574e-15, -3.0e-10,
                                  0.0, -0.0, 0.99e-9])
def test_numerically_zero_is_written_as_zero(tiny):
    # a fitted delay of 7e-52 s, |T(0)| of 2e-15 dB: below ZERO = 1e-9 in their unit
    assert abs(tiny) < ZERO
    value = round_significant(tiny)
    assert value == 0.0 and math.copysign(1.0, value) == 1.0  # never "-0"
    assert number(tiny) == "0"
    assert number(tiny, unit="ms") == "0 ms"
    assert rounded_json({"td_s": tiny}) == {"td_s": 0.0}


def test_number_text():
    assert number(698.6234) == "698.6"
    assert number(1385.03, 5) == "1385"
    assert number(0.000393123, 3) == "0.000393"
    assert number(63.41077909187686, unit="deg") == "63.41 deg"
    assert number(123456.0) == "1.235e+05"
    assert number(None) == "—" and number(math.nan) == "—" and number(math.inf) == "—"
    assert number(True) == "yes" and number(False) == "no"
    assert number("PASS") == "PASS"
    assert number(300) == "300"
    assert number(np.float64(2.5)) == "2.5"


def test_difference_is_zero_below_the_shown_precision():
    # equal up to a root finder's tolerance: the same as shown, so 0 (not +9.257e-07)
    assert difference(1466.5000009256743, 1466.5) == "0"
    assert difference(40.04 - 2.389e-05, 40.04) == "0"
    # below half a unit of the 5th significant digit the figures are shown with: 0
    assert difference(1466.53, 1466.51) == "0"
    assert difference(1466.53, 1466.47) == "+0.06 (+0.00409 %)"
    # both numerically zero: 0, not -3e-51
    assert difference(7.142233997188651e-52, 3.0383034192225457e-51) == "0"
    # written with 4 digits, relative to the baseline (from the 6-digit figures of results.json)
    assert difference(891.1, 1385.0) == "-493.9 (-35.7 %)"
    assert difference(26481.4812345, 26487.0) == "-5.5 (-0.0208 %)"  # 26481.5 - 26487
    assert difference(0.00012855, 0.00012696) == "+1.59e-06 (+1.25 %)"
    assert difference(None, 1.0) == "—" and difference(1.0, None) == "—"
    assert difference(True, True) == "same" and difference(True, False) == "differs"
    assert difference(1.0, 0.0) == "+1"  # no relative change to a zero baseline


def test_difference_value():
    assert difference_value(1452.2, 1466.5, 5) == -14.3  # not -14.299999999999955
    assert difference_value(1466.5000009, 1466.5) == 0.0
    assert difference_value(1.0e-12, 0.0) == 0.0
    assert difference_value(2.0, 1.0) == 1.0
    assert difference_value(None, 1.0) is None and difference_value("a", "b") is None
    assert difference_value(True, False) is None


def test_rounded_json():
    data = {"a": 0.1 + 0.2, "b": [1e-20, math.nan, np.float64(2 / 3), -math.inf],
            "c": True, "d": 3, "e": np.int64(4), "f": "text 1.23456789", "g": None,
            "h": (np.bool_(False), 1234567.891)}
    assert rounded_json(data) == {"a": 0.3, "b": [0.0, None, 0.666667, None], "c": True,
                                  "d": 3, "e": 4, "f": "text 1.23456789", "g": None,
                                  "h": [False, 1234570.0]}
    text = json.dumps(rounded_json(data))
    assert "NaN" not in text and "Infinity" not in text


def test_round_array_keeps_gaps():
    values = round_array([1.23456789, math.nan, -2e-15, 98765.4321, math.inf])
    assert values[0] == 1.23457 and math.isnan(values[1]) and values[2] == 0.0
    assert values[3] == 98765.4 and values[4] == math.inf
    assert round_array(np.ones((2, 3)) / 3).shape == (2, 3)


@pytest.mark.parametrize("digits", [3, 4, 6])
def test_round_array_gives_formatted_floats_to_the_bit(digits):
    # The vectorised rounding must give exactly float(format(v, ".6g")) (Python's correctly
    # rounded formatting, the reference): random magnitudes over 42 decades, decimal values
    # with exact ties at the last digit (0.1234565), powers of ten and their neighbouring
    # floats (where log10 may be off), values that round up to the next power (999999.5).
    rng = np.random.default_rng(digits)
    powers = 10.0 ** np.arange(-9, 25, dtype=float)
    values = np.concatenate([
        rng.standard_normal(50_000) * 10.0 ** rng.uniform(-12, 30, 50_000),
        np.round(rng.uniform(-1e7, 1e7, 50_000)) / 10.0 ** rng.integers(0, 9, 50_000),
        powers, -powers, np.nextafter(powers, 0.0), np.nextafter(powers, np.inf),
        [0.1234565, 1.234565, 999999.5, 9999995.0, 0.5, 2.5e-7, 1.5e300, -3.7e-300, 1e-9],
    ])
    expected = [float(format(v, f".{digits}g")) + 0.0 if abs(v) >= ZERO else 0.0
                for v in values.tolist()]
    got = round_array(values, digits)
    np.testing.assert_array_equal(got.view(np.int64), np.array(expected).view(np.int64))


# ---- comparing results.json within the written precision ---------------------------------------

def test_json_differences_within_the_written_precision():
    committed = {"bw": 1385.03, "td": 0.0, "ok": True, "name": "base", "none": None,
                 "msg": "overshoot = 3.339 % meets <= 15 %",
                 "table": [{"values": [1466.5, 1466.5], "differences": [0.0, 0.0]}]}
    same = json.loads(json.dumps(committed))
    assert json_differences(committed, same) == []
    # a last digit rounded the other way on another machine is within the precision
    other = {**same, "bw": 1385.04, "msg": "overshoot = 3.340 % meets <= 15 %",
             "table": [{"values": [1466.5, 1466.49], "differences": [0.0, -0.01]}]}
    assert json_differences(committed, other) == []
    assert json_differences(committed, {**same, "td": 1e-12}) == []
    # beyond the precision, or a changed structure, is reported with its path
    assert json_differences(committed, {**same, "bw": 1386.0}) == [
        "$.bw: expected 1385.03, got 1386.0"]
    assert json_differences(committed, {**same, "msg": "overshoot = 3.36 % meets <= 15 %"})
    assert json_differences(committed, {**same, "msg": "overshoot = 3.339 % fails <= 15 %"})
    assert json_differences(committed, {**same, "ok": False})
    assert json_differences(committed, {**same, "none": 0.0})
    assert json_differences(committed, {**same, "bw": None})
    assert json_differences(committed, {**same, "extra": 1})[0].startswith("$: keys")
    changed = {**same, "table": [{"values": [1466.5, 1400.0], "differences": [0.0, -66.5]}]}
    assert json_differences(committed, changed) == [
        "$.table[0].values[1]: expected 1466.5, got 1400.0",
        "$.table[0].differences[1]: expected 0.0, got -66.5"]
    assert json_differences([1, 2], [1, 2, 3]) == ["$: 2 items expected, got 3"]


# ---- SVG -----------------------------------------------------------------------------------------

def _svg(noise, hash_p, hash_m):
    return f"""<?xml version="1.0" encoding="utf-8" standalone="no"?>
<!DOCTYPE svg PUBLIC "-//W3C//DTD SVG 1.1//EN"
  "http://www.w3.org/Graphics/SVG/1.1/DTD/svg11.dtd">
<svg width="504pt" height="396pt" viewBox="0 0 504 396" version="1.1">
 <defs><path id="m{hash_m}" d="M 0 {3.5 + noise:f} L -0.123456 0.5"/></defs>
 <g id="line2d_1">
  <path d="M 41.995162 {363.999057 + noise:f} L 499.634221 21.00" clip-path="url(#p{hash_p})" \
style="stroke-opacity: 0.35; stroke-width: 1.4"/>
  <use xlink:href="#m{hash_m}" x="119.065187" y="-0.001" style="fill: #1f77b4"/>
 </g>
 <g id="text_1"><!-- ζ 0.358123 @ 698.6 rad/s -->
  <text x="{12.3456 + noise:f}" y="7.89">ζ 0.358123 @ 698.6 rad/s</text>
 </g>
 <clipPath id="p{hash_p}"><rect x="41.995162" y="21.001658" width="457.639059" height="343"/>
 </clipPath>
</svg>
"""


def test_tidy_svg_rounds_coordinates_and_renames_hashed_ids():
    tidy = tidy_svg(_svg(0.0, "8847e705fe", "1cdd57e84d"))
    assert tidy.startswith('<?xml version="1.0" encoding="utf-8" standalone="no"?>')
    assert "SVG 1.1//EN" in tidy and 'viewBox="0 0 504 396"' in tidy
    assert 'd="M 42 364 L 499.63 21.00"' in tidy  # 2 decimals (41.995162 is 42.00)
    assert 'd="M 0 3.5 L -0.12 0.5"' in tidy
    assert 'x="119.07" y="0"' in tidy  # -0.001 -> 0, never "-0"
    assert "stroke-opacity: 0.35; stroke-width: 1.4" in tidy and "#1f77b4" in tidy
    # text content and comments are not numbers to round
    assert "<!-- ζ 0.358123 @ 698.6 rad/s -->" in tidy and ">ζ 0.358123 @ 698.6 rad/s<" in tidy
    assert '<text x="12.35" y="7.89">' in tidy  # 3 or more decimals are rounded, fewer kept
    # the content-hash ids are renamed consistently, references follow
    assert "8847e705fe" not in tidy and "1cdd57e84d" not in tidy
    (p_id,) = re.findall(r'clipPath id="([^"]+)"', tidy)
    (m_id,) = re.findall(r'path id="([^"]+)"', tidy)
    assert re.fullmatch(r"p[0-9a-f]{8}_1", p_id) and re.fullmatch(r"m[0-9a-f]{8}_0", m_id)
    assert f'clip-path="url(#{p_id})"' in tidy and f'xlink:href="#{m_id}"' in tidy


def test_tidy_svg_hides_last_bit_noise():
    # the same figure drawn from floats that differ in their last bits: other coordinates
    # (matplotlib writes 6 decimals) and so other matplotlib hashes, the same tidy SVG
    one = tidy_svg(_svg(0.0, "8847e705fe", "1cdd57e84d"))
    two = tidy_svg(_svg(2e-6, "0123456789", "abcdefabcd"))
    assert _svg(0.0, "8847e705fe", "1cdd57e84d") != _svg(2e-6, "8847e705fe", "1cdd57e84d")
    assert one == two
    # a different figure gets other ids (figures inlined in one HTML page never share one)
    three = tidy_svg(_svg(0.5, "8847e705fe", "1cdd57e84d"))
    assert set(re.findall(r'id="(p[^"]+)"', one)).isdisjoint(
        re.findall(r'id="(p[^"]+)"', three))


# ---- a whole report -----------------------------------------------------------------------------

def _files(root):
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def _floats(value):
    if isinstance(value, float):
        yield value
    elif isinstance(value, dict):
        for item in value.values():
            yield from _floats(item)
    elif isinstance(value, list):
        for item in value:
            yield from _floats(item)


@pytest.fixture(scope="module")
def one_build(tmp_path_factory):
    """The fitted variant's report (its 0.5° step fits a delay of 7e-52 s, i.e. 0)."""
    root = tmp_path_factory.mktemp("determinism")
    return build_report([load_variant(None, "fitted")], root / "one", settings=FAST)


@pytest.mark.slow  # run by .ci/run, which also builds the shipped reports twice and compares
def test_report_built_twice_is_byte_identical(one_build, tmp_path):
    two = build_report([load_variant(None, "fitted")], tmp_path / "two", settings=FAST)
    first = _files(one_build)
    assert first == _files(two)
    assert {"index.html", "report.md", "results.json"} <= set(first)
    assert any(name.endswith(".svg") for name in first)


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_figures_drawn_in_worker_processes_equal_drawn_here(one_build, tmp_path):
    # build_report draws the figures in FIGURE_WORKERS forked processes by default; drawn in
    # this process instead, every file is the same byte for byte (the load envelope's figure
    # included: a worker draws it while the report is computed)
    here = build_report([load_variant(None, "fitted")], tmp_path / "here", settings=FAST,
                        workers=1)
    assert _files(here) == _files(one_build)
    assert "figures/fitted/load_envelope.svg" in _files(one_build)


def test_report_is_written_at_the_stated_precision(one_build):
    folder = one_build
    results = json.loads((folder / "results.json").read_text())
    for value in _floats(results):
        assert value == round_significant(value, JSON_DIGITS)  # at most 6 significant digits
        assert value == 0.0 or abs(value) >= ZERO
    step = results["variants"][0]["simulate"][0]
    assert step["step"]["amplitude_deg"] == 0.5 and step["fit"]["td_s"] == 0.0
    assert results["variants"][0]["analyze"]["closed_loop"]["dc_gain_db"] == 0.0
    text = (folder / "report.md").read_text()
    assert not re.search(r"\de-(1\d|[2-9]\d)", text)  # no 1e-10 and smaller: those are 0
    assert re.search(r"\| 0\.5° step \(model\) \| [^|]+ \| [^|]+ \| 0 \|", text)  # td 0 ms
    assert "| DC gain \\|T(0)\\| | dB | 0 |" in text
    for name in (p for p in folder.rglob("*.svg")):
        svg = name.read_text()
        tags = re.sub(r"<!--.*?-->", "", svg, flags=re.DOTALL)
        tags = " ".join(re.findall(r"<[^>]*>", tags))
        assert not re.search(r"\d\.\d{3}", tags), name  # coordinates at 0.01 pt
