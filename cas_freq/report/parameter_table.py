"""The report's parameter table: every variant's parameters, labelled and in the units of the
parameter table (:data:`cas_freq.core.parameters.PARAMETERS`), in the config's architecture (a
cascade's position gains per second, a linear output's loads in SI lengths, the filters)."""

import math
import re

from cas_freq.config.wording import name_the_output
from cas_freq.core.numbers import number
from cas_freq.core.parameters import base_values, is_cascade
from cas_freq.core.parameters import parameter as record
from cas_freq.report.document import Table

#: The parameter table's config keys (:data:`~cas_freq.core.parameters.PARAMETERS`, whose labels
#: and units they are shown with), in the report's order.
_PARAMETER_KEYS = (
    "motor.R", "motor.L", "motor.Km", "motor.Ke", "motor.J", "motor.mu_v", "gear.ratio",
    "current_loop.Kp", "current_loop.Ki", "current_loop.delay", "current_loop.v_max",
    "position_loop.Kp", "position_loop.Ki", "position_loop.Kd", "position_loop.Tf",
    "position_loop.ff_v", "position_loop.ff_a", "position_loop.delay", "position_loop.i_max",
)

#: The same for a drive with a velocity loop (P/PI position -> PI velocity -> PI current;
#: :data:`~cas_freq.core.parameters.CASCADE_PARAMETERS` gives the position keys' units); the
#: filters' numbers follow either (:func:`_filter_rows`).
_CASCADE_PARAMETER_KEYS = (
    "motor.R", "motor.L", "motor.Km", "motor.Ke", "motor.J", "motor.mu_v", "gear.ratio",
    "current_loop.Kp", "current_loop.Ki", "current_loop.delay", "current_loop.v_max",
    "velocity_loop.Kp", "velocity_loop.Ki", "velocity_loop.delay", "velocity_loop.i_max",
    "velocity_loop.feedback_filter", "velocity_loop.ff_a",
    "position_loop.Kp", "position_loop.Ki", "position_loop.ff_v", "position_loop.omega_max",
    "position_loop.delay",
)

#: The settings shown after them (not numbers): (label, getter of a config, shown for a
#: cascade).
_SETTING_ROWS = (
    ("derivative on", lambda p: p.position_loop.derivative_on, False),
    ("controllers (simulation)", lambda p: p.simulation.controllers, True),
)

#: Keys of the load and drivetrain (docs/model.md §5), shown when some variant is loaded; each
#: value is 0 (or the efficiency 1) where the key is absent.
_LOAD_KEYS = (
    "load.inertia", "load.damping", "load.hinge_stiffness", "load.hinge_bias",
    "gear.efficiency", "gear.backdrive_efficiency", "gear.stiffness", "gear.damping",
    "gear.backlash", "motor.coulomb_friction",
)

#: The same at a linear output (``gear.screw_lead``): the load in kg, N*s/m, N/m, N.
_LINEAR_LOAD_KEYS = (
    "load.mass", "load.damping", "load.stiffness", "load.bias",
    *(key for key in _LOAD_KEYS if not key.startswith("load.")),
)

#: Effective values of keys a config may leave to a rule (derived, or a default of another key).
_EFFECTIVE = {
    "motor.mu_v": lambda p: p.motor.viscous_friction,
    "position_loop.Tf": lambda p: p.position_loop.filter_time_constant,
    "gear.backdrive_efficiency": lambda p: p.gear.backdrive,
}

#: How an SI unit of :data:`~cas_freq.core.parameters.PARAMETERS` is shown: (unit, factor from SI);
#: a unit not listed is shown as pint spells it with ``·`` and ``²``.
_SHOWN_UNITS = {"ohm": ("Ω", 1.0), "H": ("mH", 1e3), "s": ("ms", 1e3),
                "rad": ("deg", 180.0 / math.pi), "dimensionless": ("-", 1.0),
                "m": ("mm", 1e3)}

#: Keys shown in another unit than their SI unit's (a friction of a few mN·m).
_SHOWN_KEY_UNITS = {"motor.coulomb_friction": ("mN·m", 1e3)}

#: The parameter table's ASCII symbols as a reader writes them (whole words only).
_SYMBOLS = {"mu_v": "μv", "eta": "η", "eta_b": "η_b", "tau_c": "τc", "tau_p": "τp",
            "tau_h": "τ_h", "delta": "δ", "tau_v": "τv", "tau_vf": "τvf", "w0": "ω0"}


