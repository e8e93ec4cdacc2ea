"""maxon EPOS4 parameters: a config variant's gains as the drive's objects, and back.

:data:`OBJECTS` is the one table of the EPOS4 objects cas_freq reads and writes: object index
and subindex, the name the drive gives it, the drive's unit (a pint string), the config key it
carries (:data:`cas_freq.core.parameters.PARAMETERS`) and where the index and unit come from.

====================  =============================  ===================  ====================
object                name                           drive unit           config key
====================  =============================  ===================  ====================
0x30A0:01             Current controller P gain      uV/A                 current_loop.Kp
0x30A0:02             Current controller I gain      uV/(A*ms)            current_loop.Ki
0x30A1:01             Position controller P gain     uA/rad               position_loop.Kp
0x30A1:02             Position controller I gain     uA/(rad*s)           position_loop.Ki
0x30A1:03             Position controller D gain     uA*s/rad             position_loop.Kd
0x30A1:04             Position controller FF         uA*s/rad             position_loop.ff_v
                      velocity gain
0x30A1:05             Position controller FF         uA*s^2/rad           position_loop.ff_a
                      acceleration gain
0x30A2:01             Velocity controller P gain     uA*s/rad             velocity_loop.Kp
0x30A2:02             Velocity controller I gain     uA/rad               velocity_loop.Ki
0x3001:02             Output current limit           mA                   position_loop.i_max
                                                                          (velocity_loop.i_max)
====================  =============================  ===================  ====================

The 0x30A1 objects carry the PID-on-PI's position loop, the 0x30A2 objects a cascade's velocity
loop (:func:`objects_of`); the blocks of a variant that no object carries (filters, a cascade's
position loop, an output encoder) are listed by :func:`not_exported`, never dropped silently.

Sources: maxon, *EPOS4 Positioning Controllers, Firmware Specification* (document rel8234,
edition November 2018), section 6.2 "Object dictionary": §6.2.53 Motor data (0x3001),
§6.2.61 Current control parameter set (0x30A0), §6.2.62 Position control parameter set
(0x30A1). Only that document's table of contents could be read here; the indices, subindices,
names and units above were checked against public EPOS4 code that cites those sections (the
page docs/epos4.md lists what was confirmed where, and what was not).

The drive stores every one of these objects as a whole number (UNSIGNED32) in its unit, so a
variant's gains are rounded to 1 unit of the drive on export, and the rounding is reported.
Units are converted with pint (:func:`cas_freq.core.units.to_si`), never by hand-written factors.

Coordinates: the drive's gains are per radian of its position sensor. cas_freq's gains are
per radian of the motor shaft (docs/model.md §1), the same thing when the encoder sits on the
motor shaft (QT-CAS: report §3) and no gear is configured in the drive (object 0x3003).

The parameter file is the INI-style CANopen device configuration file (DCF, CiA 306): one
section per object, ``[30A0sub1]`` for object 0x30A0 subindex 1 (index in hex, subindex in hex
without leading zeros), with keys ``ParameterName``, ``ObjectType``, ``DataType``,
``AccessType``, ``DefaultValue`` and ``ParameterValue`` (the value in the device, decimal or
``0x`` hex). The reader takes ``ParameterValue`` (``DefaultValue`` when a section has none, and
says so) of the objects of :data:`OBJECTS` and ignores every other section.
"""

import configparser
import dataclasses
import math
import re
from pathlib import Path

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.fileio import read_input
from cas_freq.core.units import registry, to_si

__all__ = [
    "CASCADE",
    "FIRMWARE_SPECIFICATION",
    "OBJECTS",
    "PID_ON_PI",
    "DriveObject",
    "DriveSetting",
    "Epos4Export",
    "architecture",
    "export_text",
    "import_values",
    "not_exported",
    "objects_of",
    "read_export",
    "settings_of",
    "settings_table",
    "variant_entries",
]

