"""Conversion of config values with units to SI floats, with pint.

This module sits at the bottom of the package (it imports nothing from cas_freq), so the
parameter table (:mod:`cas_freq.core.parameters`), the config schema and the CLI share one
conversion.

A config value is either a plain number, taken as already in SI, or a string such as
``"0.071 mH"``, ``"16300 rpm"``, ``"5.54 g*cm^2"`` or ``"0.4 ms"``, converted to the SI unit the
field expects.

Angles: radians are dimensionless in pint, so pint alone would read ``16300 min^-1`` (a speed in
revolutions per minute, as datasheets write it) as 16300 rad/min, 2π too small, ``25000 rad/s``
as 25000 Hz, and ``V/Hz`` as ``V*s/rad``. So the angle is checked as if it were a dimension of
its own (:func:`angle_problem`): the unit given must carry the same power of an angle (``rad``,
``deg``, ``rev``/``turn``, ``rpm``...) as the SI unit wanted. An angular rate (``rad/s``) accepts
``rpm``, ``rev/s``, ``deg/s``, but not ``Hz``, ``s^-1`` or ``min^-1`` (the error asks "min^-1:
rpm?"); a frequency (``Hz``) accepts ``kHz`` or ``1/s`` but not ``rad/s`` or ``rpm``; ``V*s/rad``
accepts ``V/rpm`` but not ``V/Hz`` or ``V*s``; ``A/rad`` does not accept ``A``. ``rev`` is an
alias of pint's ``revolution``. One unit carries an angle it does not write: a torque per
current (``N*m/A``, ``mN*m/A``), which in SI equals the back-EMF per angular rate exactly (the
motor's power balance, torque * rate = Km * i * rate = back-EMF * i), so it counts as per radian:
``Ke: 26.4 mN*m/A`` reads as 0.0264 V*s/rad and ``Km: 26.4 mV*s/rad`` as 0.0264 N*m/A, while
``V*s``, ``V/Hz`` and ``V/min^-1`` (per revolution or per radian?) stay refused for either.

Logarithmic units (``dB``, ``Np``, ``octave``) stand alone (``dB/s``, ``dB*s``, ``dB^2`` are
refused) and are read only where the value wanted is itself logarithmic: ``15 dB`` is not a
percentage.

A value string is ONE number and ONE unit, nothing else, checked by a strict pattern before pint
sees it (:func:`split_quantity`): the number is ``[+-]?(\\d+\\.?\\d*|\\.\\d+)([eE][+-]?\\d+)?``, the
unit is made of unit names, ``*``, ``/``, ``·``, blanks, parentheses and at most one small
integer exponent (``^2``, ``**-1``, |exponent| <= 4) per factor, and the whole string is at most
64 characters. Only the unit part is given to pint, as a unit (never evaluated as an expression,
so ``'9**9**9 ohm'`` is refused at once). Decimal commas (``"0,4 ms"``), several numbers
(``"6 3435 A/rad"``), stray dots (``"0.071.5 mH"``) are refused saying what was read; a percent
is accepted only where the quantity itself is a percentage (unit ``percent``). A bare number in
a string (``"0.4"``) is already SI. A factor ``1`` before ``/`` is pint's spelling of a
reciprocal (``"40 1/s"``, ``"5 1/s^2"``).

pint is imported only when a conversion needs it: the factor of each (unit text, SI unit) pair
pint has converted before is read from a disk cache (:mod:`cas_freq.core.unit_cache`) and applied
as pint applies it, so a CLI start whose units were all seen before does not import pint.
"""

import functools
import math
import numbers
import re

from cas_freq.core import unit_cache

#: Longest accepted value string.
MAX_TEXT = 64
#: Largest accepted |exponent| of one unit factor.
MAX_EXPONENT = 4
#: Deepest accepted nesting of parentheses in a unit.
MAX_DEPTH = 3

_NUMBER = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_QUANTITY = re.compile(rf"\s*({_NUMBER})\s*(.*?)\s*", re.DOTALL)
_TOKEN = re.compile(
    r"\s*(?:(?P<name>(?:[^\W\d_]|[°Ωµμ%])(?:[^\W\d]|[°Ωµμ])*|1(?=\s*/))"
    r"|(?P<exp>(?:\^|\*\*)\s*(?P<power>[+-]?\d+))|(?P<op>[*/·()]))"
)
_RATIO = re.compile(r"\s*(\d+\.?\d*|\.\d+)\s*:\s*(\d+\.?\d*|\.\d+)\s*")
_PERCENT = re.compile(r"%|percent|ppm|permille|‰", re.IGNORECASE)

