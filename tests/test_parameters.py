"""The parameter table (cas_freq.core.parameters): one declaration of every numeric parameter.

The table must cover every numeric field of the config schema and of LoopParameters; every
bound must be enforced identically by the schema, by :func:`parse_value` (sweep, Monte Carlo)
and by :func:`variant_parameters`; and the derived rules (Tf, mu_v) must give the same numbers
through the schema's properties and through :func:`variant_parameters`.
"""

import copy
import dataclasses
import math
import types
import typing

import numpy as np
import pytest
from architectures import as_cascade
from pydantic import BaseModel
from pydantic.fields import FieldInfo

from cas_freq.config import ActuatorConfig, load_variant
from cas_freq.config.loader import validate
from cas_freq.config.schema import CascadePositionLoop, LinearGear, LinearLoad
from cas_freq.core.exceptions import ConfigError, ConfigTypeError
from cas_freq.core.parameters import (
    CASCADE_ONLY,
    CASCADE_PARAMETERS,
    LINEAR_ONLY,
    PARAMETERS,
    STATIC_FIELDS,
    VARIABLE_KEYS,
    LoopParameters,
    base_values,
    check_key,
    filter_time_constant,
    parse_value,
    unit_of,
    variant_parameters,
    viscous_friction,
)


def _numeric_schema_fields(model, prefix=""):
    """Dotted key -> FieldInfo declaring each float field of ``model``, recursively.

    An optional field (``param(key) | None``) keeps its declaration inside the union's
    ``Annotated`` member; a required one has it merged into the field itself.
    """
    found = {}
    for name, info in model.model_fields.items():
        members = typing.get_args(info.annotation) if typing.get_origin(info.annotation) in (
            typing.Union, types.UnionType) else (info.annotation,)
        sub = next((m for m in members if isinstance(m, type) and issubclass(m, BaseModel)),
                   None)
        if sub is not None:
            found.update(_numeric_schema_fields(sub, f"{prefix}{name}."))
            continue
        for member in members:
            if member is float:
                found[f"{prefix}{name}"] = info
            elif (typing.get_origin(member) is typing.Annotated
                  and typing.get_args(member)[0] is float):
                declared = [m for m in member.__metadata__ if isinstance(m, FieldInfo)]
                found[f"{prefix}{name}"] = declared[0] if declared else info
    return found


def _set(data, dotted, value):
    *sections, leaf = dotted.split(".")
    for section in sections:
        data = data.setdefault(section, {})
    data[leaf] = value


def _outside(parameter):
    """A value just outside the parameter's accepted range."""
    if parameter.lower is None:
        return math.nan
    if parameter.strict:
        return float(parameter.lower)
    return float(np.nextafter(parameter.lower, -np.inf))


def _inside(parameter, base):
    return base if base is not None else 1.0


# --- the table covers both the schema and LoopParameters -----------------------------------------


