"""The filter kinds, declared once (cas_freq/core/filters_config.py, FILTERS).

Every reader of a filter's kind takes it from the registry: the config's numbers
(FILTER_NUMBERS, FILTER_TYPES), their records (FILTER_PARAMETERS, unit and bounds), their
per-run fields (Filter) and the loop structure's block (filter_block). The transfer functions
are checked against docs/model.md's formulas ("Filters"), written out here at one frequency.
"""

import types

import numpy as np
import pytest

from cas_freq.core.filters_config import (
    FILTER_NUMBERS,
    FILTER_PARAMETERS,
    FILTER_TYPES,
    FILTERS,
    Filter,
    number_field,
)
from cas_freq.model import parts
from cas_freq.model.structure import filter_block

W0, ZETA, WIDTH, DEPTH_DB = 300.0, 0.4, 120.0, -20.0
ZERO, POLE = 150.0, 900.0  # a lead-lag's [rad/s]


def _item(kind):
    return types.SimpleNamespace(kind=kind, frequency=W0, damping=ZETA, width=WIDTH,
                                 depth_db=DEPTH_DB, zero=ZERO, pole=POLE)


def _docs_formula(kind, s):
    """docs/model.md, "Filters": the kinds in the form written there."""
    if kind == "leadlag":
        return (1.0 + s / ZERO) / (1.0 + s / POLE)
    if kind == "lowpass1":
        return 1.0 / (s / W0 + 1.0)
    if kind == "lowpass2":
        return W0**2 / (s * s + 2.0 * ZETA * W0 * s + W0**2)
    zeta = WIDTH / (2.0 * W0)
    d = 10.0 ** (DEPTH_DB / 20.0)
    return (s * s + 2.0 * d * zeta * W0 * s + W0**2) / (s * s + 2.0 * zeta * W0 * s + W0**2)


def test_the_config_names_derive_from_the_registry():
    assert FILTER_TYPES == tuple(FILTERS)
    assert FILTER_NUMBERS == {name: kind.numbers for name, kind in FILTERS.items()}
    for kind in FILTERS.values():
        for number in kind.numbers:
            assert number in FILTER_PARAMETERS  # a record: unit, bounds, meaning
            assert number_field(number) in Filter.NUMBERS  # a per-run field


@pytest.mark.parametrize("kind", list(FILTERS))
def test_the_structure_s_block_is_the_registry_s_transfer_function(kind):
    block = filter_block(_item(kind))
    assert block.name == FILTERS[kind].label
    s = 1j * np.array([0.0, 30.0, 300.0, 3000.0])
    value = parts.polyval(block.numerator, s) / parts.polyval(block.denominator, s)
    np.testing.assert_allclose(value, _docs_formula(kind, s), rtol=1e-13)
    assert value[0] == pytest.approx(1.0)


def test_a_filter_keeps_only_its_kind_s_numbers():
    lowpass = Filter("current_command", "lowpass2", frequency=W0, damping=ZETA, width=WIDTH)
    assert np.isnan(lowpass.width).all() and lowpass.damping[0] == ZETA
    notch = Filter("current_command", "notch", frequency=W0, width=WIDTH, depth_db=DEPTH_DB)
    assert np.isnan(notch.damping).all() and notch.depth_db[0] == DEPTH_DB
