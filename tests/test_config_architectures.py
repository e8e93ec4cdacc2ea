"""Config keys of the drive architectures (docs/config.md): the
velocity loop (a cascade), the filters and the output-side position feedback, as far as the
config and LoopParameters carry them, and that analyze and simulate run them.

The tests load the configs with the loader's internal ``validate`` and check the values against
the SI conversion worked out by hand in each test.
"""

import dataclasses
import math

import numpy as np
import pytest
import yaml
from architectures import as_cascade
from clirun import run_cli

from cas_freq.config import load_all_variants, load_variant
from cas_freq.config.loader import _apply, validate
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.filters_config import Filter
from cas_freq.core.parameters import (
    STATIC_FIELDS,
    LoopParameters,
    base_values,
    check_key,
    loop_values,
    parse_value,
    unit_of,
    variable_keys,
    variant_parameters,
)

# --- the shipped configs are unchanged ------------------------------------------------------------

#: LoopParameters of every shipped variant as the code before the architectures gave them
#: (commit 44986e5, printed with ``float(getattr(p, field)[0])``), in this field order.
_FIELDS = ("R", "L", "Km", "Ke", "J", "mu_v", "ratio", "ci_Kp", "ci_Ki", "v_max", "tau_c",
           "cp_Kp", "cp_Ki", "cp_Kd", "Tf", "ff_v", "ff_a", "i_max", "tau_p",
           "derivative_on_measurement", "F_c", "eta", "eta_b", "K_g", "c_g", "backlash", "J_L",
           "b_L", "K_h", "tau_h")