#: The maxon document every object index and unit is cited from.
FIRMWARE_SPECIFICATION = ("maxon, EPOS4 Positioning Controllers, Firmware Specification "
                          "(rel8234, Nov 2018)")

#: CANopen data types (CiA 301) the reader accepts for the objects, and their value ranges.
DATA_TYPES = {0x0004: ("INTEGER32", -(2**31), 2**31 - 1),
              0x0006: ("UNSIGNED16", 0, 2**16 - 1),
              0x0007: ("UNSIGNED32", 0, 2**32 - 1)}
#: The data type the writer declares (and the range export checks): UNSIGNED32.
UNSIGNED32 = 0x0007

#: Largest parameter file read [bytes] (a whole EPOS4 object dictionary is ~0.2 MB).
MAX_FILE_BYTES = 16 << 20


#: The loop structures :data:`OBJECTS` are declared for (:func:`architecture`).
PID_ON_PI, CASCADE = "PID-on-PI", "cascade"


@dataclasses.dataclass(frozen=True)
class DriveObject:
    """One object of the EPOS4 object dictionary that carries a config key.

    Attributes
    ----------
    index, subindex : int
        Object index (``0x30A0``) and subindex.
    name : str
        The object's name in the drive (the DCF's ``ParameterName``).
    unit : str
        The drive's unit of the stored whole number, as pint spells it (``"uV/A"``).
    key : str
        The config key it carries (``"current_loop.Kp"``), one of
        :data:`cas_freq.core.parameters.PARAMETERS`.
    required : bool
        True if an export must hold it (the controller gains); False for the current limit.
    source : str
        Where the index, subindex and unit come from.
    architectures : tuple of str
        The loop structures whose config keys it carries: :data:`PID_ON_PI` (the report's
        PID position loop on a PI current loop), :data:`CASCADE` (P/PI position, PI velocity,
        PI current).
    """

    index: int
    subindex: int
    name: str
    unit: str
    key: str
    required: bool
    source: str
    architectures: tuple = (PID_ON_PI, CASCADE)

    @property
    def label(self):
        """``0x30A0:01``."""
        return f"0x{self.index:04X}:{self.subindex:02X}"

    @property
    def section(self):
        """The DCF section of the object: ``30A0sub1``."""
        return f"{self.index:04X}sub{self.subindex:X}"


_CURRENT = "EPOS4 Firmware Specification §6.2.61 Current control parameter set"
_POSITION = "EPOS4 Firmware Specification §6.2.62 Position control parameter set"
_MOTOR = "EPOS4 Firmware Specification §6.2.53 Motor data"
# 0x30A2 "Velocity control parameter set": subindex 1 "Velocity controller P gain", 2
# "Velocity controller I gain" (3, 4: FF velocity and acceleration gains, 5: "Velocity
# controller filter cut-off frequency"), UNSIGNED32, as public EPOS4 driver code lists the
# object dictionary citing the Firmware Specification (p. 167 of rel8234). The units µA·s/rad
# (current per rad/s) and µA/rad (current per rad) follow the micro-SI scaling of the
# confirmed gains of 0x30A0/0x30A1; maxon's own words on them were not found (docs/epos4.md).
_VELOCITY = "EPOS4 Firmware Specification, 0x30A2 Velocity control parameter set (p. 167)"

