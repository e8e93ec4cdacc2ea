"""Read a frequency-sweep recording (chirp or stepped sine) and tell sweeps from steps.

A sweep recording is a CSV as a step recording is (:mod:`cas_freq.identification.recordings`,
the same header and unit rules of :mod:`cas_freq.identification.columns`): time, the output command
and the output angle (required here), the motor current and the current command (optional). Its
command oscillates: :func:`is_sweep` counts how often it crosses its median, outside a dead band
of a tenth of its range; a step's command (one or two levels, with noise) crosses it at most
once. Irregular sampling is resampled (:func:`numpy.interp`) to a uniform grid at the median
interval, which the spectral estimates (:mod:`cas_freq.identification.frf`) need.
"""

import dataclasses
import math

import numpy as np

from cas_freq.core.exceptions import ConfigError
from cas_freq.identification.columns import accepted_names
from cas_freq.identification.recordings import read_columns

#: Fewest samples of a sweep recording (8 Welch averages of 32 samples, overlapping by half).
MIN_SAMPLES = 144
#: Crossings of the command's median (outside the dead band) from which a command is a sweep.
MIN_CROSSINGS = 6
#: Dead band about the median, as a fraction of the command's range.
DEAD_BAND = 0.1
#: Relative spread of the intervals above which the recording is resampled.
REGULAR_TOLERANCE = 1e-6


@dataclasses.dataclass(frozen=True, eq=False)
class SweepRecording:
    """A sweep recording in SI on a uniform time grid.

    Attributes
    ----------
    time_s : numpy.ndarray
        Uniform times [s] (the file's own, from its first sample).
    command_rad, position_rad : numpy.ndarray
        Output command and output angle [rad].
    current_a, current_command_a : numpy.ndarray or None
        Motor current and current command [A], if the file has such columns.
    interval_s : float
        The grid's interval: the median interval of the file [s].
    samples : int
        Rows in the file.
    resampled : bool
        True if the file's sampling was irregular and the signals were interpolated.
    interval_spread : float
        Largest relative deviation of the file's intervals from their median [-].
    source : str
        The file read.
    """

    time_s: np.ndarray
    command_rad: np.ndarray
    position_rad: np.ndarray
    current_a: np.ndarray | None
    current_command_a: np.ndarray | None
    interval_s: float
    samples: int
    resampled: bool
    interval_spread: float
    source: str

    @property
    def rate_hz(self):
        """Sampling rate of the grid [Hz]."""
        return 1.0 / self.interval_s


def median_crossings(command):
    """How many times ``command`` crosses its median, outside a dead band of
    :data:`DEAD_BAND` of its range (0 for a constant command)."""
    command = np.asarray(command, dtype=float)
    if command.size == 0:
        return 0
    span = float(np.max(command) - np.min(command))
    if span <= 0.0:
        return 0
    deviation = command - float(np.median(command))
    side = np.sign(np.where(np.abs(deviation) > DEAD_BAND * span, deviation, 0.0))
    side = side[side != 0]
    return int(np.count_nonzero(side[1:] != side[:-1]))


def is_sweep(command):
    """True if the command oscillates (a chirp or stepped sine), False for a step (None or a
    command of one or two levels: at most one crossing of its median)."""
    return command is not None and median_crossings(command) >= MIN_CROSSINGS


def recording_kind(path, columns=None):
    """``"sweep"`` or ``"step"``: what the recording ``path`` holds (its command column,
    :func:`is_sweep`); ConfigError as :func:`~cas_freq.identification.recordings.read_columns`
    raises it."""
    arrays, _, _ = read_columns(path, columns)
    return "sweep" if is_sweep(arrays.get("command")) else "step"


def uniform(time_s, signals):
    """``signals`` on a uniform grid at the median interval of ``time_s``.

    Parameters
    ----------
    time_s : numpy.ndarray
        Strictly increasing times [s].
    signals : dict of str to numpy.ndarray or None
        Signals sampled at ``time_s`` (None passes through).

    Returns
    -------
    tuple
        (grid [s], resampled signals, median interval [s], resampled (bool), largest relative
        deviation of the intervals from the median [-]).
    """
    steps = np.diff(time_s)
    interval = float(np.median(steps))
    spread = float(np.max(np.abs(steps / interval - 1.0)))
    if spread <= REGULAR_TOLERANCE:
        return time_s, dict(signals), interval, False, spread
    count = int(math.floor((time_s[-1] - time_s[0]) / interval * (1.0 + 1e-12))) + 1
    grid = time_s[0] + interval * np.arange(count)
    out = {name: None if values is None else np.interp(grid, time_s, values)
           for name, values in signals.items()}
    return grid, out, interval, True, spread


def read_sweep(path, columns=None):
    """Read a sweep recording.

    Parameters
    ----------
    path : str or Path
        CSV with a header naming time, command and position columns (optionally current and
        current_command) and their units.
    columns : dict, optional
        ``role -> header cell`` naming columns outright.

    Returns
    -------
    SweepRecording

    Raises
    ------
    ConfigError
        (a ValueError) naming the file (and line) for what
        :func:`~cas_freq.identification.recordings.read_columns` rejects, no command column,
        fewer than :data:`MIN_SAMPLES` rows, a command that does not oscillate.
    """
    path = str(path)
    arrays, lines, found = read_columns(path, columns)
    if "command" not in found:
        raise ConfigError(f"{path}: line {lines[0] - 1 if lines else 1}: a sweep recording "
                          f"needs a command column; accepted: {accepted_names('command')}")
    t = arrays["time"]
    if t.size < MIN_SAMPLES:
        raise ConfigError(f"{path}: {t.size} samples (lines {lines[0]} to {lines[-1]}); a "
                          f"frequency response needs at least {MIN_SAMPLES}")
    command = arrays["command"]
    if not is_sweep(command):
        raise ConfigError(f"{path}: column {found['command'].header!r}: the command crosses "
                          f"its median {median_crossings(command)} times (lines {lines[0]} to "
                          f"{lines[-1]}); a sweep's oscillates (at least {MIN_CROSSINGS}), is "
                          "this a step recording?")
    grid, signals, interval, resampled, spread = uniform(t, {
        "command": command, "position": arrays["position"],
        "current": arrays.get("current"), "current_command": arrays.get("current_command"),
    })
    return SweepRecording(
        time_s=grid, command_rad=signals["command"], position_rad=signals["position"],
        current_a=signals["current"], current_command_a=signals["current_command"],
        interval_s=interval, samples=int(t.size), resampled=resampled,
        interval_spread=spread, source=path,
    )


__all__ = ["MIN_SAMPLES", "SweepRecording", "is_sweep", "median_crossings", "read_sweep",
           "recording_kind", "uniform"]