ACCEPTED = "expected one number and one unit, e.g. '0.4 ms' or '5.54 g*cm^2' (or a number in SI)"


@functools.cache
def registry():
    """The shared pint unit registry, built once, on first use.

    Built from pint's disk cache of its parsed definitions (``cache_folder=":auto:"``, the
    user's cache folder; ~0.02 s instead of ~0.2 s of every CLI start); without a usable cache
    folder, parsed afresh. The units are pint's own either way.
    """
    import pint  # here, not at the top: a start whose units are all cached never imports it

    try:
        units = pint.UnitRegistry(cache_folder=":auto:")
    except Exception:  # noqa: BLE001 - no writable cache folder (or a stale cache): parse afresh
        units = pint.UnitRegistry()
    units.define("@alias revolution = rev")  # rev/s, rev/min: the datasheets' spelling
    return units


def _shown(text, limit=60):
    """``repr`` of ``text`` cut to about ``limit`` characters (one line, whatever it holds)."""
    shown = repr(text)
    return shown if len(shown) <= limit else shown[: limit - 4] + "...'"


def _refused(text, reason):
    """The ValueError of an unreadable value string: what was read, why, what is accepted."""
    return ValueError(f"cannot read {_shown(text)}: {reason}; {ACCEPTED}")


def _check_unit(unit, text):
    """Raise ValueError unless ``unit`` is names, operators, parentheses and small exponents."""
    pos, depth, previous = 0, 0, None  # previous: "name", "exp", "(", ")", "op" or None
    while pos < len(unit):
        match = _TOKEN.match(unit, pos)
        if match is None or match.end() == pos:
            rest = unit[pos:].strip()
            if rest[:1].isdigit() or rest[:1] in "+-.":
                raise _refused(text, f"read a number, then {_shown(rest)} (several numbers or "
                                     "a stray dot?)")
            raise _refused(text, f"cannot read the unit at {_shown(rest)}")
        pos = match.end()
        if match.group("name"):
            previous = "name"
        elif match.group("exp"):
            power = match.group("power")
            if previous not in ("name", ")") or abs(int(power)) > MAX_EXPONENT:
                raise _refused(text, "a unit exponent follows a unit name or ')' once, and is a "
                                     f"whole number within ±{MAX_EXPONENT}")
            previous = "exp"
        else:
            op = match.group("op")
            if op == "(":
                depth += 1
                if depth > MAX_DEPTH:
                    raise _refused(text, "parentheses nested too deep")
            elif op == ")":
                depth -= 1
                if depth < 0:
                    raise _refused(text, "unbalanced parentheses")
            previous = op if op in "()" else "op"
    if depth:
        raise _refused(text, "unbalanced parentheses")


def split_quantity(text):
    """``(number, unit)`` of a value string, or ValueError saying what was read.

    ``unit`` is the unit text as written (``""`` for a bare number), checked against the
    pattern of the module docstring but not yet given to pint.
    """
    if not isinstance(text, str):
        raise TypeError(f"expected a string, got {type(text).__name__}")
    if len(text) > MAX_TEXT:
        raise _refused(text, f"longer than {MAX_TEXT} characters")
    comma = re.fullmatch(r"\s*([+-]?\d*),(\d+)\s*(.*?)\s*", text, re.DOTALL)
    if comma and comma.group(1).lstrip("+-"):
        fixed = f"{comma.group(1)}.{comma.group(2)}"
        fixed += f" {comma.group(3)}" if comma.group(3) else ""
        raise _refused(text, f"decimal comma? write {fixed!r}")
    ratio = _RATIO.fullmatch(text)
    if ratio:
        value = float(ratio.group(1)) / float(ratio.group(2)) if float(ratio.group(2)) else None
        write = f"write {value:.6g}" if value is not None else "write one number"
        raise _refused(text, f"a ratio a:b is not a number; {write}")
    match = _QUANTITY.fullmatch(text)
    if match is None or "," in match.group(2):
        if "," in text:
            raise _refused(text, "a comma is not part of a value (decimal comma? several "
                                 "numbers?)")
        raise _refused(text, "does not start with a number")
    number, unit = match.group(1), match.group(2)
    _check_unit(unit, text)
    return number, unit


def _pint_text(unit):
    """Unit text as pint reads it (``·`` a product, ``µ``/``μ`` the prefix ``u``)."""
    return unit.replace("·", "*").replace("µ", "u").replace("μ", "u")