#: The EPOS4 objects cas_freq reads and writes, in the order they are printed.
OBJECTS = (
    DriveObject(0x30A0, 1, "Current controller P gain", "uV/A", "current_loop.Kp", True,
                _CURRENT),
    DriveObject(0x30A0, 2, "Current controller I gain", "uV/(A*ms)", "current_loop.Ki", True,
                _CURRENT),
    DriveObject(0x30A1, 1, "Position controller P gain", "uA/rad", "position_loop.Kp", True,
                _POSITION, (PID_ON_PI,)),
    DriveObject(0x30A1, 2, "Position controller I gain", "uA/(rad*s)", "position_loop.Ki",
                True, _POSITION, (PID_ON_PI,)),
    DriveObject(0x30A1, 3, "Position controller D gain", "uA*s/rad", "position_loop.Kd", True,
                _POSITION, (PID_ON_PI,)),
    DriveObject(0x30A1, 4, "Position controller FF velocity gain", "uA*s/rad",
                "position_loop.ff_v", True, _POSITION, (PID_ON_PI,)),
    DriveObject(0x30A1, 5, "Position controller FF acceleration gain", "uA*s^2/rad",
                "position_loop.ff_a", True, _POSITION, (PID_ON_PI,)),
    DriveObject(0x30A2, 1, "Velocity controller P gain", "uA*s/rad", "velocity_loop.Kp", True,
                _VELOCITY, (CASCADE,)),
    DriveObject(0x30A2, 2, "Velocity controller I gain", "uA/rad", "velocity_loop.Ki", True,
                _VELOCITY, (CASCADE,)),
    DriveObject(0x3001, 2, "Output current limit", "mA", "position_loop.i_max", False, _MOTOR,
                (PID_ON_PI,)),
    DriveObject(0x3001, 2, "Output current limit", "mA", "velocity_loop.i_max", False, _MOTOR,
                (CASCADE,)),
)


def architecture(params):
    """:data:`CASCADE` for a validated config with a velocity loop, else :data:`PID_ON_PI`."""
    from cas_freq.core.parameters import is_cascade

    return CASCADE if is_cascade(params) else PID_ON_PI


def objects_of(structure=PID_ON_PI):
    """The objects of :data:`OBJECTS` that carry the config keys of a loop ``structure``."""
    return tuple(obj for obj in OBJECTS if structure in obj.architectures)

#: 0x30A1:09 "SI unit position controller I gain": the unit of 0x30A1:02, selectable in later
#: firmware. Only its default (µA/(rad*s)) is read; another value is refused rather than
#: guessed (docs/epos4.md).
I_GAIN_UNIT = (0x30A1, 9)
I_GAIN_UNIT_DEFAULT = 0xFA040300

#: What a variant has that no object of :data:`OBJECTS` carries (docs/epos4.md).
NOT_WRITTEN = ("position_loop.Tf (no EPOS4 object for the derivative filter was confirmed), "
               "current_loop.v_max (the supply voltage), the delays")
#: The same for a cascade (the blocks with no object are listed one by one, :func:`not_exported`).
NOT_WRITTEN_CASCADE = ("current_loop.v_max (the supply voltage), the delays, "
                       "position_loop.omega_max, position_loop.ff_v, velocity_loop.ff_a (the "
                       "units of 0x30A2:03/04 were not confirmed)")


def not_exported(params):
    """One line per block of a validated variant that no EPOS4 object carries, saying so.

    The EPOS4 object dictionary (as public driver code lists it, docs/epos4.md) has no
    configurable filter at the current command or on the velocity feedback; its velocity
    controller has a filter cut-off frequency (0x30A2:05) whose unit and form (a first-order
    low-pass?) were not confirmed; its dual-loop mode (0x30AE "Dual loop position control
    parameter set") closes the position loop on a second encoder with gains whose form and
    units were not confirmed. A cascade's position loop (a velocity command per position error)
    has no object: the EPOS4's position controller (0x30A1) commands the current.

    Returns
    -------
    list of str
        ``"no EPOS4 object for filters.0 (notch at the current command): not exported (...)"``.
    """
    lines = []
    if architecture(params) == CASCADE:
        lines.append("no EPOS4 object for the cascade's position loop (position_loop.Kp, "
                     "position_loop.Ki: a velocity command per position error): not exported "
                     "(the EPOS4's position controller 0x30A1 commands the current; with the "
                     "velocity controller 0x30A2 the position loop runs in the master)")
        if getattr(params.velocity_loop, "feedback_filter", 0.0):
            lines.append("no EPOS4 object for velocity_loop.feedback_filter (first-order "
                         "low-pass on the measured speed): not exported (0x30A2:05 Velocity "
                         "controller filter cut-off frequency exists; its unit and filter form "
                         "were not confirmed)")
    for index, item in enumerate(getattr(params, "filters", None) or ()):
        lines.append(f"no EPOS4 object for filters.{index} ({item.type} at the "
                     f"{item.at.replace('_', ' ')}): not exported (the EPOS4 has no "
                     "configurable filter there in the public object dictionary)")
    if getattr(params.position_loop, "feedback", "motor") == "output":
        lines.append("no EPOS4 object for position_loop.feedback: output (the position loop on "
                     "an output encoder): not exported (the dual-loop mode, 0x30AE Dual loop "
                     "position control parameter set, reads a second encoder; its gains' form "
                     "and units were not confirmed)")
    return lines


