"""Read a bench step recording: a CSV whose header names the columns and their units.

The columns (:mod:`cas_freq.identification.columns`): time (required), the commanded output angle
(optional), the measured output angle (required), motor current and voltage (optional); others are
ignored, so what ``cas-freq simulate --step 10deg --csv FILE`` writes is a recording. Lines
starting with ``#`` are comments. Sampling may be irregular.

The angles are held to the bounds of ``--step``: the step non-zero and within ±90 deg, the
position within ±180 deg of its pre-trigger level, every sample within 1000 turns.

The trigger (the step's time) is the command's jump when there is a command column: the first
sample at which the command has moved by half of its change (for a step sampled at the jump, the
first sample at the new level); without a command column, or when the command holds one level
throughout (it stepped at the recording's start, as in ``simulate --csv``), the trigger is
t = 0 of the file's time. The samples before the command first leaves its initial level (for a
step, the samples before the trigger; for a profile move, those before the move starts) are the
pre-trigger segment: the mean of the position and of the command there is the offset,
subtracted from each (without pre-trigger samples the offsets are 0). The step size is the
command's median after the trigger less its offset.
"""

import dataclasses
import math
import statistics

import numpy as np

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.fileio import csv_row, read_input
from cas_freq.identification.columns import find_columns

#: Fewest samples from the trigger on (a fit of three parameters needs some more than three).
MIN_SAMPLES = 10
#: Largest |angle| of a command or position sample as recorded [rad]: 1000 turns, beyond any
#: output's travel, so the offsets' arithmetic stays finite (a 1e308 column overflowed it).
MAX_RECORDED_RAD = 2000.0 * math.pi
#: Largest commanded step [rad]: the bound of ``--step``, ±90 deg at the output.
MAX_STEP_RAD = math.pi / 2
#: Largest excursion of the position from its pre-trigger level [rad]: twice the largest step
#: (an overshoot of 100 %; a second-order step response stays below it).
MAX_EXCURSION_RAD = 2 * MAX_STEP_RAD


@dataclasses.dataclass(frozen=True, eq=False)
class Recording:
    """A step recording in SI, the trigger at t = 0 and the offsets removed.

    Attributes
    ----------
    time_s : numpy.ndarray
        Times [s] from the trigger (negative before it), strictly increasing.
    command_rad : numpy.ndarray or None
        Commanded output angle [rad] less its pre-trigger mean; None without a command column.
    position_rad : numpy.ndarray
        Measured output angle [rad] less its pre-trigger mean.
    current_a, voltage_v : numpy.ndarray or None
        Motor current [A] and voltage [V] as recorded, if there are such columns.
    step_rad : float or None
        The commanded step [rad], from the command column (None without one).
    trigger_s : float
        Time of the trigger in the file's own time [s].
    position_offset_rad, command_offset_rad : float
        The pre-trigger means removed [rad] (0 without pre-trigger samples).
    source : str
        The file read.
    start_s : float
        Time [s] from the trigger at which the command first leaves its initial level (0 for a
        step sampled at its jump, < 0 for a move that ramps up to the trigger).
    """

    time_s: np.ndarray
    command_rad: np.ndarray | None
    position_rad: np.ndarray
    current_a: np.ndarray | None
    voltage_v: np.ndarray | None
    step_rad: float | None
    trigger_s: float
    position_offset_rad: float
    command_offset_rad: float
    source: str
    start_s: float = 0.0

    @property
    def after(self):
        """Boolean mask of the samples from the trigger on."""
        return self.time_s >= 0.0


def _cells(path):
    """(line number, cells) of every non-comment, non-blank line of the CSV ``path``
    (:func:`cas_freq.core.fileio.read_input`: a regular file of at most
    :data:`~cas_freq.core.fileio.MAX_DATA_BYTES`)."""
    text = read_input(path, "recording")
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        yield number, csv_row(path, number, line)


def _number(path, number, column, cell):
    """The float of one cell, or ConfigError naming file, line and column."""
    try:
        value = float(cell)
    except ValueError:
        what = "empty" if not cell.strip() else f"not a number: {cell.strip()[:30]!r}"
        raise ConfigError(f"{path}: line {number}: column {column.header!r}: {what}") from None
    if not math.isfinite(value):
        raise ConfigError(f"{path}: line {number}: column {column.header!r}: {cell.strip()} "
                          "(values must be finite numbers)")
    return value


