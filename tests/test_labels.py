"""Every name of a loop, a break point and a figure is typed once (issue 39, item 5).

A loop's symbol and where it is broken are declared by the loop structure
(:func:`cas_freq.model.structure.build`); a figure's label and unit by the figure table
(:data:`cas_freq.core.figures.FIGURES`). Everything else reads them: this test scans the package's
source (``ast``: every string literal but the docstrings, f-strings' literal parts included)
for a copy typed by hand, which is how the tables, the text and the figures used to drift
from the declaration ("bandwidth (-3 dB)" beside "bandwidth ω_BW (−3.01 dB)"; a cascade's
position loop "broken at the current command").
"""

import ast
import re
from pathlib import Path

import pytest

import cas_freq
from cas_freq.config import load_variant
from cas_freq.core.figures import FIGURES
from cas_freq.report.data import described_loops

PACKAGE = Path(cas_freq.__file__).parent

#: The declarations, where the names are typed.
DECLARATIONS = {"core/figures.py", "model/structure.py"}

#: Labels that are also a value a result holds (the verdict "stable"): a literal equal to them
#: is that value, not a copy of the label.
ALSO_VALUES = {"stable"}


def _literals(tree):
    """The string literals of a module that are not docstrings: (line, text)."""
    docstrings = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            first = node.body[0] if node.body else None
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                docstrings.add(id(first.value))
        elif isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
            docstrings.add(id(node.value))  # a bare string: an attribute's docstring
    return [(node.lineno, node.value) for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str)
            and id(node) not in docstrings]


@pytest.fixture(scope="module")
def declared_loops():
    """The loops of a PID-on-PI drive and of a cascade, as the structure declares them."""
    return [loop for path in ("configs/qt_cas.yaml", "configs/cascade_axis.yaml")
            for loop in described_loops(load_variant(path, "base").params)]


def copies(text, labels, symbols, breaks):
    """Why ``text`` (a literal) copies a declared name, or None."""
    if text in labels or text in symbols:
        return "a figure's label or a loop's symbol"
    if any(text.startswith(f"{label} [") for label in labels):
        return "a figure's label with a unit"
    if symbols and re.search(rf"(?<!\w)(?:{'|'.join(map(re.escape, symbols))})(?!\w)", text):
        return "a loop's symbol"
    if any(f"broken at {where}" in text for where in breaks):
        return "a loop's break point"
    return None


def test_the_scan_finds_a_typed_copy(declared_loops):
    # the checks below would pass on a scan that finds nothing: they find these
    labels = {figure.label for figure in FIGURES.values()} - ALSO_VALUES
    symbols = {loop.symbol for loop in declared_loops}
    breaks = {loop.breaks_at for loop in declared_loops} | {loop.break_symbol
                                                             for loop in declared_loops}
    assert {"L_i", "L_v", "L_p"} <= symbols and {"V", "ω_cmd"} <= breaks
    for text in ("phase margin", "delay margin [ms]", "|L_p| [dB]", "L_v (broken at i_cmd)",
                 "position loop, broken at the velocity command"):
        assert copies(text, labels, symbols, breaks), text
    for text in ("L_pade", "phase margins of every loop", "stable", "ω_BW [rad/s]"):
        assert copies(text, labels, symbols, breaks) is None, text
    source = 'def f():\n    """The phase margin."""\n    return f"{x}: phase margin"\n'
    assert _literals(ast.parse(source)) == [(3, ": phase margin")]


def test_no_loop_or_figure_name_is_typed_outside_its_declaration(declared_loops):
    labels = {figure.label for figure in FIGURES.values()} - ALSO_VALUES
    symbols = {loop.symbol for loop in declared_loops}
    breaks = {loop.breaks_at for loop in declared_loops} | {loop.break_symbol
                                                             for loop in declared_loops}
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        name = path.relative_to(PACKAGE).as_posix()
        if name in DECLARATIONS:
            continue
        for line, text in _literals(ast.parse(path.read_text(encoding="utf-8"))):
            why = copies(text, labels, symbols, breaks)
            if why:
                found.append(f"{name}:{line}: {text!r} ({why})")
    assert not found, "names typed outside their declaration:\n" + "\n".join(found)