_BY_ADDRESS = {structure: {(obj.index, obj.subindex): obj for obj in objects_of(structure)}
               for structure in (PID_ON_PI, CASCADE)}
_SECTION = re.compile(r"([0-9A-Fa-f]{4})(?:sub([0-9A-Fa-f]{1,2}))?")
_VALUE = re.compile(r"(-?)(?:0[xX]([0-9A-Fa-f]+)|(\d+))")
_NO_DEFAULTS = "\x00cas_freq: no DEFAULT section"


def _quantity(magnitude, unit):
    """A pint Quantity in the shared registry."""
    return registry().Quantity(magnitude, unit)


def _si_unit(key):
    from cas_freq.core.parameters import unit_of

    return unit_of(key)


def _shown(text, limit=60):
    shown = repr(text)
    return shown if len(shown) <= limit else shown[: limit - 4] + "...'"


# --------------------------------------------------------------------------- reading


@dataclasses.dataclass(frozen=True)
class ReadValue:
    """One object's value as read from a parameter file.

    Attributes
    ----------
    obj : DriveObject
    value : int
        The whole number the drive stores [``obj.unit``].
    line : int
        Line of the value in the file (1-based).
    from_default : bool
        True if the section had no ``ParameterValue`` and ``DefaultValue`` was read.
    """

    obj: DriveObject
    value: int
    line: int
    from_default: bool


@dataclasses.dataclass(frozen=True)
class Epos4Export:
    """The EPOS4 objects of one parameter file.

    Attributes
    ----------
    path : str
        The file read.
    values : tuple of ReadValue
        The objects of :data:`OBJECTS` found, in the table's order.
    absent : tuple of DriveObject
        Optional objects of :data:`OBJECTS` the file does not hold.
    ignored : int
        Sections of other objects, not read.
    """

    path: str
    values: tuple
    absent: tuple
    ignored: int


def _decode(raw):
    """The text of a parameter file: UTF-8 (with or without BOM), else Latin-1 (Windows
    tools write 8-bit text)."""
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _line_numbers(text):
    """``{(section, key_lowercase): line}`` and ``{section: header line}`` of INI text."""
    keys, headers, section = {}, {}, None
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped[0] in ";#":
            continue
        if stripped.startswith("[") and "]" in stripped:
            section = stripped[1:stripped.index("]")]
            headers.setdefault(section, number)
        elif section is not None and "=" in stripped and not line[:1].isspace():
            keys.setdefault((section, stripped.split("=", 1)[0].strip().lower()), number)
    return keys, headers


