"""The lead-lag filter (``type: leadlag``, docs/model.md "Filters": (1 + s/w_z)/(1 + s/w_p)).

Oracles, each derived here from docs/model.md:

- **In series.** A filter at ``current_command`` sits in the position loop's path of the
  PID-on-PI (and in the velocity loop's of the cascade), so the loop broken at its controller's
  output is the loop without it times F(jw), and the closed loop T = L/(1 + L) follows. Checked
  to 1e-12 relative: both sides are the same products, in another order.
- **Its phase.** (1 + jw/w_z)/(1 + jw/w_p) has its largest phase at the geometric mean
  sqrt(w_z w_p): arcsin((w_p - w_z)/(w_p + w_z)) (a lead for w_z < w_p; a lag, negative, for
  w_z > w_p); its gain goes from 1 at 0 to w_p/w_z. Read off the loop's ratio with and
  without the filter, to 1e-12.
- **The simulator** steps it as a first-order block: a small sine dwell follows the linear
  closed loop with the filter (0.02 dB, 0.2 deg: the tolerances of
  tests/test_simulation_architectures.py), and the filter moves T by far more than that.
- **The config**: it loads with its two numbers, is refused without one or with another kind's
  number, and its numbers are sweepable keys.
"""

import dataclasses
import math

import numpy as np
import pytest

from cas_freq.config.loader import load_variant, shipped_configs_dir
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.filters_config import Filter
from cas_freq.core.parameters import LoopParameters, variable_keys
from cas_freq.model.loops import Selector, responses

W = np.array([30.0, 300.0, 1000.0, 3000.0, 2.0e4])  # [rad/s]
LEAD = (400.0, 4000.0)  # (w_z, w_p) [rad/s]: +55 deg at 1265 rad/s
LAG = (8000.0, 4000.0)  # -19.5 deg at 5657 rad/s; the loop stays stable


def _qt_cas(filters=()):
    p = LoopParameters.from_config(load_variant().params)
    return dataclasses.replace(p, filters=tuple(filters))


def _cascade(filters=()):
    path = shipped_configs_dir() / "cascade_axis.yaml"
    p = LoopParameters.from_config(load_variant(path).params)
    return dataclasses.replace(p, filters=(*p.filters, *filters))


def _leadlag(zero, pole, at="current_command"):
    return Filter(at, "leadlag", zero=zero, pole=pole)


def _oracle(zero, pole, w):
    return (1.0 + 1j * w / zero) / (1.0 + 1j * w / pole)


def _loops(p, w=W):
    return responses(Selector(p)(), 1j * w)


@pytest.mark.parametrize("numbers", [LEAD, LAG], ids=["lead", "lag"])
@pytest.mark.parametrize(("build", "loop"), [(_qt_cas, "position_loop"),
                                             (_cascade, "velocity_loop")],
                         ids=["pid_on_pi", "cascade"])
def test_a_leadlag_at_the_current_command_multiplies_the_loop(build, loop, numbers):
    without, with_filter = _loops(build()), _loops(build([_leadlag(*numbers)]))
    expected = without.loops[loop] * _oracle(*numbers, W)
    np.testing.assert_allclose(with_filter.loops[loop], expected, rtol=1e-12)
    if loop == "position_loop":  # the outermost loop: T = L/(1 + L) (no other input)
        np.testing.assert_allclose(with_filter.closed_loop * (1.0 + expected),
                                   expected * without.closed_loop * (1 + without.loops[loop])
                                   / without.loops[loop], rtol=1e-10)


@pytest.mark.parametrize("numbers", [LEAD, LAG], ids=["lead", "lag"])
def test_the_largest_phase_is_at_the_geometric_mean(numbers):
    zero, pole = numbers
    w = np.array([1e-3, math.sqrt(zero * pole), 1e9])
    ratio = (_loops(_qt_cas([_leadlag(zero, pole)]), w).position_loop
             / _loops(_qt_cas(), w).position_loop)
    assert np.degrees(np.angle(ratio[1])) == pytest.approx(
        math.degrees(math.asin((pole - zero) / (pole + zero))), abs=1e-9)
    assert abs(ratio[0]) == pytest.approx(1.0, abs=1e-6)
    assert abs(ratio[2]) == pytest.approx(pole / zero, rel=1e-6)


@pytest.mark.parametrize("numbers", [LEAD, LAG], ids=["lead", "lag"])
def test_the_simulator_follows_the_linear_loop_with_the_filter(numbers):
    pytest.importorskip("numba")
    from cas_freq.simulation.sinedwell import linear_reference, sine_dwell

    p = _qt_cas([_leadlag(*numbers)])
    frequencies = np.array([300.0, 1500.0])
    small = math.radians(0.05)
    result = sine_dwell(p, [small], frequencies)
    linear = linear_reference(p, frequencies)
    assert not result.limit_hit.any()
    assert np.max(np.abs(20 * np.log10(np.abs(linear / linear_reference(_qt_cas(), frequencies)
                                              )))) > 0.5  # the filter matters
    np.testing.assert_allclose(result.magnitude_db[0], 20 * np.log10(np.abs(linear)), atol=0.02)
    np.testing.assert_allclose(result.phase_deg[0], np.degrees(np.unwrap(np.angle(linear))),
                               atol=0.2)


def _config_with(tmp_path, item):
    text = (shipped_configs_dir() / "qt_cas.yaml").read_text()
    path = tmp_path / "leadlag.yaml"
    path.write_text(text + f"\nfilters:\n  - {item}\n")
    return path


def test_the_config_takes_a_leadlag_and_its_numbers_are_keys(tmp_path):
    path = _config_with(tmp_path, "{at: current_command, type: leadlag, zero: 400 rad/s, "
                                  "pole: 4 krad/s}")
    loaded = load_variant(path)
    item = loaded.params.filters[0]
    assert (item.type, item.zero, item.pole) == ("leadlag", 400.0, 4000.0)
    p = LoopParameters.from_config(loaded.params)
    assert (p.filters[0].zero[0], p.filters[0].pole[0]) == (400.0, 4000.0)
    assert {"filters.0.zero", "filters.0.pole"} <= set(variable_keys(loaded.params))


@pytest.mark.parametrize(("item", "message"), [
    ("{at: current_command, type: leadlag, zero: 400 rad/s}", "needs pole"),
    ("{at: current_command, type: leadlag, zero: 400 rad/s, pole: 4000 rad/s, "
     "frequency: 10 rad/s}", "takes zero, pole, not frequency"),
    ("{at: current_command, type: leadlag, zero: -4 rad/s, pole: 4000 rad/s}", "zero"),
    ("{at: current_command, type: notch, frequency: 800 rad/s, width: 400 rad/s, "
     "depth: -20 dB, zero: 3 rad/s}", "not zero"),
])
def test_a_wrong_leadlag_is_refused_naming_the_number(tmp_path, item, message):
    with pytest.raises(ConfigError, match=message):
        load_variant(_config_with(tmp_path, item))