def test_table_covers_every_numeric_schema_field():
    from cas_freq.config.descriptions import DERIVING_PARAMETERS
    from cas_freq.config.schema import REFERENCE_PARAMETERS

    # the reference: section (comparison data, not model parameters) has its own table of the
    # same Parameter rows
    # the worm's geometry and the simulant's are static descriptions the config derives
    # gear.efficiency and load.inertia from, declared in the same rows (DERIVING_PARAMETERS)
    table = {**PARAMETERS, **REFERENCE_PARAMETERS, **DERIVING_PARAMETERS}
    fields = _numeric_schema_fields(ActuatorConfig)
    # the load envelope's step is a test condition (a fin angle checked as a requirement's
    # step is), not a parameter of the actuator
    fields.pop("load_envelope.step")
    # a cascade's position loop (with a velocity_loop: section) is a model of its own; its
    # Kp, Ki and ff_v are declared from CASCADE_PARAMETERS' rows (another unit)
    cascade = _numeric_schema_fields(CascadePositionLoop, "position_loop.")
    assert set(CASCADE_PARAMETERS) <= set(cascade)
    fields.update({key: info for key, info in cascade.items() if key not in CASCADE_PARAMETERS})
    # a linear output (gear.screw_lead) has gear and load sections of its own; the keys whose
    # unit changes are declared from LINEAR_PARAMETERS' rows
    from cas_freq.core.parameters import LINEAR_PARAMETERS

    linear = {**_numeric_schema_fields(LinearGear, "gear."),
              **_numeric_schema_fields(LinearLoad, "load.")}
    assert set(LINEAR_PARAMETERS) <= set(linear)
    fields.update({key: info for key, info in linear.items()
                   if key not in LINEAR_PARAMETERS and key not in fields})
    assert set(fields) == set(table)
    for key, info in [*fields.items(), *((k, cascade[k]) for k in CASCADE_PARAMETERS),
                      *((k, linear[k]) for k in LINEAR_PARAMETERS)]:
        row = (CASCADE_PARAMETERS if info is cascade.get(key) and key in CASCADE_PARAMETERS
               else LINEAR_PARAMETERS if info is linear.get(key) and key in LINEAR_PARAMETERS
               else table)[key]
        # each field is declared from its own row (param(key)), not from a neighbour's
        assert info.json_schema_extra == {"key": key, "unit": row.unit}, key
        assert info.description == row.meaning, key


def test_table_covers_every_float_field_of_loop_parameters():
    floats = ({f.name for f in dataclasses.fields(LoopParameters)}
              - {"derivative_on_measurement", *STATIC_FIELDS})
    # a cascade's velocity_loop.i_max and velocity_loop.ff_a fill the fields of
    # position_loop.i_max and position_loop.ff_a: each field once, where it first appears
    mapped = list(dict.fromkeys(p.field for p in PARAMETERS.values() if p.field is not None))
    assert sorted(mapped) == sorted(floats)
    assert {p.field for p in CASCADE_PARAMETERS.values()} <= floats
    # in the dataclass's order, so the table reads like the dataclass
    order = [f.name for f in dataclasses.fields(LoopParameters) if f.name in floats]
    assert mapped == order


def test_every_row_is_well_formed():
    for key, parameter in PARAMETERS.items():
        assert parameter.key == key
        assert parameter.meaning.endswith(f"[{parameter.unit}]"), key
        assert unit_of(key) == parameter.unit
    # the loop-parameter keys can be varied, the sample rates (static: one per batch) and the
    # sensors' resolution (read by analyze only) and the supply of the rate and torque envelope
    # (not loop parameters) cannot
    assert set(VARIABLE_KEYS) == {k for k in PARAMETERS if not k.startswith(
        ("simulation.", "sampling.", "sensors.", "supply."))}
    with pytest.raises(ConfigError, match="supply.voltage: cannot be varied"):
        check_key("supply.voltage")
    with pytest.raises(ConfigError, match="simulation.current_loop_rate: cannot be varied"):
        check_key("simulation.current_loop_rate")
    with pytest.raises(ConfigError, match="sampling.position_loop: cannot be varied"):
        check_key("sampling.position_loop")


def test_base_values_reads_every_variable_key():
    params = load_variant().params
    values = base_values(params)
    assert list(values) == list(VARIABLE_KEYS)
    assert values["position_loop.Kp"] == params.position_loop.Kp
    assert values["motor.no_load.speed"] == params.motor.no_load.speed
    assert values["motor.mu_v"] is None and values["position_loop.Tf"] is None  # derived
    fitted = base_values(load_variant(None, "fitted").params)
    assert fitted["motor.mu_v"] == 1.2e-6 and fitted["motor.no_load.speed"] is None


# --- one bound, enforced identically everywhere ---------------------------------------------------