def _parse_ini(text, where):
    """configparser of the parameter file ``text``; ConfigError naming the line if it is not
    INI."""
    parser = configparser.ConfigParser(
        interpolation=None, strict=True, delimiters=("=",), comment_prefixes=(";", "#"),
        inline_comment_prefixes=None, empty_lines_in_values=False,
        default_section=_NO_DEFAULTS,
    )
    accepted = ("an INI-style parameter file (CiA 306 DCF): [section] headers such as "
                "[30A0sub1], then Key=Value lines")
    try:
        parser.read_string(text, source=where)
    except configparser.MissingSectionHeaderError as exc:
        raise ConfigError(f"{where}: line {exc.lineno}: {_shown(exc.line.strip())} comes "
                          f"before any [section]; expected {accepted}") from None
    except configparser.DuplicateSectionError as exc:
        raise ConfigError(f"{where}: line {exc.lineno}: section [{exc.section}] appears twice; "
                          "each object may appear once") from None
    except configparser.DuplicateOptionError as exc:
        raise ConfigError(f"{where}: line {exc.lineno}: [{exc.section}] has {exc.option}= "
                          "twice; each key may appear once per section") from None
    except configparser.ParsingError as exc:
        number, line = exc.errors[0]
        raise ConfigError(f"{where}: line {number}: cannot read {_shown(line.strip())}; "
                          f"expected {accepted}") from None
    return parser


def _integer(text, data_type, where, expected):
    """The whole number of a DCF value text (decimal or 0x hex) within ``data_type``'s range."""
    name, low, high = DATA_TYPES[data_type]
    match = _VALUE.fullmatch(text.strip())
    if match is None:
        raise ConfigError(f"{where}: {_shown(text)} is not a whole number; {expected}")
    sign, hexadecimal, decimal = match.groups()
    value = int(hexadecimal, 16) if hexadecimal is not None else int(decimal)
    value = -value if sign else value
    if not low <= value <= high:
        raise ConfigError(f"{where}: {_shown(text)} is outside the range of {name} "
                          f"({low}..{high}); {expected}")
    return value


def read_export(path, structure=PID_ON_PI):
    """Read the EPOS4 objects of :data:`OBJECTS` from an EPOS Studio parameter file.

    Parameters
    ----------
    path : str or Path
        The INI-style parameter file (CiA 306 DCF). It is only read.
    structure : str
        The loop structure of the config the values go to (:func:`architecture`): the objects
        of :func:`objects_of` it are read (a cascade: the current and velocity controllers and
        the current limit), the others ignored.

    Returns
    -------
    Epos4Export

    Raises
    ------
    ConfigError
        Naming the file, the line, the section and the value, for a file that is not INI, an
        object that appears twice (``[30A0sub1]`` and ``[30a0sub01]`` are one object), a value
        that is not a whole number of the declared data type, a data type other than
        INTEGER32, UNSIGNED16 or UNSIGNED32, a position I gain in a unit other than the default
        (0x30A1:09), or a missing gain object (every one is listed).
    """
    path = Path(path)
    where = str(path)
    raw = read_input(path, "EPOS4 parameter file", MAX_FILE_BYTES, encoding=None)
    text = _decode(raw)
    parser = _parse_ini(text, where)
    key_lines, header_lines = _line_numbers(text)

    found, seen_at, ignored, i_gain_unit = {}, {}, 0, None
    for section in parser.sections():
        match = _SECTION.fullmatch(section.strip())
        address = None
        if match is not None:
            address = (int(match.group(1), 16),
                       int(match.group(2), 16) if match.group(2) is not None else None)
        obj = _BY_ADDRESS[structure].get(address)
        if address == I_GAIN_UNIT:
            i_gain_unit = section
            continue
        if obj is None:
            ignored += 1
            continue
        line = header_lines.get(section, 0)
        if obj in seen_at:
            raise ConfigError(f"{where}: line {line}: [{section}] is object {obj.label} again "
                              f"(first as [{seen_at[obj][0]}] at line {seen_at[obj][1]}); each "
                              "object may appear once")
        seen_at[obj] = (section, line)
        found[obj] = _read_value(parser, section, obj, where, key_lines, line)
    if i_gain_unit is not None and structure == PID_ON_PI:
        _check_i_gain_unit(parser, i_gain_unit, where, key_lines, header_lines)

    objects = objects_of(structure)
    missing = [obj for obj in objects if obj.required and obj not in found]
    if missing:
        listed = ", ".join(f"{obj.label} {obj.name} ([{obj.section}])" for obj in missing)
        raise ConfigError(f"{where}: missing {'object' if len(missing) == 1 else 'objects'} "
                          f"{listed}; an EPOS4 export for a {structure} config holds every "
                          f"controller gain ({', '.join(o.label for o in objects if o.required)})")
    return Epos4Export(
        path=where,
        values=tuple(found[obj] for obj in objects if obj in found),
        absent=tuple(obj for obj in objects if obj not in found),
        ignored=ignored,
    )


