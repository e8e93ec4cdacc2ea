"""Which header cell of a recording holds which signal, and in which unit.

A header cell names a column and, optionally, its unit: in brackets or parentheses
(``t [s]``, ``delta (deg)``, ``time [ms]``) or as a suffix after the last underscore
(``time_s``, ``position_deg``, ``output_angle_rad``, ``current_a``). The names are matched
without regard to case, the units by pint (:func:`cas_freq.core.units.to_si`), so ``t [us]`` or
``delta [mrad]`` work as well; a unit of another dimension than the signal's is an error. A
column without a unit is in the role's default unit (:data:`ROLES`). Cells that name no role are
ignored (``theta [rad]``, ``omega [rad/s]``, ... of ``cas-freq simulate --csv``).
"""

import dataclasses
import re

from cas_freq.core.exceptions import listed
from cas_freq.core.units import to_si

#: role -> (accepted names, SI unit, default unit of a column without one, required).
ROLES = {
    "time": (("t", "time"), "s", "s", True),
    "command": (("command", "command_output", "command_fin", "cmd", "delta_cmd", "setpoint",
                 "command_angle"), "rad", "deg", False),
    "position": (("position", "delta", "output_angle", "fin_angle", "fin", "angle", "pos"),
                 "rad", "deg", True),
    "current": (("current", "i"), "A", "A", False),
    "current_command": (("current_command", "i_cmd", "current_demand", "current_cmd",
                         "i_command"), "A", "A", False),
    "voltage": (("voltage", "v"), "V", "V", False),
}

#: Unit suffixes of ``name_unit`` cells (lower case) and how pint spells them.
SUFFIX_UNITS = {"s": "s", "ms": "ms", "us": "us", "deg": "deg", "rad": "rad", "mrad": "mrad",
                "a": "A", "ma": "mA", "v": "V", "mv": "mV"}


def accepted_names(role):
    """What the header may call ``role``, for error messages."""
    names, si, default, _ = ROLES[role]
    examples = ", ".join(names)
    return f"{role}: {examples} (unit in brackets or as a suffix, e.g. '{names[0]} [{default}]' " \
           f"or '{names[0]}_{default.lower()}'; without one, {default})"


@dataclasses.dataclass(frozen=True)
class Column:
    """One recognised column.

    Attributes
    ----------
    index : int
        Position in the row (0-based).
    header : str
        The header cell as written.
    unit : str
        The unit it is read in (as pint spells it).
    scale : float
        Factor to the role's SI unit (:data:`ROLES`), from pint.
    """

    index: int
    header: str
    unit: str
    scale: float


def split_cell(cell):
    """(name in lower case, unit text or None) of a header cell."""
    text = cell.strip()
    match = re.fullmatch(r"(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]", text)
    if match:
        return match.group(1).strip().lower(), match.group(2)
    lower = text.lower()
    if any(lower in names for names, *_ in ROLES.values()):
        return lower, None
    name, _, suffix = lower.rpartition("_")
    if name and suffix in SUFFIX_UNITS:
        return name, SUFFIX_UNITS[suffix]
    return lower, None


def _column(role, index, cell, unit):
    """The :class:`Column` of ``cell`` read as ``role``; ValueError for a bad unit."""
    _, si, default, _ = ROLES[role]
    unit = default if unit is None or not unit.strip() else unit
    try:
        scale = to_si(f"1 {unit}", si)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"column {cell.strip()!r} ({role}): unit {unit!r} not accepted "
                         f"({exc})") from None
    return Column(index, cell.strip(), unit, scale)


def find_columns(cells, explicit=None):
    """The recognised columns of a header row.

    Parameters
    ----------
    cells : sequence of str
        The header cells.
    explicit : dict, optional
        ``role -> header cell`` naming a role's column outright (``{"time": "t_ms"}``); the
        cell is matched as written (case and surrounding blanks aside), its unit read as above.

    Returns
    -------
    dict
        ``role -> Column`` for each role found.

    Raises
    ------
    ValueError
        For an unknown role or cell in ``explicit``, a unit pint does not know or of the wrong
        dimension, a role named twice, or a missing time or position column (the message lists
        what is accepted).
    """
    explicit = dict(explicit or {})
    unknown = [role for role in explicit if role not in ROLES]
    if unknown:
        raise ValueError(f"unknown column role {unknown[0]!r}; the roles are "
                         f"{', '.join(ROLES)}")
    shown = listed((repr(cell.strip()[:40]) for cell in cells), ", ")
    found = {}
    for role, wanted in explicit.items():
        matches = [i for i, cell in enumerate(cells)
                   if cell.strip().lower() == wanted.strip().lower()]
        if not matches:
            raise ValueError(f"no column {wanted!r} (given for {role}); the header has {shown}")
        found[role] = _column(role, matches[0], cells[matches[0]], split_cell(cells[matches[0]])[1])
    taken = {column.index for column in found.values()}
    for index, cell in enumerate(cells):
        if index in taken:
            continue
        name, unit = split_cell(cell)
        for role, (names, *_rest) in ROLES.items():
            if name in names and role not in explicit:
                if role in found:
                    raise ValueError(f"two {role} columns, {found[role].header!r} and "
                                     f"{cell.strip()!r}; name the one to use with "
                                     f"columns {role}=NAME")
                found[role] = _column(role, index, cell, unit)
    missing = [role for role, (*_rest, required) in ROLES.items()
               if required and role not in found]
    if missing:
        accepted = "; ".join(accepted_names(role) for role in missing)
        raise ValueError(f"no {' and no '.join(missing)} column in the header ({shown}); "
                         f"accepted: {accepted}")
    return found


def parse_column_option(text):
    """``{"time": "t_ms", "position": "enc_deg"}`` from ``"time=t_ms,position=enc_deg"``."""
    mapping = {}
    for part in text.split(","):
        role, sep, name = part.partition("=")
        role, name = role.strip().lower(), name.strip()
        if not sep or not name:
            raise ValueError(f"--columns: expected ROLE=NAME[,ROLE=NAME...], got {text!r}")
        if role not in ROLES:
            raise ValueError(f"--columns: unknown role {role!r}; the roles are {', '.join(ROLES)}")
        mapping[role] = name
    return mapping