def read_columns(path, columns=None):
    """The recognised columns of a recording CSV, each as an array in SI.

    Parameters
    ----------
    path : str or Path
        CSV file with a header (module docstring).
    columns : dict, optional
        ``role -> header cell`` naming columns outright
        (:func:`~cas_freq.identification.columns.find_columns`).

    Returns
    -------
    tuple of (dict, list of int, dict)
        ``role -> numpy.ndarray`` in the role's SI unit, the file's line number of each row,
        and ``role -> Column`` as found in the header.

    Raises
    ------
    ConfigError
        (a ValueError) naming the file and line for: no header, no time or position column
        (listing what is accepted), a unit pint does not know or of the wrong dimension, a
        row of another width, an empty, non-numeric or non-finite cell, a time that repeats or
        decreases, no data rows.
    """
    path = str(path)
    rows = _cells(path)
    try:
        header_line, header = next(rows)
    except StopIteration:
        raise ConfigError(f"{path}: no data (an empty file or only comments)") from None
    try:
        [float(cell) for cell in header]
    except ValueError:
        pass
    else:
        raise ConfigError(f"{path}: line {header_line}: expected a header naming the columns "
                          "(e.g. 'time_s,command_deg,position_deg'), got numbers")
    try:
        found = find_columns(header, columns)
    except ValueError as exc:
        raise ConfigError(f"{path}: line {header_line}: {exc}") from None
    values = {role: [] for role in found}
    lines = []
    time = found["time"]
    for number, cells in rows:
        if len(cells) != len(header):
            raise ConfigError(f"{path}: line {number}: expected {len(header)} columns as the "
                              f"header, got {len(cells)}")
        row = {role: _number(path, number, column, cells[column.index]) * column.scale
               for role, column in found.items()}
        for role, value in row.items():
            if not math.isfinite(value):  # a finite cell beyond the float range in SI
                column = found[role]
                raise ConfigError(f"{path}: line {number}: column {column.header!r}: "
                                  f"{cells[column.index].strip()[:30]} {column.unit} is not "
                                  "finite in SI (values must be finite numbers)")
        if lines:
            previous = values["time"][-1]
            if row["time"] == previous:
                raise ConfigError(f"{path}: line {number}: time {cells[time.index].strip()} "
                                  f"{time.unit} repeats line {lines[-1]}'s")
            if row["time"] < previous:
                raise ConfigError(f"{path}: line {number}: time {cells[time.index].strip()} "
                                  f"{time.unit} is before line {lines[-1]}'s (times must "
                                  "increase)")
        for role, value in row.items():
            values[role].append(value)
        lines.append(number)
    if not lines:
        raise ConfigError(f"{path}: no data rows after the header (line {header_line})")
    return {role: np.array(items) for role, items in values.items()}, lines, found


def read_recording(path, columns=None):
    """Read a step recording.

    Parameters
    ----------
    path : str or Path
        CSV file with a header (module docstring).
    columns : dict, optional
        ``role -> header cell`` naming columns outright (roles: time, command, position,
        current, current_command, voltage), e.g. ``{"time": "t_ms", "position": "enc_deg"}``.

    Returns
    -------
    Recording

    Raises
    ------
    ConfigError
        (a ValueError) naming the file and line for what :func:`read_columns` rejects, a
        command that does not step, fewer than :data:`MIN_SAMPLES` samples from the trigger
        on, an angle beyond :data:`MAX_RECORDED_RAD`, a step beyond the bounds of ``--step``
        (:data:`MAX_STEP_RAD`) or a position beyond :data:`MAX_EXCURSION_RAD` of its
        pre-trigger level.
    """
    arrays, lines, found = read_columns(path, columns)
    return _triggered(str(path), arrays, lines, found)