def _read_value(parser, section, obj, where, key_lines, header_line):
    """The ReadValue of ``obj`` from its ``section``."""
    items = parser[section]
    expected = (f"{obj.label} {obj.name} is a whole number in {obj.unit}, decimal or 0x hex "
                "(e.g. ParameterValue=616300)")
    data_type = UNSIGNED32
    if "datatype" in items:
        line = key_lines.get((section, "datatype"), header_line)
        text = items["datatype"]
        match = _VALUE.fullmatch(text.strip())
        code = None
        if match is not None and not match.group(1):
            code = int(match.group(2), 16) if match.group(2) else int(match.group(3))
        if code not in DATA_TYPES:
            accepted = ", ".join(f"0x{c:04X} ({n})" for c, (n, _, _) in DATA_TYPES.items())
            raise ConfigError(f"{where}: line {line}: [{section}] DataType={text.strip()}: "
                              f"{obj.label} {obj.name} is a whole number; accepted DataType "
                              f"{accepted}")
        data_type = code
    if "parametervalue" in items and items["parametervalue"].strip():
        key, from_default = "parametervalue", False
    elif "defaultvalue" in items and items["defaultvalue"].strip():
        key, from_default = "defaultvalue", True
    else:
        raise ConfigError(f"{where}: line {header_line}: [{section}] ({obj.label} {obj.name}) "
                          "has no ParameterValue (nor DefaultValue); " + expected)
    line = key_lines.get((section, key), header_line)
    shown_key = "DefaultValue" if from_default else "ParameterValue"
    value = _integer(items[key], data_type, f"{where}: line {line}: [{section}] {shown_key}",
                     expected)
    return ReadValue(obj, value, line, from_default)


def _check_i_gain_unit(parser, section, where, key_lines, header_lines):
    """Refuse a position I gain in another unit than the default µA/(rad*s)."""
    items = parser[section]
    key = "parametervalue" if items.get("parametervalue", "").strip() else "defaultvalue"
    text = items.get(key, "").strip()
    if not text:
        return
    line = key_lines.get((section, key), header_lines.get(section, 0))
    expected = (f"cas_freq reads 0x30A1:02 only in the default unit µA/(rad*s), "
                f"0x30A1:09 = 0x{I_GAIN_UNIT_DEFAULT:08X}")
    value = _integer(text, UNSIGNED32, f"{where}: line {line}: [{section}]", expected)
    if value != I_GAIN_UNIT_DEFAULT:
        raise ConfigError(f"{where}: line {line}: [{section}] SI unit position controller I "
                          f"gain = 0x{value:08X}: {expected}; set the drive to that unit and "
                          "export again")


# --------------------------------------------------------------------------- conversion


def import_values(export):
    """The config values of an export: ``{key: (drive text, SI value)}``.

    Parameters
    ----------
    export : Epos4Export

    Returns
    -------
    dict of str to (str, float)
        For each object read, its config key, the value as a config string in the drive's unit
        (``"616300 uV/A"``, read by the config loader as it is) and the value in the key's SI
        unit (:func:`cas_freq.core.parameters.unit_of`), converted with pint.
    """
    out = {}
    for read in export.values:
        text = f"{read.value} {read.obj.unit}"
        out[read.obj.key] = (text, to_si(text, _si_unit(read.obj.key)))
    return out


