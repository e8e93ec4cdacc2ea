"""The one walk over the loop table (cas_freq/model/table.py) in its two continuous algebras.

The walk runs the recurrence E_k = b_k f_k E_(k-1) + c_k once, with the arithmetic as a
parameter: complex values on a grid (Values, the frequency responses) or polynomial stacks
with Padé delays (Polynomials, the characteristic polynomials of the stability verdicts). With
the Padé delay D(-s tau)/D(s tau) the polynomial walk multiplies each loop's b_k by D(s tau_k),
so (induction over k) its E_k is the complex walk's E_k times prod_(j<=k) D(s tau_j), and each
polynomial term c_k/(beta_k E_(k-1)) is the complex walk's cascade view L_k. The two share the
walk but not the arithmetic (polymul/polyadd of coefficient columns against complex products
of values), so a wrong step in either algebra shows here.

Tolerance: the polynomials' coefficients span tens of decades (poles from ~10 rad/s to ~1e5
rad/s), so Horner's rule on them at a frequency loses digits the complex walk keeps; over
10..3e4 rad/s the two agree to 3e-14 at worst (measured on these cases), and 1e-11 relative
leaves ~400x room for that while a wrong term (a missing factor, a sign) moves them by orders
of magnitude more.
"""

import numpy as np
import pytest

from cas_freq.config import load_variant
from cas_freq.core.parameters import LoopParameters
from cas_freq.model import parts
from cas_freq.model.delay import DelayModel, pade_denominator
from cas_freq.model.loops import Selector
from cas_freq.model.structure import build
from cas_freq.model.table import Polynomials, Values, cascade, table, walk

ORDER = 4
OMEGA = np.logspace(1, 4.5, 40)
RELATIVE = 1e-11
CASES = [("configs/qt_cas.yaml", "base"), ("configs/qt_cas.yaml", "fin_encoder"),
         ("configs/qt_cas.yaml", "loaded"), ("configs/cascade_axis.yaml", "base")]


def _at(polynomial, s):
    """A polynomial of coefficient columns (one run) at ``s``."""
    return parts.polyval(tuple(float(c[0]) for c in polynomial), s)


@pytest.mark.parametrize(("config", "variant"), CASES)
def test_the_polynomial_walk_is_the_complex_walk_times_the_pade_denominators(config, variant):
    p = LoopParameters.from_config(load_variant(config, variant).params)
    rows = table(build(Selector(p)()))
    s = 1j * OMEGA
    values = walk(rows, Values(s, DelayModel(ORDER)))
    polynomials = walk(rows, Polynomials(1, ORDER))
    lag = 1.0
    for k, name in enumerate(rows.names):
        lag = lag * np.polyval(pade_denominator(ORDER), s * float(np.ravel(rows.rows[k].tau)[0]))
        expected = values.characteristic[name] * lag
        found = _at(polynomials.characteristic[name], s)
        assert np.max(np.abs(found / expected - 1.0)) < RELATIVE, name
    complex_views = cascade(values.steps)
    for step in polynomials.steps:
        view = _at(step.c, s) / (_at(step.beta, s) * _at(step.inner, s))
        assert np.max(np.abs(view / complex_views[step.name] - 1.0)) < RELATIVE, step.name


def test_the_table_carries_each_loops_names_and_nesting():
    # innermost first, as the structure declares them, with the symbol and the break point
    p = LoopParameters.from_config(load_variant("configs/cascade_axis.yaml", "base").params)
    structure = build(Selector(p)())
    rows = table(structure)
    assert rows.names == ("current_loop", "velocity_loop", "position_loop")
    assert [row.symbol for row in rows.rows] == [loop.symbol for loop in structure.loops]
    assert [row.breaks_at for row in rows.rows] == [loop.breaks_at for loop in structure.loops]
    # the command enters the outermost controller only (without the feed-forward)
    assert [row.reference is not None for row in rows.rows] == [False, False, True]
    assert [row.reference is not None for row in table(structure, True).rows] == [
        False, True, True]