@pytest.mark.parametrize("key", list(PARAMETERS))
def test_bound_enforced_identically_by_schema_parse_value_and_variants(key, shipped_raw):
    parameter = PARAMETERS[key]
    bad = _outside(parameter)
    rule = "finite" if parameter.lower is None else parameter.rule
    expected = f"{key}: must be {rule}, got {bad!r} {parameter.unit}"
    if parameter.datasheet_unit:  # a value with a unit (a bare number is refused)
        bad = f"{bad!r} {parameter.unit}"
        expected = f"{key}: must be {rule}, got {bad!r}"

    # parse_value (sweep --set, montecarlo --tolerance)
    with pytest.raises(ConfigError) as info:
        parse_value(key, bad)
    assert str(info.value) == expected

    # the config schema (a velocity-loop key in a cascade config, a linear output's key in a
    # config with a screw)
    if key in CASCADE_ONLY:
        as_cascade(shipped_raw)
    if key in LINEAR_ONLY:
        shipped_raw["gear"]["screw_lead"] = 0.005
        shipped_raw["load"] = {}
        for section in ("variants", "load_envelope", "requirements", "reference"):  # angles
            shipped_raw.pop(section, None)
    cascade = copy.deepcopy(shipped_raw) if key in {**CASCADE_ONLY, **LINEAR_ONLY} else None
    if key == "motor.mu_v":
        del shipped_raw["motor"]["no_load"]
    _set(shipped_raw, key, bad)
    with pytest.raises(ConfigError) as info:
        validate(shipped_raw, "test")
    assert f"test: {expected}" in str(info.value)

    # variant_parameters: same message, with the offending sample (its values are in SI)
    if key in VARIABLE_KEYS and not parameter.datasheet_unit:
        params = validate(cascade, "test") if cascade else load_variant().params
        good = _inside(parameter, base_values(params)[key])
        with pytest.raises(ConfigError) as info:
            variant_parameters(params, {key: [good, bad]})
        assert str(info.value) == f"{expected} (samples [1])"


@pytest.mark.parametrize("key", list(PARAMETERS))
def test_values_on_the_bound_or_inside_are_accepted(key):
    parameter = PARAMETERS[key]

    def given(value):  # as a config writes it: with the SI unit where a unit is required
        return f"{value} {parameter.unit}" if parameter.datasheet_unit else value

    if parameter.lower is not None and not parameter.strict:
        assert parse_value(key, given(parameter.lower)) == parameter.lower
    if parameter.upper is not None:
        assert parse_value(key, given(parameter.upper)) == parameter.upper
        assert parse_value(key, given(str(parameter.upper))) == parameter.upper
    inside = 1.0 if parameter.lower is None else parameter.lower + 1.0
    if parameter.upper is not None:
        inside = min(inside, parameter.upper)
    assert parse_value(key, given(inside)) == inside


def test_parse_value_converts_units_and_names_the_key():
    assert parse_value("position_loop.delay", "0.4 ms") == pytest.approx(4e-4, rel=1e-12)
    assert parse_value("simulation.current_loop_rate", "25 kHz") == pytest.approx(25e3)
    with pytest.raises(ConfigError, match=r"^position_loop\.Kd: must be 0 or within "
                       r"1e-09\.\.1e\+09 A\*s/rad, got '-1'"):
        parse_value("position_loop.Kd", "-1")
    with pytest.raises(ConfigError, match=r"^current_loop\.delay: cannot read '1 V' as a value"):
        parse_value("current_loop.delay", "1 V")
    with pytest.raises(ConfigError,
                       match=r"^motor\.R: cannot read 'nan ohm': does not start with a number"):
        parse_value("motor.R", "nan ohm")
    with pytest.raises(ConfigTypeError, match=r"^motor\.R: expected a number in ohm"):
        parse_value("motor.R", [1.0])
    with pytest.raises(ConfigError, match="not a numeric parameter"):
        parse_value("position_loop.derivative_on", 1.0)