@dataclasses.dataclass(frozen=True)
class DriveSetting:
    """One object's value for a variant, in the drive's unit, rounded to the drive's resolution.

    Attributes
    ----------
    obj : DriveObject
    si_value : float
        The variant's value [SI unit of ``obj.key``].
    exact : float
        The same value in the drive's unit [``obj.unit``].
    value : int
        ``exact`` rounded to a whole number, what the drive stores [``obj.unit``].
    """

    obj: DriveObject
    si_value: float
    exact: float
    value: int

    @property
    def si_unit(self):
        """SI unit of ``si_value``."""
        return _si_unit(self.obj.key)

    @property
    def rounded(self):
        """True if rounding to the drive's resolution changed the value (by more than the
        floating-point noise of the unit conversion, 1e-9 relative)."""
        return abs(self.exact - self.value) > 1e-9 * max(1.0, abs(self.exact))

    @property
    def relative_change(self):
        """(value - exact) / exact [-], 0 for an exact 0."""
        return (self.value - self.exact) / self.exact if self.exact else 0.0

    def to_dict(self):
        """JSON-ready dict of the setting."""
        return {
            "object": self.obj.label, "index": self.obj.index, "subindex": self.obj.subindex,
            "name": self.obj.name, "key": self.obj.key, "drive_value": self.value,
            "drive_unit": self.obj.unit, "drive_exact": self.exact,
            "si_value": self.si_value, "si_unit": self.si_unit, "rounded": self.rounded,
            "relative_change": self.relative_change, "source": self.obj.source,
        }


def settings_of(params, origin="the variant"):
    """A validated variant's values of every object of :data:`OBJECTS`, in the drive's units.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        The variant (:attr:`cas_freq.config.LoadedVariant.params`), in SI.
    origin : str
        What to name in an error message (``"configs/qt_cas.yaml (variant 'base')"``).

    Returns
    -------
    list of DriveSetting
        The objects of the variant's loop structure (:func:`objects_of`), in the order of
        :data:`OBJECTS`; each value is rounded half up to a whole number of the drive's unit.
        The blocks no object carries: :func:`not_exported`.

    Raises
    ------
    ConfigError
        For a value the drive cannot store: negative (the objects are UNSIGNED32) or larger
        than 4294967295 in the drive's unit; the message names the key, the value and the
        range in both units.
    """
    from cas_freq.core.parameters import base_values

    values = base_values(params)
    _, low, high = DATA_TYPES[UNSIGNED32]
    settings = []
    for obj in objects_of(architecture(params)):
        si = values[obj.key]
        si_unit = _si_unit(obj.key)
        exact = float(_quantity(si, si_unit).to(obj.unit).magnitude)
        value = math.floor(exact + 0.5)
        if not low <= value <= high:
            top = float(_quantity(high, obj.unit).to(si_unit).magnitude)
            raise ConfigError(
                f"{origin}: {obj.key} = {si:g} {si_unit} is {exact:.6g} {obj.unit}, which "
                f"{obj.label} {obj.name} cannot hold: the drive stores 0..{high} {obj.unit} "
                f"(0..{top:.6g} {si_unit})"
            )
        settings.append(DriveSetting(obj, float(si), exact, value))
    return settings


# --------------------------------------------------------------------------- writing


