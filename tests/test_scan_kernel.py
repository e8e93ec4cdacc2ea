"""The compiled grid scans against their numpy references, to the bit.

:func:`cas_freq.analysis.margins.first_turned_jumps`, ``magnitudes``, ``probes._long_chords`` and
:func:`cas_freq.analysis.closed_loop.first_fall_below_90` run their kernel
(:mod:`cas_freq.analysis.scan_kernel`) on large arrays and numpy below
:data:`cas_freq.core.jit.COMPILED_FROM`; ``CAS_FREQ_ENGINE=reference`` forces numpy. Both forms
make the same comparisons on the same values (turns by whole quarters are exact; the
magnitudes: the same operations in the same order), so the indices and values must be
equal. The responses: the loops of random variants of two actuators (many jumps and
crossings, on the analysis grid), spirals built to jump at known points, and rows with NaN,
with no event, and with an event at the first or the last interval.
"""

import numpy as np
import pytest

from cas_freq.analysis.closed_loop import first_fall_below_90
from cas_freq.analysis.frequency import (
    DEFAULT_POINTS_PER_DECADE,
    DEFAULT_RANGE_RAD_S,
    frequency_grid,
)
from cas_freq.analysis.margins import (
    continuous_phase_at,
    first_turned_jumps,
    magnitudes,
    quarter_turn,
)
from cas_freq.analysis.probes import LOG_SHARP, _log_corners, _long_chords, extremum_probes
from cas_freq.config import load_variant
from cas_freq.core.jit import use_compiled
from cas_freq.core.parameters import variant_parameters
from cas_freq.model.loops import Selector, responses


def _loops(config, variant, n=48, seed=0):
    loaded = load_variant(config, variant)
    rng = np.random.default_rng(seed)
    base = {"position_loop.Kp": loaded.params.position_loop.Kp,
            "position_loop.Kd": loaded.params.position_loop.Kd,
            "current_loop.Kp": loaded.params.current_loop.Kp}
    params = variant_parameters(loaded.params,
                                {k: v * rng.uniform(0.3, 3.0, n) for k, v in base.items()})
    omega = frequency_grid(*DEFAULT_RANGE_RAD_S, DEFAULT_POINTS_PER_DECADE, 0.001)
    grid = responses(Selector(params)(column=True), 1j * omega)
    return [np.broadcast_to(r, (n, omega.size)).copy()
            for r in (grid.current_loop, grid.position_loop, grid.closed_loop)]


def _synthetic(m=400):
    k = np.arange(m)
    rows = [
        np.exp(-1j * 0.02 * k) * (1 + k / m),           # a slow clockwise spiral: jumps at pi
        np.exp(1j * 0.05 * k),                          # anticlockwise: jumps the other way
        np.full(m, 1.0 + 0.5j),                         # nothing happens
        np.exp(-1j * (np.pi / 2 + 0.01 * k)),           # below -90 deg from the start
        np.where(k < 1, 1j, -1.0 - 1e-3j),              # event in the first interval
        np.where(k < m - 1, 1.0 + 0j, -1.0 - 1e-3j),    # event in the last interval
        np.where(k == 7, np.nan + 0j, np.exp(-1j * 0.03 * k)),  # a NaN on the way
    ]
    return np.array(rows)


def _arrays():
    arrays = _loops("configs/qt_cas.yaml", "base") + _loops("configs/dc_servo.yaml", "base")
    return arrays + [_synthetic()]


def _reference(monkeypatch, function, *args):
    monkeypatch.setenv("CAS_FREQ_ENGINE", "reference")
    return function(*args)


def _compiled(monkeypatch, function, *args):
    monkeypatch.setenv("CAS_FREQ_ENGINE", "compiled")
    monkeypatch.setattr("cas_freq.core.jit.COMPILED_FROM", 0)
    assert use_compiled(), "numba is needed: without it both sides would run numpy"
    return function(*args)