@functools.cache
def logarithmic(name):
    """True if the unit text ``name`` is one of pint's logarithmic units (``dB``, ``Np``,
    ``octave``, ``dBm``), False otherwise (also for an unknown name or a combination)."""
    try:
        units = registry().parse_units(_pint_text(name))._units
        (only,) = units
        return bool(getattr(registry()._units[only].converter, "is_logarithmic", False))
    except Exception:  # noqa: BLE001 - unknown, prefixed offset, several factors: not one
        return False


def _names(unit):
    """The unit names of checked unit text, in order (without the reciprocal's ``1``)."""
    names, pos = [], 0
    while pos < len(unit):
        match = _TOKEN.match(unit, pos)
        if match is None or match.end() == pos:
            break
        name = match.group("name")
        if name and name != "1":
            names.append(name)
        pos = match.end()
    return names


def parse_unit(unit, text=None):
    """The pint Unit of checked unit text (``""`` is dimensionless).

    Raises
    ------
    ValueError
        If a name is unknown to pint, or a logarithmic unit (``dB``) is combined with another
        unit or raised to a power (``dB/s``, ``dB^2``).
    """
    if not unit:
        return registry().dimensionless
    shown = text if text is not None else unit
    names = _names(unit)
    odd = [name for name in names if logarithmic(name)]
    if odd and unit.strip() != odd[0]:
        raise _refused(shown, f"{odd[0]} is a logarithmic unit: it stands alone, "
                              f"not combined with another unit or raised to a power "
                              f"({_shown(unit)})")
    try:
        parsed = registry().parse_units(_pint_text(unit))
        parsed.dimensionality  # noqa: B018 - pint raises here for some unknown combinations
    except Exception as exc:  # noqa: BLE001 - pint raises many kinds (UndefinedUnitError, ...)
        raise _refused(shown, f"unknown unit {_shown(unit)} ({type(exc).__name__})") from None
    return parsed


def has_unit(text):
    """True if the value string ``text`` (checked as :func:`to_si` does) carries a unit."""
    return bool(split_quantity(text)[1])


def _number(value, unit):
    try:
        number = float(value)
    except OverflowError:
        digits = len(str(abs(int(value)))) if isinstance(value, int) else "too many"
        raise ValueError(f"must be finite, got a {digits}-digit number, too large") from None
    if not math.isfinite(number):
        raise ValueError(f"must be finite, got {number!r} {unit}")
    return number


def to_si(value, unit):
    """Convert a config value to a float in ``unit``.

    Parameters
    ----------
    value : float or int or str
        A number (already in ``unit``) or a quantity string like ``"0.4 ms"``.
    unit : str
        The SI unit the value is wanted in, as pint spells it (``"s"``, ``"A/rad"``).

    Returns
    -------
    float
        The magnitude in ``unit``, finite.

    Raises
    ------
    TypeError
        If ``value`` is neither a number nor a string.
    ValueError
        If the string is not one number and one unit (module docstring), its unit has another
        dimension than ``unit`` or another power of an angle (:func:`angle_problem`), it is a
        ratio ``a:b`` or a percentage where ``unit`` is not ``percent``, or the value is not
        finite.
    """
    if isinstance(value, bool) or not isinstance(value, (numbers.Real, str)):
        raise TypeError(
            f"expected a number in {unit} or a string with a unit, got {type(value).__name__}"
        )
    if isinstance(value, numbers.Real):
        return _number(value, unit)
    number, unit_text = split_quantity(value)
    magnitude = _number(number, unit)
    if not unit_text:
        # a bare number inside a string ("0.4", or YAML's "1e-6"): already SI
        return magnitude
    if _PERCENT.search(unit_text) and unit != "percent":
        raise ValueError(f"cannot read {_shown(value)}: a percentage is not a value in {unit}; "
                         "write the value itself")
    factor = unit_cache.cached_factor(unit_text, unit)
    if factor is not None:
        result = magnitude * factor  # what pint returns for a factor it gave (unit_cache)
    else:
        result = _pint_convert(value, magnitude, unit_text, unit)
    if not math.isfinite(result):
        raise ValueError(f"{_shown(value)} is not finite in {unit}")
    return result


