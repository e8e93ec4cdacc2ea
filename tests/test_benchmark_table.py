"""benchmarks/run.py's table is the one source of the speed tables of README.md and
docs/speed.md (``--write-docs``): the Markdown it prints and how it replaces them."""

import importlib.util
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def run():
    """benchmarks/run.py as a module (its folder on sys.path for ``baselines``; the BLAS
    variables it sets at import restored)."""
    saved_path, saved_env = list(sys.path), dict(os.environ)
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        spec = importlib.util.spec_from_file_location("benchmark_run", ROOT / "benchmarks/run.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path[:] = saved_path
        os.environ.clear()
        os.environ.update(saved_env)
    return module


def _rows(run):
    return [run.Row("sine-dwell map 8 × 30", "1.20 s", goal="≤ 1.5 s", load="0.5–0.7",
                    headline=True),
            run.Row("one step", "0.50 ms", "nlsys 300 ms", 600.0, "≥ 1,000×", "0.5–0.6"),
            run.Row("same", "0.50 ms", "nlsys 20 ms", 40.0, headline=True)]


def test_table_is_markdown_with_ratio_goal_and_load(run):
    lines = run.table(_rows(run)).splitlines()
    assert lines[0] == "| case | cas_freq | python-control | ratio | goal | load |"
    assert lines[2] == "| sine-dwell map 8 × 30 | 1.20 s | – | – | ≤ 1.5 s | 0.5–0.7 |"
    assert lines[3] == "| one step | 0.50 ms | nlsys 300 ms | 600× | ≥ 1,000× | 0.5–0.6 |"
    assert len(lines) == 5 and all(line.count("|") == 7 for line in lines)


def test_write_docs_replaces_only_the_marked_table(run, tmp_path):
    readme, speed = tmp_path / "README.md", tmp_path / "speed.md"
    for path in (readme, speed):
        path.write_text(f"before\n{run.TABLE_START}\nold table\n{run.TABLE_END}\nafter\n",
                        encoding="utf-8")
    run.write_docs(_rows(run), "Measured now.\n\n", {readme: True, speed: False})
    short, full = readme.read_text(encoding="utf-8"), speed.read_text(encoding="utf-8")
    assert "old table" not in short + full
    assert short.startswith(f"before\n{run.TABLE_START}\nMeasured now.\n\n| case |")
    assert short.endswith(f"{run.TABLE_END}\nafter\n") and full.endswith("after\n")
    assert "one step" in full and "one step" not in short  # the README: issue 30's rows
    assert "nlsys 20 ms" in short
    # a file without its markers is refused, and then nothing is written
    readme.write_text("no markers\n", encoding="utf-8")
    before = speed.read_text(encoding="utf-8")
    with pytest.raises(SystemExit, match="speed-table"):
        run.write_docs(_rows(run), "", {speed: False, readme: True})
    assert speed.read_text(encoding="utf-8") == before


def test_the_docs_have_the_markers(run):
    for path in run.DOCS:
        text = path.read_text(encoding="utf-8")
        assert text.count(run.TABLE_START) == 1 and text.count(run.TABLE_END) == 1, path