def test_loop_parameters_check_finiteness_not_the_keys_ranges():
    # The keys' ranges are checked where a user's value enters (parse_value above,
    # variant_parameters); LoopParameters also holds an internal scan's values, e.g. the
    # stable hinge-stiffness scan's K_h = -3e9 N*m/rad, past load.hinge_stiffness's 1e9.
    base = LoopParameters.from_config(load_variant().params)
    assert base.replace(K_h=np.array([-3e9, 3e9])).K_h.tolist() == [-3e9, 3e9]
    with pytest.raises(ConfigError, match=r"^simulation parameters: ff_v: must be finite, got "
                                          r"inf \(runs \[0\]\)"):
        base.replace(ff_v=np.inf)
    with pytest.raises(ConfigError, match=r"K_h: must be finite, got nan \(runs \[1\]\)"):
        base.replace(K_h=np.array([0.0, np.nan]))
    # Tf may be 0 where there is no derivative term, not where there is one
    assert base.replace(cp_Kd=0.0, Tf=0.0).Tf[0] == 0.0
    with pytest.raises(ConfigError, match="Tf: must be > 0 s where cp_Kd > 0"):
        base.replace(Tf=0.0)


# --- the derived rules agree ----------------------------------------------------------------------


def test_derived_rules_agree_between_schema_and_variants(shipped_raw):
    rng = np.random.default_rng(10)
    n = 25
    samples = {
        "motor.Km": rng.uniform(0.005, 0.02, n),
        "motor.no_load.speed": rng.uniform(500.0, 3000.0, n),
        "motor.no_load.current": rng.uniform(0.0, 0.5, n),
        "position_loop.Kp": rng.uniform(0.5, 10.0, n),
        "position_loop.Kd": np.r_[0.0, rng.uniform(0.0, 0.1, n - 1)],  # Kd = 0: Tf = 0
    }
    base = load_variant().params
    batch = variant_parameters(base, samples)
    for i in range(n):
        for key, values in samples.items():
            value = float(values[i])
            _set(shipped_raw, key, f"{value!r} rad/s" if key == "motor.no_load.speed" else value)
        params = validate(shipped_raw, "sample")
        # one function behind both: equal to the last bit
        assert batch.mu_v[i] == params.motor.viscous_friction
        assert batch.Tf[i] == params.position_loop.filter_time_constant
        assert LoopParameters.from_config(params).Tf[0] == batch.Tf[i]
    assert batch.Tf[0] == 0.0


def test_derived_rules_on_scalars_and_arrays():
    assert filter_time_constant(6.0, 0.06) == pytest.approx(1e-3, rel=1e-15)
    assert filter_time_constant(6.0, 0.06, 2e-4) == 2e-4  # a set Tf wins
    assert filter_time_constant(0.0, 0.0) == 0.0  # no derivative: no filter
    np.testing.assert_array_equal(filter_time_constant([6.0, 3.0], [0.06, 0.0]), [0.06 / 60, 0])
    with pytest.raises(ValueError, match="Kp = 0 and Kd > 0"):
        filter_time_constant(0.0, 0.01)
    km, speed, current = np.array([0.01, 0.02]), np.array([1000.0, 2000.0]), np.array([0.2, 0.2])
    np.testing.assert_array_equal(viscous_friction(km, speed, current), km * current / speed)
    with pytest.raises(ValueError, match="no_load_speed: must be > 0"):
        viscous_friction(km, np.array([1000.0, 0.0]), current)


def test_shipped_mu_v_is_the_same_number_through_every_path():
    # The value itself (report Table 3: 1.341e-6 N*m*s/rad from Km = 0.0105 N*m/A, I0 = 0.218 A,
    # n0 = 16300 rpm) is checked in test_formulas.py and test_config.py; here every path that
    # derives it gives that same float.
    params = load_variant().params
    mu_v = params.motor.viscous_friction
    assert LoopParameters.from_config(params).mu_v[0] == mu_v
    assert variant_parameters(params, {}).mu_v[0] == mu_v
    assert variant_parameters(params, {"motor.Km": [params.motor.Km]}).mu_v[0] == mu_v