def _check_angles(path, arrays, lines, found):
    """Raise ConfigError for a command or position sample beyond :data:`MAX_RECORDED_RAD`
    (before any arithmetic on them, so no overflow warning precedes the error)."""
    for role in ("command", "position"):
        values = arrays.get(role)
        if values is None:
            continue
        beyond = np.flatnonzero(np.abs(values) > MAX_RECORDED_RAD)
        if beyond.size:
            index = int(beyond[0])
            raise ConfigError(
                f"{path}: line {lines[index]}: column {found[role].header!r}: "
                f"{math.degrees(values[index]):.6g} deg is not an output angle (accepted: "
                f"within ±{math.degrees(MAX_RECORDED_RAD):.6g} deg, 1000 turns)")


def _check_step(path, recording, lines, found):
    """Raise ConfigError unless the recording's step is within the bounds ``--step`` has
    (non-zero, within ±90 deg) and its position within twice that of its pre-trigger level."""
    step = recording.step_rad
    if step is not None and not 0 < abs(step) <= MAX_STEP_RAD:
        raise ConfigError(
            f"{path}: column {found['command'].header!r}: the command steps by "
            f"{math.degrees(step):.6g} deg; a step is non-zero and within "
            f"±{math.degrees(MAX_STEP_RAD):g} deg at the output (as --step)")
    beyond = np.flatnonzero(np.abs(recording.position_rad) > MAX_EXCURSION_RAD)
    if beyond.size:
        index = int(beyond[0])
        raise ConfigError(
            f"{path}: line {lines[index]}: column {found['position'].header!r}: the position "
            f"is {math.degrees(recording.position_rad[index]):.6g} deg from its pre-trigger "
            f"level; a step response stays within ±{math.degrees(MAX_EXCURSION_RAD):g} deg "
            "(twice the largest step)")


def _triggered(path, arrays, lines, found):
    """The :class:`Recording` of the columns read: trigger found, offsets removed, its angles
    within the bounds of a step (:func:`_check_angles`, :func:`_check_step`)."""
    _check_angles(path, arrays, lines, found)
    recording = _offsets_removed(path, arrays, lines, found)
    _check_step(path, recording, lines, found)
    return recording


def _offsets_removed(path, arrays, lines, found):
    """The :class:`Recording` of the columns read: trigger found, offsets removed."""
    t = arrays["time"]
    command = arrays.get("command")
    trigger = start = 0.0
    if command is not None:
        first, last = command[0], float(np.median(command[-max(1, command.size // 4):]))
        change = last - first
        if abs(change) > 1e-9 * max(abs(first), abs(last), 1.0):
            trigger = float(t[np.flatnonzero(np.abs(command - first) >= 0.5 * abs(change))[0]])
            start = float(t[np.flatnonzero(np.abs(command - first) > 1e-6 * abs(change))[0]])
        elif t[0] < 0 or first == 0.0:
            raise ConfigError(f"{path}: column {found['command'].header!r}: the command does "
                              f"not step (it holds {math.degrees(first):g} deg from line "
                              f"{lines[0]} to line {lines[-1]})")
        # else one level throughout, from t >= 0: the step is at t = 0, the recording's start
    before, after = t < start, t >= trigger
    count = int(np.count_nonzero(after))
    if count < MIN_SAMPLES:
        where = f"line {lines[int(np.argmax(after))]}" if count else f"after line {lines[-1]}"
        raise ConfigError(f"{path}: {count} samples from the trigger at t = {trigger:g} s "
                          f"({where}) on; at least {MIN_SAMPLES} are needed")
    position = arrays["position"]
    position_offset = float(np.mean(position[before])) if before.any() else 0.0
    command_offset = float(np.mean(command[before])) if before.any() and command is not None \
        else 0.0
    step = None
    if command is not None:
        step = float(statistics.median(command[after])) - command_offset
    return Recording(
        time_s=t - trigger,
        command_rad=None if command is None else command - command_offset,
        position_rad=position - position_offset,
        current_a=arrays.get("current"), voltage_v=arrays.get("voltage"),
        step_rad=step, trigger_s=trigger, position_offset_rad=position_offset,
        command_offset_rad=command_offset, source=path, start_s=start - trigger,
    )


__all__ = ["MAX_EXCURSION_RAD", "MAX_RECORDED_RAD", "MAX_STEP_RAD", "MIN_SAMPLES", "Recording",
           "read_columns", "read_recording"]
