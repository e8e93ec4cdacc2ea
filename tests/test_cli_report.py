"""``cas-freq report`` and ``cas-freq compare`` on the command line: files, exit codes, bad input,
and (when Chromium is installed) that the HTML renders its figures in a headless browser."""

import json
import shutil
import subprocess

import pytest
from clirun import run_cli

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
        (["report", "--variant", "nope"], "unknown variant(s) nope; the file has base"),
        (["report", "--amplitudes", "10"], "--amplitudes"),
        (["report", "--frequencies", "5:1:3"], "--frequencies"),
        (["report", "--pade-order", "0"], "Padé order"),
        (["report", "missing.yaml"], "not found"),
        (["compare", "configs/qt_cas.yaml", "--variants", "base"], "at least two variants"),
        (["compare", "configs/qt_cas.yaml", "--variants", "base,,x"], "--variants"),
        (["compare", "configs/qt_cas.yaml", "--variants", "base,zzz"], "unknown variant(s) zzz"),
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


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(CHROMIUM is None, reason="headless-browser check: Chromium not installed")
def test_html_renders_in_headless_chromium(report_dir, tmp_path):
    """HEADLESS BROWSER CHECK (skipped without Chromium): the page loads from file:// with
    every figure as an inline SVG element the browser parsed, and renders to a screenshot."""
    url = (report_dir / "index.html").as_uri()
    common = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"]
    dom = subprocess.run([*common, "--dump-dom", url], capture_output=True, text=True,
                         timeout=120, check=True).stdout
    assert dom.count("<svg") == len(plots.VARIANT_FIGURES)
    assert "<title>cas_freq report: qt_cas</title>" in dom
    shot = tmp_path / "shot.png"
    subprocess.run([*common, "--window-size=1200,3000", f"--screenshot={shot}", url],
                   capture_output=True, timeout=120, check=True)
    assert shot.stat().st_size > 50_000  # a blank page is a few kB