def settings_table(settings, title, missing=None):
    """A text table of a variant's settings, for typing them into the drive.

    Parameters
    ----------
    settings : sequence of DriveSetting
    title : str
        First line (``"qt_cas / base"``).
    missing : sequence of str, optional
        The variant's :func:`not_exported` lines, printed after the table.

    Returns
    -------
    str
        One row per object: object index, name, drive value and unit, SI value and key; then
        which values were rounded to the drive's resolution, and by how much.
    """
    rows = [("object", "name", "drive value", "SI value", "config key")]
    for item in settings:
        rows.append((item.obj.label, item.obj.name, f"{item.value} {item.obj.unit}",
                     f"{item.si_value:.6g} {item.si_unit}", item.obj.key))
    widths = [max(len(row[i]) for row in rows) for i in range(4)]
    lines = [title]
    for row in rows:
        cells = [row[i].ljust(widths[i]) for i in range(4)] + [row[4]]
        lines.append("  " + "  ".join(cells).rstrip())
    rounded = [item for item in settings if item.rounded]
    if rounded:
        lines.append("  rounded to the drive's resolution (1 unit of the drive):")
        for item in rounded:
            lines.append(f"    {item.obj.label} {item.obj.key}: {item.exact:.9g} -> {item.value} "
                         f"{item.obj.unit} ({100 * item.relative_change:+.3g} %)")
    else:
        lines.append("  no rounding: every value is a whole number in the drive's unit")
    cascade = any(item.obj.key.startswith("velocity_loop.") for item in settings)
    lines.append(f"  not drive objects: {NOT_WRITTEN_CASCADE if cascade else NOT_WRITTEN}")
    lines += [f"  {line}" for line in missing or ()]
    return "\n".join(lines)


def export_text(settings, origin, file_name=None, missing=()):
    """An EPOS4 parameter file (INI-style DCF) holding ``settings``, as :func:`read_export`
    reads it.

    Parameters
    ----------
    settings : sequence of DriveSetting
    origin : str
        The config and variant it was written from, for the file's header comment.
    file_name : str, optional
        ``FileName`` of the ``[FileInfo]`` section.
    missing : sequence of str
        The variant's :func:`not_exported` lines, written as comments after the header.

    Returns
    -------
    str
        A header comment saying that cas_freq wrote it (it was not exported from a drive), a
        ``[FileInfo]`` section, and one section per object with ``ParameterName``,
        ``ObjectType=0x7``, ``DataType=0x0007``, ``AccessType=rw`` and ``ParameterValue``.
    """
    from cas_freq import __version__

    origin = " ".join(str(origin).split())
    lines = [
        f"; EPOS4 parameters written by cas-freq epos4 export (cas_freq {__version__}) from",
        f"; {origin}.",
        "; Written by cas_freq, NOT exported from a drive. Objects and units: maxon EPOS4",
        "; Firmware Specification, as cas_freq/drive/epos4.py cites them; file format: the",
        "; INI-style CANopen DCF (CiA 306), with only these objects. Values are whole numbers",
        "; in the drive's units, rounded from the variant's SI values.",
        *(f"; {line}" for line in missing),
        "",
        "[FileInfo]",
    ]
    if file_name:
        lines.append(f"FileName={file_name}")
    lines += [f"CreatedBy=cas_freq {__version__}",
              "Description=EPOS4 controller gains written by cas-freq epos4 export", ""]
    for item in settings:
        lines += [
            f"[{item.obj.section}]",
            f"ParameterName={item.obj.name}",
            "ObjectType=0x7",
            f"DataType=0x{UNSIGNED32:04X}",
            "AccessType=rw",
            f"ParameterValue={item.value}",
            f"; {item.obj.label} = {item.si_value:.9g} {item.si_unit} ({item.obj.key}) "
            f"in {item.obj.unit}",
            "",
        ]
    return "\n".join(lines)


def variant_entries(export):
    """The dotted-key lines of a config variant holding an export's values.

    Parameters
    ----------
    export : Epos4Export

    Returns
    -------
    list of (str, str, str)
        ``(key, value text, comment)`` per object read, e.g. ``("current_loop.Kp",
        "616300 uV/A", "0x30A0:01 Current controller P gain = 0.6163 V/A")``; the value text is
        in the drive's unit, read by the config loader as it is.
    """
    values = import_values(export)
    entries = []
    for read in export.values:
        text, si = values[read.obj.key]
        note = " (from DefaultValue)" if read.from_default else ""
        entries.append((read.obj.key, text, f"{read.obj.label} {read.obj.name} = {si:.6g} "
                        f"{_si_unit(read.obj.key)}{note}"))
    return entries
