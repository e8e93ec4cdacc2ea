"""``cas-freq report`` and ``cas-freq compare`` on the command line: files, exit codes, bad input,
and that the HTML renders in headless Chromium (conftest's ``chromium`` fixture; skipped, saying
why, where it is not installed: .ci/run installs it)."""

import html
import json
import re
import subprocess

import pytest
from clirun import run_cli

from cas_freq.plots import overlays
from cas_freq.plots import report as plots

FAST = ["--amplitudes", "0.5deg,10deg", "--frequencies", "600,1200", "--pade-order", "6"]


_run = run_cli


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory):
    target = tmp_path_factory.mktemp("cli") / "out"
    code, out, err = _run(["report", "--variant", "base", "-o", str(target), *FAST])
    assert code == 0, err
    assert out.strip() == str(target / "index.html")
    return target


def test_report_writes_the_files(report_dir):
    assert (report_dir / "index.html").is_file() and (report_dir / "report.md").is_file()
    results = json.loads((report_dir / "results.json").read_text())
    assert [v["variant"] for v in results["variants"]] == ["base"]
    assert results["settings"]["amplitudes_deg"] == pytest.approx([0.5, 10.0])
    # the shipped config has requirements: verify's verdicts are in the report
    assert {v["id"] for v in results["variants"][0]["verify"]} >= {"BW-1", "OS-1"}
    text = (report_dir / "report.md").read_text()
    assert ("regenerate with: cas-freq report --variant base --amplitudes 0.5deg,10deg "
            "--frequencies 600,1200 --pade-order 6") in text


def test_report_default_folder_is_under_reports(tmp_path, monkeypatch):
    from cas_freq.report.build import default_report_dir

    assert str(default_report_dir("qt_cas")) == "reports/qt_cas"
    assert str(default_report_dir("../../etc")) == "reports/_.._etc"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["report", "--variant", "nope"], "unknown variant 'nope'; the file has 'base'"),
        (["report", "--amplitudes", "10"], "--amplitudes"),
        (["report", "--frequencies", "5:1:3"], "--frequencies"),
        (["report", "--pade-order", "0"], "Padé order"),
        (["report", "missing.yaml"], "not found"),
        (["compare", "configs/qt_cas.yaml", "--variants", "base"], "at least two variants"),
        (["compare", "configs/qt_cas.yaml", "--variants", "base,,x"], "--variants"),
        (["compare", "configs/qt_cas.yaml", "--variants", "base,zzz"], "unknown variant 'zzz'"),
        (["compare", "--variant", "base", "--variant", "y", "--variant", "z"],
         "unknown variants 'y', 'z'"),
        (["compare", "--variant", "base"], "at least two variants"),
    ],
)
def test_bad_input_exits_2(argv, message, tmp_path, monkeypatch, shipped_config_path):
    monkeypatch.chdir(shipped_config_path.parents[1])
    code, _, err = _run([*argv, "-o", str(tmp_path / "never")])
    assert code == 2
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "never").exists()


def test_compare_cli(tmp_path, shipped_config_path):
    target = tmp_path / "cmp"
    code, out, err = _run(["compare", str(shipped_config_path), "--variants", "base,fitted",
                           "-o", str(target), *FAST])
    assert code == 0, err
    results = json.loads((target / "results.json").read_text())
    assert results["labels"] == ["qt_cas/base", "qt_cas/fitted"]
    assert [row[0] for row in results["verdict_matrix"]["rows"]][:2] == ["BW-1", "OS-1"]


# ---- the pages in a real browser ---------------------------------------------------------------

#: Chromium's options: headless, no sandbox (root in CI), and nothing that reaches the network
#: (this machine's network is closed) or outlives the run (a fresh profile each time).
CHROMIUM_OPTIONS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                    "--no-first-run", "--disable-background-networking",
                    "--disable-component-update", "--disable-sync")

#: Browser window widths checked for horizontal overflow [px]: a typical desktop, a narrow one.
WIDTHS_PX = (1280, 800)

#: Window width at which every table of up to :data:`FITTING_COLUMNS` columns shows whole,
#: without scrolling in its box [px] (a desktop window; the report's text column is 1100 px).
TABLE_WINDOW_PX = 1280

#: The most columns of a table that must fit :data:`TABLE_WINDOW_PX`: the verdicts (11) and a
#: comparison of six variants (8: parameters, verdicts). Compare's every-figure table, a value
#: and a difference per variant (12 columns for six), is wider by design and scrolls in its box.
FITTING_COLUMNS = 11