_BEFORE = {
    ("qt_cas", "base"): (
        0.361, 7.099999999999999e-05, 0.0105, 0.0105, 5.54e-07, 1.3410024468859454e-06, 20.0,
        0.6163, 2835.3, 30.0, 6e-05, 6.3435, 70.2619, 0.0381, 0.0006006148025537953, 0.0096,
        0.00012, 20.0, 0.0004, False, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    ("qt_cas", "fitted"): (
        0.361, 7.099999999999999e-05, 0.0075, 0.0105, 7.19e-07, 1.2e-06, 20.0, 0.6163, 2835.3,
        30.0, 6e-05, 6.3435, 70.2619, 0.0381, 0.0006006148025537953, 0.0096, 0.00012, 20.0,
        0.0004, False, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    ("qt_cas", "relaxed"): (
        0.361, 7.099999999999999e-05, 0.0105, 0.0105, 5.54e-07, 1.3410024468859454e-06, 20.0,
        0.6163, 2835.3, 30.0, 6e-05, 3.8061, 42.1571, 0.02286, 0.0006006148025537952, 0.0096,
        0.00012, 20.0, 0.0004, False, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    ("qt_cas", "loaded"): (
        0.361, 7.099999999999999e-05, 0.0075, 0.0105, 5.54e-07, 1.2e-06, 20.0, 0.6163, 2835.3,
        30.0, 6e-05, 6.3435, 70.2619, 0.0381, 0.0006006148025537953, 0.0096, 0.00012, 20.0,
        0.0004, False, 0.001, 0.7, 0.0, 3000.0, 0.03, 0.0, 4.62e-05, 0.0, 2.0, 0.1),
    ("dc_servo", "base"): (
        2.5, 0.0012, 0.05, 0.05, 2e-05, 2e-06, 50.0, 3.6, 7500.0, 24.0, 5e-05, 6.0, 30.0, 0.08,
        0.0013333333333333333, 0.0, 0.0, 5.0, 0.0002, False, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0),
}


@pytest.mark.parametrize("name", ["qt_cas", "dc_servo"])
def test_shipped_configs_load_to_the_same_loop_parameters(name, shipped_dir):
    # (the variants that existed at 44986e5; fin_encoder and sampled are new)
    loaded = [v for v in load_all_variants(shipped_dir / f"{name}.yaml")
              if v.variant not in ("fin_encoder", "sampled")]
    assert {(name, v.variant) for v in loaded} == {k for k in _BEFORE if k[0] == name}
    for variant in loaded:
        for build in (LoopParameters.from_config, lambda p: variant_parameters(p, {})):
            params = build(variant.params)
            got = tuple(getattr(params, field)[0] for field in _FIELDS)
            assert got == _BEFORE[(name, variant.variant)], variant.variant  # bit for bit
            # the new fields at "absent": no velocity loop, motor feedback, no filters
            assert (params.cv_Kp, params.cv_Ki, params.tau_v, params.tau_vf) == (0, 0, 0, 0)
            assert params.omega_max[0] == math.inf
            assert params.cascade is False and params.feedback_output is False
            assert params.filters == ()


@pytest.fixture
def shipped_dir():
    from cas_freq.config.loader import shipped_configs_dir

    return shipped_configs_dir()


# --- the cascade ----------------------------------------------------------------------------------


def _cascade(shipped_raw, **position):
    raw = as_cascade(shipped_raw)
    raw["position_loop"].update(position)
    return raw


def test_cascade_loads_into_loop_parameters(shipped_raw):
    raw = _cascade(shipped_raw, Kp="30 s^-1", Ki="5 rad/s^2/rad", ff_v=0.9,
                   omega_max="3000 rpm")
    raw["velocity_loop"].update(Kp="0.02 A*s/rad", Ki=1.5, i_max="12 A", delay="0.1 ms",
                                feedback_filter="0.2 ms", ff_a=1e-4)
    config = validate(raw, "test")
    params = LoopParameters.from_config(config)
    assert params.cascade is True and params.feedback_output is False
    # position controller in 1/s, 1/s^2, [-]
    assert (params.cp_Kp[0], params.cp_Ki[0], params.ff_v[0]) == (30.0, 5.0, 0.9)
    assert params.cp_Kd[0] == 0 and params.Tf[0] == 0  # P or PI: no derivative
    assert params.omega_max[0] == pytest.approx(3000 * 2 * math.pi / 60, rel=1e-15)
    # the velocity loop: i_max and ff_a fill the PID-on-PI's fields
    assert (params.cv_Kp[0], params.cv_Ki[0]) == (0.02, 1.5)
    assert params.i_max[0] == 12.0 and params.ff_a[0] == 1e-4
    assert params.tau_v[0] == pytest.approx(1e-4) and params.tau_vf[0] == pytest.approx(2e-4)
    assert not params.derivative_on_measurement[0]
    # the batch builder gives the same
    again = variant_parameters(config, {})
    for field in dataclasses.fields(params):
        if field.name not in STATIC_FIELDS:
            assert np.array_equal(getattr(again, field.name), getattr(params, field.name))


def test_velocity_loop_defaults(shipped_raw):
    params = LoopParameters.from_config(validate(_cascade(shipped_raw), "test"))
    # as_cascade gives Kp, Ki, i_max and delay; the feedback filter and ff_a default to none,
    # position Ki and ff_v are given, omega_max defaults to no limit
    assert params.tau_vf[0] == 0 and params.ff_a[0] == 0 and params.omega_max[0] == math.inf


@pytest.mark.parametrize(("key", "value", "why"), [
    ("Kd", 0.01, "not used with a velocity loop (the position controller is P or PI)"),
    ("Tf", "0.6 ms", "not used with a velocity loop (the position controller is P or PI)"),
    ("derivative_on", "measurement",
     "not used with a velocity loop (the position controller is P or PI)"),
    ("i_max", "20 A",
     "not used with a velocity loop: the current command's limit is velocity_loop.i_max"),
    ("ff_a", 1e-4,
     "not used with a velocity loop: the acceleration feed-forward is velocity_loop.ff_a"),
])
def test_cascade_refuses_the_pid_keys(shipped_raw, key, value, why):
    with pytest.raises(ConfigError) as info:
        validate(_cascade(shipped_raw, **{key: value}), "test")
    assert str(info.value) == f"test: position_loop.{key}: {why}"


def test_cascade_position_gain_in_the_pid_unit_is_refused_with_a_hint(shipped_raw):
    with pytest.raises(ConfigError) as info:
        validate(_cascade(shipped_raw, Kp="30 A/rad"), "test")
    text = str(info.value)
    assert text.startswith("test: position_loop.Kp: cannot read '30 A/rad' as a value in 1/s")
    assert ("with a velocity_loop the position controller's output is a velocity command: "
            "position_loop.Kp is in 1/s (e.g. '30 s^-1')") in text
    # parse_value (sweep --set, montecarlo) reads the same unit given the cascade config
    config = validate(_cascade(shipped_raw), "test2")
    assert unit_of("position_loop.Kp", config) == "1/s"
    assert unit_of("position_loop.Kp") == "A/rad"
    assert parse_value("position_loop.Kp", "30 s^-1", config) == 30.0
    with pytest.raises(ConfigError, match="position_loop.Kp: cannot read '30 A/rad'"):
        parse_value("position_loop.Kp", "30 A/rad", config)


def test_cascade_needs_some_position_and_velocity_gain(shipped_raw):
    with pytest.raises(ConfigError, match="position_loop: Kp and Ki are both 0: no position"):
        validate(_cascade(shipped_raw, Kp=0, Ki=0), "test")
    raw = _cascade(shipped_raw)
    raw["velocity_loop"].update(Kp=0, Ki=0)
    with pytest.raises(ConfigError, match="velocity_loop: Kp and Ki are both 0: no velocity"):
        validate(raw, "test")


def test_omega_max_without_a_velocity_loop_is_refused(shipped_raw):
    shipped_raw["position_loop"]["omega_max"] = "3000 rpm"
    with pytest.raises(ConfigError) as info:
        validate(shipped_raw, "test")
    assert str(info.value) == (
        "test: position_loop.omega_max: clamps the velocity command of a velocity loop, and the "
        "config has no velocity_loop section")


# --- position feedback ----------------------------------------------------------------------------


def test_position_feedback_from_the_output(shipped_raw):
    shipped_raw["position_loop"]["feedback"] = "output"
    config = validate(shipped_raw, "test")
    assert LoopParameters.from_config(config).feedback_output is True
    shipped_raw["position_loop"]["feedback"] = "encoder"
    with pytest.raises(ConfigError) as info:
        validate(shipped_raw, "test")
    assert str(info.value) == "test: position_loop.feedback: must be motor or output, got 'encoder'"


# --- filters --------------------------------------------------------------------------------------

_NOTCH = {"at": "current_command", "type": "notch", "frequency": "900 rad/s",
          "width": 300, "depth": "-20 dB"}


def test_filters_load_into_filter_records(shipped_raw):
    raw = as_cascade(shipped_raw)
    raw["filters"] = [_NOTCH,
                      {"at": "velocity_feedback", "type": "lowpass2", "frequency": 5000},
                      {"at": "current_command", "type": "lowpass1", "frequency": "2000 rpm"}]
    config = validate(raw, "test")
    notch, second, first = LoopParameters.from_config(config).filters
    assert (notch.at, notch.kind) == ("current_command", "notch")
    assert (notch.frequency[0], notch.width[0], notch.depth_db[0]) == (900.0, 300.0, -20.0)
    assert np.isnan(notch.damping[0])
    assert notch.notch_damping[0] == 300.0 / (2 * 900.0)  # zeta = width / (2 w0)
    assert (second.at, second.kind, second.damping[0]) == ("velocity_feedback", "lowpass2",
                                                           0.7071)  # the default damping
    assert np.isnan(second.width[0]) and np.isnan(second.depth_db[0])
    # a frequency in rpm is an angular rate: 2000 rev/min = 2000*2*pi/60 rad/s
    assert first.frequency[0] == pytest.approx(2000 * 2 * math.pi / 60, rel=1e-15)
    assert variable_keys(config)[-6:] == (
        "filters.0.frequency", "filters.0.width", "filters.0.depth", "filters.1.frequency",
        "filters.1.damping", "filters.2.frequency")
    assert base_values(config)["filters.0.depth"] == -20.0


def as_pid(raw):
    """``raw`` with a PID position loop again (after as_cascade)."""
    raw["position_loop"].update(Kp=6.3, Ki=70.0, Kd=0.038, i_max=20.0)
    raw["position_loop"].pop("ff_v")
    return validate(raw, "test")


@pytest.mark.parametrize(("item", "expected"), [
    ({**_NOTCH, "at": "velocity"},
     "filters.0.at: 'velocity' is not a filter point; use current_command, "
     "velocity_command, velocity_feedback, current_feedback, position_feedback or "
     "position_command"),
    ({**_NOTCH, "at": "velocity_feedback"},
     "filters.0.at: velocity_feedback needs a velocity loop (a velocity_loop section); use "
     "current_command"),
    ({**_NOTCH, "depth": 0}, "filters.0.depth: a notch's depth is below 0 dB, got 0 dB"),
    ({**_NOTCH, "depth": "3 dB"}, "filters.0.depth: a notch's depth is below 0 dB, got 3 dB"),
    ({**_NOTCH, "type": "bandpass"},
     "filters.0.type: 'bandpass' is not a filter type; use lowpass1, lowpass2, notch or "
     "leadlag"),
    ({"at": "current_command", "type": "lowpass1"}, "filters.0: a lowpass1 filter needs frequency"),
    ({**_NOTCH, "q": 3}, "filters.0.q: unknown key (value 3); filters.0 accepts at, type, "
                         "frequency, damping, width, depth"),
    ({**_NOTCH, "type": "lowpass1"},
     "filters.0: a lowpass1 filter takes frequency, not width, depth"),
    ({"at": "current_command", "type": "notch", "frequency": 900},
     "filters.0: a notch filter needs width and depth"),
    ({**_NOTCH, "frequency": "150 Hz"},
     "filters.0.frequency: cannot read '150 Hz' as a value in rad/s: Hz is a rate per time"),
])
def test_filter_errors_name_the_key_value_and_what_is_accepted(shipped_raw, item, expected):
    shipped_raw["filters"] = [item]
    with pytest.raises(ConfigError) as info:
        validate(shipped_raw, "test")
    assert str(info.value).startswith(f"test: {expected}")


# --- the CLI ------------------------------------------------------------------------------------


@pytest.mark.parametrize("change", [
    as_cascade,
    lambda raw: raw.update(filters=[_NOTCH]),
    lambda raw: raw["position_loop"].update(feedback="output"),
], ids=["cascade", "notch", "output_feedback"])
def test_every_architecture_analyzes_and_simulates(shipped_raw, tmp_path, change):
    # the simulator refused these before it simulated them (exit 2, "not in this version
    # yet"); now a small step runs and follows the command (its figures against the linear
    # loop: tests/test_simulation_architectures.py)
    change(shipped_raw)
    path = tmp_path / "drive.yaml"
    path.write_text(yaml.safe_dump(shipped_raw))
    load_variant(path)
    assert run_cli(["analyze", str(path)])[0] == 0
    code, out, err = run_cli(["simulate", str(path), "--step", "1deg"])
    assert code == 0, err
    assert "not in this version" not in out + err


# --- batches --------------------------------------------------------------------------------------


def _filtered_cascade(shipped_raw):
    raw = as_cascade(shipped_raw)
    raw["filters"] = [_NOTCH, {"at": "velocity_feedback", "type": "lowpass1", "frequency": 5000}]
    return validate(raw, "test")


def test_variant_parameters_carry_the_velocity_loop_and_the_filters(shipped_raw):
    config = _filtered_cascade(shipped_raw)
    batch = variant_parameters(config, {"velocity_loop.Kp": [0.01, 0.02, 0.03],
                                        "filters.0.frequency": [800, 900, 1000],
                                        "filters.0.depth": -30.0,
                                        "position_loop.omega_max": 400.0})
    assert batch.n_runs == 3 and batch.cascade is True
    assert batch.cv_Kp.tolist() == [0.01, 0.02, 0.03] and batch.cv_Ki.tolist() == [1.0] * 3
    notch, lowpass = batch.filters
    assert notch.frequency.tolist() == [800, 900, 1000] and notch.depth_db.tolist() == [-30] * 3
    assert notch.width.tolist() == [300] * 3 and lowpass.frequency.tolist() == [5000] * 3
    assert batch.omega_max.tolist() == [400.0] * 3
    assert loop_values(batch, "filters.0.frequency", config).tolist() == [800, 900, 1000]
    assert loop_values(batch, "velocity_loop.i_max", config).tolist() == [20.0] * 3
    # take and replace keep the structure and take the filters' runs
    two = batch.take([2, 0])
    assert two.cascade is True and two.filters[0].frequency.tolist() == [1000, 800]
    assert two.cv_Kp.tolist() == [0.03, 0.01]
    changed = batch.replace(tau_vf=2e-4)
    assert changed.tau_vf.tolist() == [2e-4] * 3 and changed.filters[0].n_runs == 3


@pytest.mark.parametrize(("key", "expected"), [
    ("position_loop.Kd",
     "position_loop.Kd: not used with a velocity loop (the position controller is P or PI)"),
    ("filters.2.frequency", "filters.2.frequency: the config has 2 filter(s) (filters.0 to "
                            "filters.1)"),
    ("filters.1.width", "filters.1.width: a lowpass1 filter has no width; it takes frequency"),
    ("filters.0.depth", "filters.0.depth: a notch's depth is below 0 dB, got 0 dB"),
    ("velocity_loop.Kp", "velocity_loop.Kp: must be 0 or within 1e-09..1e+09 A*s/rad, got -1.0"),
])
def test_variant_parameters_refuse_keys_and_values_the_cascade_does_not_take(shipped_raw, key,
                                                                            expected):
    config = _filtered_cascade(shipped_raw)
    value = {"filters.0.depth": 0.0, "velocity_loop.Kp": -1.0}.get(key, 1.0)
    with pytest.raises(ConfigError) as info:
        variant_parameters(config, {key: [value]})
    assert str(info.value).startswith(expected)


def test_velocity_loop_keys_are_refused_without_a_velocity_loop():
    config = load_variant().params
    for key in ("velocity_loop.Kp", "position_loop.omega_max"):
        with pytest.raises(ConfigError, match=f"{key}: .*the config has no velocity_loop"):
            variant_parameters(config, {key: [1.0]})
        assert key not in variable_keys(config)
    with pytest.raises(ConfigError, match="filters.0.frequency: the config has no filters"):
        check_key("filters.0.frequency", config)


def test_one_batch_has_one_structure(shipped_raw):
    pid = load_variant().params
    cascade = validate(as_cascade(shipped_raw), "test")
    with pytest.raises(ConfigError, match="must share their loop structure"):
        LoopParameters.from_configs([pid, cascade])
    both = LoopParameters.from_configs([cascade, cascade])
    assert both.n_runs == 2 and both.cascade is True
    with pytest.raises(ConfigError, match="cp_Kd: must be 0 in a cascade"):
        both.replace(cp_Kd=0.01, Tf=1e-3)
    with pytest.raises(ConfigError, match="velocity_feedback filter needs a velocity loop"):
        LoopParameters.from_config(pid).replace(
            filters=(Filter("velocity_feedback", "lowpass1", 100.0),))


def test_set_and_variants_reach_a_filter_number(shipped_raw):
    raw = as_cascade(shipped_raw)
    raw["filters"] = [dict(_NOTCH)]
    _apply(raw, "filters.0.frequency", "1000 rad/s", "--set")
    assert validate(raw, "test").filters[0].frequency == 1000.0
    with pytest.raises(ConfigError, match="filters has 1 item"):
        _apply(raw, "filters.3.frequency", 1.0, "--set")


def test_sweep_tolerance_and_tune_read_the_cascade_units(shipped_raw):
    from cas_freq.core.parameter_keys import parse_grid_values
    from cas_freq.core.tolerances import parse_tolerance
    from cas_freq.tuning.space import parse_bounds, parse_free, tune_keys

    config = _filtered_cascade(shipped_raw)
    grid = parse_grid_values("position_loop.Kp", "10 s^-1:30 s^-1:3", config)
    assert grid.tolist() == [10.0, 20.0, 30.0]
    with pytest.raises(ConfigError, match="in 1/s"):
        parse_grid_values("position_loop.Kp", "10 A/rad:30 A/rad:3", config)
    assert parse_grid_values("filters.0.frequency", "800,1000", config).tolist() == [800, 1000]
    assert parse_tolerance("position_loop.Kp=2 s^-1", config).absolute == 2.0
    with pytest.raises(ConfigError, match="position_loop.Kd: not used with a velocity loop"):
        parse_tolerance("position_loop.Kd=10%", config)
    free = parse_free("velocity_loop.Kp,filters.0.frequency", config)
    keys = tune_keys(config, free, parse_bounds(["filters.0.frequency=500:1500"], free, config))
    assert [(k.key, k.start, k.unit) for k in keys] == [
        ("velocity_loop.Kp", 0.02, "A*s/rad"), ("filters.0.frequency", 900.0, "rad/s")]


def test_an_unknown_key_lists_what_the_architecture_accepts(shipped_raw):
    shipped_raw["position_loop"]["bogus"] = 1
    with pytest.raises(ConfigError) as info:
        validate(shipped_raw, "test")
    assert str(info.value) == (
        "test: position_loop.bogus: unknown key (value 1); position_loop accepts Kp, Ki, Kd, "
        "Tf, ff_v, ff_a, i_max, delay, derivative_on, derivative_window, feedback")
    raw = as_cascade(shipped_raw)
    with pytest.raises(ConfigError) as info:
        validate(raw, "test")
    assert str(info.value) == (
        "test: position_loop.bogus: unknown key (value 1); position_loop accepts Kp, Ki, ff_v, "
        "omega_max, delay, feedback")


def test_tune_frees_the_cascade_gains_by_default(shipped_raw):
    from cas_freq.tuning.space import default_free, parse_free

    assert default_free(load_variant().params) == (
        "position_loop.Kp", "position_loop.Ki", "position_loop.Kd")
    config = validate(as_cascade(shipped_raw), "test")
    assert default_free(config) == ("position_loop.Kp", "velocity_loop.Kp", "velocity_loop.Ki")
    assert parse_free(",".join(default_free(config)), config) == default_free(config)


def test_fit_params_refuse_a_velocity_loop_key_without_a_velocity_loop():
    from cas_freq.identification.free_keys import free_keys, parse_model_spec

    config = load_variant().params
    spec = parse_model_spec("velocity_loop.Kp", 1)
    with pytest.raises(ConfigError, match="--params: velocity_loop.Kp: the config has no "
                                          "velocity_loop section"):
        free_keys(spec, variant_parameters(config, {}), "base", config)


def test_a_dumped_config_validates_again(shipped_raw):
    # model_dump writes every field, the absent ones as null (velocity_loop, omega_max, a
    # cascade's Kd): they read as absent, so the dump is the same config
    shipped_raw["requirements"] = []  # their steps would need a unit again
    config = _filtered_cascade(shipped_raw)
    data = config.model_dump()
    assert data["position_loop"]["Kd"] is None and data["filters"][0]["damping"] is None
    data["motor"]["no_load"]["speed"] = f"{data['motor']['no_load']['speed']!r} rad/s"
    assert validate(data, "test") == config
    data = load_variant().params.model_dump(exclude={"load_envelope", "variants"})
    assert data["velocity_loop"] is None and data["position_loop"]["omega_max"] is None
    data["motor"]["no_load"]["speed"] = f"{data['motor']['no_load']['speed']!r} rad/s"
    data["requirements"] = []
    assert LoopParameters.from_config(validate(data, "test")).cascade is False