def _pint_convert(value, magnitude, unit_text, unit):
    """``magnitude`` in ``unit_text`` converted to ``unit`` by pint (``value`` for messages);
    the factor is remembered (:mod:`cas_freq.core.unit_cache`) when the conversion is one."""
    import pint

    source = parse_unit(unit_text, value)
    target = registry().Unit(unit)
    if logarithmic(unit_text.strip()) != logarithmic(unit):
        head = f"cannot read {_shown(value)} as a value in {unit}"
        if logarithmic(unit):
            raise ValueError(f"{head}: write it in {unit} or as a plain number of {unit}")
        plain = unit if unit != "dimensionless" else "a plain number"
        raise ValueError(f"{head}: {unit_text.strip()} is a logarithmic unit, {unit} is not; "
                         f"write the value in {plain}")
    if source.dimensionality != target.dimensionality:
        raise ValueError(
            f"{_shown(value)} has dimension {source.dimensionality}, expected that of {unit} "
            f"({target.dimensionality})"
        )
    problem = angle_problem(value, unit_text, unit)
    if problem:
        raise ValueError(problem)
    try:
        result = float(registry().Quantity(magnitude, source).to(target).magnitude)
        factor = float(registry().Quantity(1.0, source).to(target).magnitude)
        offset = float(registry().Quantity(0.0, source).to(target).magnitude)
    except (OverflowError, ArithmeticError, pint.errors.PintError) as exc:
        raise ValueError(f"cannot read {_shown(value)}: cannot convert to {unit} ({exc})") from None
    if offset == 0.0 and math.isfinite(factor) and factor != 0.0 and result == magnitude * factor:
        unit_cache.store_factor(unit_text, unit, factor)
    return result


#: pint's dimension of a force and of a current.
_FORCE = {"[mass]": 1, "[length]": 1, "[time]": -2}
_CURRENT = {"[current]": 1}


def _power_of(unit, dimension):
    """Sum of the exponents of the factors of the pint Unit ``unit`` that are of ``dimension``
    (a dict), e.g. 1 newton in ``mN*m/A`` for a force."""
    total = 0
    for name, exponent in unit._units.items():
        if dict(registry().Unit(name).dimensionality) == dimension:
            total += exponent
    return total


def torque_per_current(unit):
    """True if the pint Unit ``unit`` is written as a torque per current (a force times a length
    over a current: ``N*m/A``, ``mN*m/A``, ``oz*in/A`` with a force ounce), which counts as per
    radian (module docstring)."""
    force, current = _power_of(unit, _FORCE), _power_of(unit, _CURRENT)
    length = _power_of(unit, {"[length]": 1})
    return force == 1 and length == 1 and current == -1


def _angle_power(unit):
    """The power of an angle in the pint Unit ``unit`` (1 for rpm, 0 for Hz, -1 for V*s/rad
    and for N*m/A, :func:`torque_per_current`): pint keeps ``radian`` among its root units
    although it is dimensionless."""
    power = dict(registry().get_root_units(unit)[1]._units).get("radian", 0)
    return power - 1 if torque_per_current(unit) else power


def _rate_hint(number, source):
    """The unit probably meant by a rate per time ``source`` (a pint Unit) where an angular
    rate is wanted: ``min^-1: rpm? ('16300 rpm')``."""
    per_second = float(registry().Quantity(1.0, source).to("1/s").magnitude)
    if math.isclose(per_second, 1 / 60):
        return f"rpm? ('{number} rpm')"
    if math.isclose(per_second, 1.0):
        return f"rev/s? ('{number} rev/s'), or rad/s"
    return "write rpm, rev/s, deg/s or rad/s"


def angle_problem(value, unit_text, unit):
    """Why the value string ``value`` (unit part ``unit_text``, of ``unit``'s pint dimension)
    cannot be read in ``unit`` because of its angle, or None.

    The one rule of angles (module docstring): the power of an angle in ``unit_text`` must equal
    that in ``unit``. Otherwise the value would be read 2π off, or a frequency as an angular
    rate: refused, naming the unit probably meant.
    """
    source, target = parse_unit(unit_text, value), registry().Unit(unit)
    given, wanted = _angle_power(source), _angle_power(target)
    if given == wanted:
        return None
    head = f"cannot read {_shown(value)} as a value in {unit}: {unit_text}"
    per_time = source.dimensionality == registry().Unit("1/s").dimensionality
    if given == 0 and wanted == 1 and per_time:
        number = split_quantity(value)[0]
        return (f"{head} is a rate per time, not an angular rate (per revolution or per radian? "
                f"2π apart); {unit_text}: {_rate_hint(number, source)}")
    if given == 0:
        return (f"{head} has no angle where {unit} has one (revolutions or radians? 2π apart); "
                f"write the angle, e.g. {unit} or with rpm, rev or deg")
    if unit == "Hz":
        return (f"{head} is an angular rate, not a frequency (1 rev/s is 1 Hz, 1 rad/s is "
                "1/(2π) Hz); write it in Hz or kHz")
    return (f"{head} has an angle to the power {given} where {unit} has it to the power "
            f"{wanted}; write it in {unit}")