#: Run in the page on its load event (every image loaded): what the browser made of each
#: figure, and how wide the document is. The result goes into an attribute of <html>, which
#: --dump-dom prints (an attribute adds nothing to the layout it measures).
_PROBE = """
window.addEventListener("load", function () {
  function box(element) {
    var r = element.getBoundingClientRect();
    return {tag: element.tagName.toLowerCase(), width: r.width, height: r.height,
            natural: element.naturalWidth === undefined ? null
                     : [element.naturalWidth, element.naturalHeight],
            src: element.getAttribute("src")};
  }
  var figures = Array.from(document.querySelectorAll("figure")).map(function (figure) {
    return Array.from(figure.querySelectorAll(":scope > svg, :scope > img")).map(box);
  });
  var files = Array.from(document.querySelectorAll("#cas-freq-probe img")).map(box);
  var tables = Array.from(document.querySelectorAll("table")).map(function (table) {
    return {columns: table.querySelectorAll("thead th").length, box: table.clientWidth,
            content: table.scrollWidth,
            caption: (table.querySelector("caption") || {}).textContent || ""};
  });
  document.documentElement.setAttribute("data-check", JSON.stringify({
    innerWidth: window.innerWidth, scrollWidth: document.documentElement.scrollWidth,
    figures: figures, files: files, tables: tables}));
});
"""


def _check_page(folder):
    """check.html beside index.html: the page, every figure file it links to loaded as an image
    (in a 1 px clipped box, so they weigh nothing in the layout), and :data:`_PROBE`."""
    page = (folder / "index.html").read_text(encoding="utf-8")
    linked = sorted(set(re.findall(r'<a href="(figures/[^"]+\.svg)"', page)))
    probes = "".join(f'<img src="{path}" alt="">' for path in linked)
    extra = (f'<div id="cas-freq-probe" style="position:absolute;left:0;top:0;width:1px;'
             f'height:1px;overflow:hidden">{probes}</div><script>{_PROBE}</script>')
    target = folder / "check.html"
    target.write_text(page.replace("</body>", extra + "</body>"), encoding="utf-8")
    return target, linked


def _render(chromium, page, width, profile):
    """What :data:`_PROBE` found in ``page`` in a ``width`` px wide window [dict]."""
    done = subprocess.run(
        [chromium, *CHROMIUM_OPTIONS, f"--user-data-dir={profile}",
         f"--window-size={width},900", "--dump-dom", page.as_uri()],
        capture_output=True, text=True, timeout=120)
    found = re.search(r'<html[^>]*\sdata-check="([^"]*)"', done.stdout)
    assert done.returncode == 0 and found, (
        f"chromium exit {done.returncode}; stderr ends: {done.stderr[-600:]}")
    return json.loads(html.unescape(found.group(1)))


@pytest.fixture(scope="module")
def compare_dir(tmp_path_factory, shipped_config_path):
    target = tmp_path_factory.mktemp("cli") / "compare"
    code, _, err = _run(["compare", str(shipped_config_path), "--all-variants", "-o",
                         str(target), *FAST])
    assert code == 0, err
    return target


@pytest.mark.parametrize("which", ["report", "compare"])
def test_html_renders_in_headless_chromium(which, report_dir, compare_dir, chromium, tmp_path):
    """HEADLESS BROWSER CHECK: the qt_cas report and the comparison open from file:// in
    Chromium; every figure is drawn with a non-zero size and every figure file it links to loads
    as an image with a non-zero natural size; the page does not overflow horizontally at
    1280 px nor at 800 px (wide tables scroll inside their own box); at 1280 px every table of
    up to :data:`FITTING_COLUMNS` columns shows whole."""
    folder = report_dir if which == "report" else compare_dir
    files = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*.svg"))
    expected = (len(plots.VARIANT_FIGURES) if which == "report"
                else len(overlays.COMPARE_FIGURES))
    assert len(files) == expected
    page, linked = _check_page(folder)
    assert linked == files  # every figure file is linked from the page
    for width in WIDTHS_PX:
        seen = _render(chromium, page, width, tmp_path / f"profile-{width}")
        assert seen["innerWidth"] == width
        # one drawn <svg> or <img> per <figure>, each with a size on the page
        assert len(seen["figures"]) == expected
        for drawn in seen["figures"]:
            assert len(drawn) == 1 and drawn[0]["width"] > 0 and drawn[0]["height"] > 0, drawn
        # each linked file parsed and rendered by the browser as an image of its own
        assert [f["src"] for f in seen["files"]] == linked
        for loaded in seen["files"]:
            assert min(loaded["natural"]) > 0, loaded
        assert seen["scrollWidth"] <= seen["innerWidth"], (
            f"{which} overflows horizontally at {width} px: the document is "
            f"{seen['scrollWidth']} px wide")
        # in a desktop window no column of a table is cut off (parameters, verdicts, the
        # comparison's six variants): each shows whole in its box, nothing to scroll
        assert seen["tables"]
        for table in seen["tables"]:
            if width >= TABLE_WINDOW_PX and table["columns"] <= FITTING_COLUMNS:
                assert table["content"] <= table["box"], (
                    f"{which} at {width} px: the table '{table['caption'][:50]}' is "
                    f"{table['content']} px wide in a {table['box']} px box")