def parameter_row_head(key, output, config=None):
    """(label, shown unit, factor from SI) of a parameter: its label and unit from
    :data:`~cas_freq.core.parameters.PARAMETERS` (in ``config``'s architecture and output kind: a
    cascade's position gains per second, a linear output's loads in SI lengths; a filter's
    numbers; ``+/-`` as ``±``), "the output" named as the config names it."""
    parameter = record(key, config)
    unit, scale = _SHOWN_KEY_UNITS.get(key) or _SHOWN_UNITS.get(parameter.unit) or (
        parameter.unit.replace("*", "·").replace("^2", "²"), 1.0)
    label = name_the_output(parameter.label, output).replace("+/-", "±")
    label = re.sub(r"\b(" + "|".join(_SYMBOLS) + r")\b", lambda m: _SYMBOLS[m.group(1)], label)
    return label, unit, scale


def parameter_value(params, key):
    """The effective value of a parameter key in a config [SI]."""
    if key in _EFFECTIVE:
        return _EFFECTIVE[key](params)
    value = params
    for part in key.split("."):
        value = getattr(value, part)
    return value


def parameter_table(datas):
    """The parameters of every variant (motor, gear, gains, delays, limits) with units; motor
    angles, loops on the motor shaft (docs/model.md)."""
    loaded = any(d.analysis.drivetrain is not None for d in datas)
    output = datas[0].loaded.params.output_label
    configs = [d.loaded.params for d in datas]
    cascade = is_cascade(configs[0])
    linear = configs[0].linear  # the variants of one report share their output's kind
    keys = _CASCADE_PARAMETER_KEYS if cascade else _PARAMETER_KEYS
    if linear:
        at = keys.index("gear.ratio") + 1
        keys = (*keys[:at], "gear.screw_lead", *keys[at:])

    def numbers(keys):
        for key in keys:
            label, unit, scale = parameter_row_head(key, output, configs[0])
            yield (label, unit, *(number(None if (v := parameter_value(p, key)) is None
                                         else v * scale) for p in configs))

    rows = [*numbers(keys),
            *_filter_rows(configs, [base_values(p) for p in configs], output),
            *((label, "", *(get(p) for p in configs)) for label, get, both in _SETTING_ROWS
              if both or not cascade)]
    if any(p.position_loop.feedback == "output" for p in configs):
        rows.append(("position feedback", "", *(p.position_loop.feedback for p in configs)))
    rows += numbers((_LINEAR_LOAD_KEYS if linear else _LOAD_KEYS) if loaded else ())
    caption = ("parameters of each variant (gains on the motor angle; Tf derived as "
               "Kd/(10·Kp) unless set; μv derived from the no-load point unless set)")
    if cascade:
        caption = ("parameters of each variant (gains on the motor angle; the position loop "
                   "commands the motor speed; μv derived from the no-load point unless set; "
                   "—: not set)")
    return Table(("parameter", "unit", *(d.loaded.variant for d in datas)), tuple(rows),
                 caption)


def _filter_rows(configs, values, output):
    """The numbers of the variants' filters, one row per filter (by its point, type and order
    among the filters of that point and type, so that a variant without a filter shows "—"
    and another filter's number never lands in its row) and number."""
    keys = {}  # (at, type, n) -> per variant: filter index or None
    for k, p in enumerate(configs):
        seen = {}
        for index, item in enumerate(p.filters or ()):
            n = seen[(item.at, item.type)] = seen.get((item.at, item.type), -1) + 1
            keys.setdefault((item.at, item.type, n), [None] * len(configs))[k] = index
    for (at, kind, n), indices in keys.items():
        k = next(j for j, index in enumerate(indices) if index is not None)
        names = [key.rsplit(".", 1)[1] for key in values[k]
                 if key.startswith(f"filters.{indices[k]}.")]
        where = f"{kind} at the {at.replace('_', ' ')}" + (f" #{n + 1}" if n else "")
        for name in names:
            label, unit, scale = parameter_row_head(f"filters.{indices[k]}.{name}", output,
                                                    configs[k])
            cells = [None if index is None else values[j].get(f"filters.{index}.{name}")
                     for j, index in enumerate(indices)]
            yield (f"{where}: {label}", unit,
                   *(number(None if value is None else value * scale) for value in cells))