@pytest.mark.parametrize("index", range(7))
def test_first_turned_jumps_equal_numpy(monkeypatch, index):
    response = _arrays()[index]
    n, m = response.shape
    rng = np.random.default_rng(index)
    rows = np.unique(rng.integers(0, n, n))
    quarters = rng.integers(-5, 6, rows.size).astype(float)
    quarters[0] = np.nan  # a row whose low-frequency slope is not a number
    view = response[:, : m - 3]  # the analysis passes column slices of its grid
    for array, width in ((response, 2), (response, m // 3), (response, m), (view, m - 3)):
        expected = _reference(monkeypatch, first_turned_jumps, array, rows, quarters, width)
        got = _compiled(monkeypatch, first_turned_jumps, array, rows, quarters, width)
        np.testing.assert_array_equal(got, expected)
        if width == m:
            assert np.any(expected < width - 1), "no jump at all: the case tests nothing"


def test_quarter_turn_is_exact():
    rng = np.random.default_rng(1)
    values = rng.standard_normal(1000) + 1j * rng.standard_normal(1000)
    for quarters in range(-5, 6):
        exact = values * 1j ** (quarters % 4)  # a product by 1, -1, 1j or -1j is exact
        np.testing.assert_array_equal(quarter_turn(values, float(quarters)), exact)
    assert np.isnan(quarter_turn(values[:3], np.nan)).all()


def test_a_point_on_the_turned_axis_gives_the_same_phase_on_both_paths(monkeypatch):
    # A point whose turn by -1 (two quarters) lands exactly on the negative real axis: a
    # complex product by exp(1j pi) = (-1 + 1.2e-16j) puts it above or below the axis
    # depending on whether the CPU fuses the multiply (numpy's SIMD loops may, numba does
    # not), i.e. a phase of +180 or -180 deg. The exact quarter turn has no such freedom.
    point = 1.002002002002002 + 1.2270985444909916e-16j
    width = 70_000  # above COMPILED_FROM with one row
    row = np.empty((1, width), dtype=complex)
    row[0, 0] = np.exp(-1j * 0.1)
    row[0, 1] = point
    row[0, 2:] = np.exp(1j * 0.1)
    ratio = 1.01
    omega = ratio ** np.arange(width, dtype=float)
    row[0, 0] *= abs(point) * ratio ** 2  # slope -2 over the first interval: two quarters
    rows, columns = np.array([0, 0]), np.array([1, width - 1])
    monkeypatch.setenv("CAS_FREQ_ENGINE", "reference")
    expected = continuous_phase_at(row, omega, rows, columns)
    monkeypatch.setenv("CAS_FREQ_ENGINE", "compiled")
    assert use_compiled()
    got = continuous_phase_at(row, omega, rows, columns)
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("index", range(7))
def test_first_fall_below_90_agrees_with_numpy(monkeypatch, index):
    response = _arrays()[index]
    response = response[:, 1:]  # a column slice, as the analysis passes
    m = response.shape[1]
    crossing, jump = _reference(monkeypatch, first_fall_below_90, response)
    got_crossing, got_jump = _compiled(monkeypatch, first_fall_below_90, response)
    np.testing.assert_array_equal(got_crossing, crossing)
    # the kernel stops at the crossing: a later jump is m - 1 there; what the caller asks,
    # whether the jump comes after the crossing, is the same
    np.testing.assert_array_equal(got_jump <= got_crossing, jump <= crossing)
    before = jump <= crossing
    np.testing.assert_array_equal(got_jump[before], jump[before])
    assert np.all(got_jump[~before] == m - 1)


def test_the_synthetic_rows_have_their_events_where_built():
    response = _synthetic()
    m = response.shape[1]
    crossing, jump = first_fall_below_90(response)
    assert crossing[2] == m - 1 and jump[2] == m - 1  # nothing happens
    assert crossing[4] == 0 and crossing[5] == m - 2
    # the clockwise spiral falls below -90 deg after 0.02 k > pi/2 and jumps after pi
    assert crossing[0] == int(np.ceil(np.pi / 2 / 0.02)) - 1
    assert jump[0] == int(np.ceil(np.pi / 0.02)) - 1 > crossing[0]



@pytest.mark.parametrize("index", range(7))
def test_magnitudes_and_long_chords_equal_numpy_to_the_bit(monkeypatch, index):
    response = _arrays()[index][:, 2:]  # a column slice, as the analysis passes
    expected = _reference(monkeypatch, magnitudes, response)
    got = _compiled(monkeypatch, magnitudes, response)
    for a, b in zip(got, expected, strict=True):
        np.testing.assert_array_equal(a, b)
    rows, k = _reference(monkeypatch, _long_chords, response, expected[1])
    got_rows, got_k = _compiled(monkeypatch, _long_chords, response, expected[1])
    np.testing.assert_array_equal(got_rows, rows)
    np.testing.assert_array_equal(got_k, k)
    if index in (1, 2, 6):  # loops of the shipped actuator and spirals that pass near -1
        assert rows.size > 0


def _log_inputs(index):
    """A response of :func:`_arrays`, the analysis grid's first columns for it (log rad/s; not
    uniform: the delay's linear part merged in) and ln |L|^2 (-inf where L is 0)."""
    response = _arrays()[index]
    omega = frequency_grid(*DEFAULT_RANGE_RAD_S, DEFAULT_POINTS_PER_DECADE, 0.001)
    omega = omega[:response.shape[1]] if index == 6 else omega
    with np.errstate(divide="ignore"):
        log_squared = np.log(response.real ** 2 + response.imag ** 2)
    return np.log(omega), response, log_squared


@pytest.mark.parametrize("index", range(7))
def test_log_corners_equal_numpy(index):
    pytest.importorskip("numba")
    from cas_freq.analysis.scan_kernel import log_corners

    log_w, response, log_squared = _log_inputs(index)
    expected, expected_size = _log_corners(log_w, response, log_squared)
    corner = np.empty(expected.shape, dtype=bool)
    size = np.empty(expected.shape)
    log_corners(log_w, response, log_squared, LOG_SHARP, corner, size)
    np.testing.assert_array_equal(corner, expected)
    # the same arithmetic in the same order, but numpy's elementwise math takes the SIMD paths
    # of the CPU (on an AVX-512 machine, numpy 2.4's X86_V3/X86_V4/AVX512_ICL), which may round
    # the last bit differently from the C library the compiled loop calls: the sizes then
    # differ by ulps, amplified by the divided differences to ~1e-15 (1.5e-10 relative; 2500
    # of 194784 sizes there, 3 with those paths disabled); the corner flags, which the
    # analysis uses, are equal
    np.testing.assert_allclose(size, expected_size, rtol=1e-9, atol=1e-14)
    if index == 1:  # the shipped actuator's position loop: corners where the grid is coarse
        assert expected.any()


@pytest.mark.parametrize("index", [1, 4])
def test_extremum_probes_are_the_same_on_both_paths(monkeypatch, index):
    log_w, response, _ = _log_inputs(index)
    omega = np.exp(log_w)

    def evaluate(runs, w):  # a stand-in loop between the samples: the nearest sample's value
        return response[runs, np.clip(np.searchsorted(omega, w), 0, omega.size - 1)]

    expected = _reference(monkeypatch, extremum_probes, evaluate, omega, response)
    got = _compiled(monkeypatch, extremum_probes, evaluate, omega, response)
    np.testing.assert_array_equal(got.runs, expected.runs)
    np.testing.assert_array_equal(got.log_w, expected.log_w)
