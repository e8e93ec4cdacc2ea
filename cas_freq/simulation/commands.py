r"""Command signals at the output, with the rate and acceleration the feed-forward needs.

Each command gives the output angle :math:`\delta_{cmd}(t)` [rad] and its first two derivatives;
the loops are closed on the motor shaft, so the simulator uses
:math:`\theta_{cmd} = N \delta_{cmd}` (:func:`motor_command`, docs/model.md). Amplitudes and
frequencies may be arrays of shape (n_runs,): ``Step(np.radians([1, 5, 10]))`` is three runs.

A step has no usable derivative (docs/model.md): its rate and acceleration are 0, so the
feed-forward does nothing. Corners (start of a ramp, ends of table segments) likewise
contribute no impulse.
"""

import dataclasses
import math
import re
from pathlib import Path

import numpy as np

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.fileio import csv_row, read_input


def _since(t, start):
    return np.asarray(t, dtype=float) - start


def _after(t, start, left):
    """Whether ``t`` is past ``start``: from ``start`` on (right limit) or only after it (left)."""
    t = np.asarray(t, dtype=float)
    return t > start if left else t >= start


def fin_limits(command, t):
    """Right and left limits of a command at ``t``: ``(command.fin(t), command.fin(t,
    left=True))``, from one evaluation where the command offers it (:meth:`Sine.fin_limits`)."""
    both = getattr(command, "fin_limits", None)
    if both is not None:
        return both(t)
    return command.fin(t), command.fin(t, left=True)


@dataclasses.dataclass(frozen=True, eq=False)
class Step:
    """Step of ``amplitude_rad`` [rad] at the output at ``start_s`` [s]."""

    amplitude_rad: float | np.ndarray
    start_s: float = 0.0

    #: The response of a step settles: the simulator may extend its horizon until it does.
    settles = True
    duration_s = None

    def fin(self, t, left=False):
        """Angle [rad], rate [rad/s], accel. [rad/s^2] at ``t`` [s] (left limits if ``left``)."""
        angle = np.where(_after(t, self.start_s, left), self.amplitude_rad, 0.0)
        return angle, np.zeros_like(angle), np.zeros_like(angle)

    def fin_limits(self, t):
        """``(fin(t), fin(t, left=True))``, the two limits sharing their zero rate and
        acceleration (one array, read only)."""
        right, left = (np.where(_after(t, self.start_s, side), self.amplitude_rad, 0.0)
                       for side in (False, True))
        zero = np.zeros_like(right)
        zero.flags.writeable = False
        return (right, zero, zero), (left, zero, zero)

    def final_rad(self):
        """The value the command holds at the end [rad]."""
        return np.asarray(self.amplitude_rad, dtype=float)

    def held_from(self):
        """The time [s] after which the command holds its value (the latest start)."""
        return float(np.asarray(self.start_s, dtype=float).max())


@dataclasses.dataclass(frozen=True, eq=False)
class Ramp:
    """Ramp at ``rate_rad_s`` [rad/s] from ``start_s`` [s], holding from ``stop_s`` [s] if given."""

    rate_rad_s: float | np.ndarray
    start_s: float = 0.0
    stop_s: float | None = None

    duration_s = None

    @property
    def settles(self):
        """A ramp that stops settles; one that does not, never does."""
        return self.stop_s is not None

    def fin(self, t, left=False):
        """Angle [rad], rate [rad/s], accel. [rad/s^2] at ``t`` [s] (left limits if ``left``)."""
        tau = _since(t, self.start_s)
        length = math.inf if self.stop_s is None else self.stop_s - self.start_s
        moving = _after(tau, 0.0, left) & ~_after(tau, length, left)
        angle = self.rate_rad_s * np.clip(tau, 0.0, length)
        rate = np.where(moving, self.rate_rad_s, 0.0)
        return angle, rate, np.zeros_like(angle)

    def final_rad(self):
        """The value the command holds at the end [rad] (only for a ramp that stops)."""
        return np.asarray(self.rate_rad_s * (self.stop_s - self.start_s), dtype=float)


@dataclasses.dataclass(frozen=True, eq=False)
class Sine:
    """``amplitude_rad * sin(frequency_rad_s * (t - start_s))`` from ``start_s`` [s] on."""

    amplitude_rad: float | np.ndarray
    frequency_rad_s: float | np.ndarray
    start_s: float = 0.0

    settles = False
    duration_s = None

    def fin(self, t, left=False):
        """Angle [rad], rate [rad/s], accel. [rad/s^2] at ``t`` [s] (left limits if ``left``)."""
        tau = _since(t, self.start_s)
        return self._fin(tau, *self._sine_cosine(tau), left)

    def fin_limits(self, t):
        """``(fin(t), fin(t, left=True))``, the sine and cosine computed once for both; the
        same arrays for both where no time is the start (the limits differ only there)."""
        tau = _since(t, self.start_s)
        sine, cosine = self._sine_cosine(tau)
        right = self._fin(tau, sine, cosine, False)
        if not np.any(tau == 0.0):
            return right, right
        return right, self._fin(tau, sine, cosine, True)

    def _sine_cosine(self, tau):
        phase = self.frequency_rad_s * np.maximum(tau, 0.0)
        return np.sin(phase), np.cos(phase)  # once each (the dwell's costliest part)

    def _fin(self, tau, sine, cosine, left):
        w = self.frequency_rad_s
        a = np.where(_after(tau, 0.0, left), self.amplitude_rad, 0.0)  # 0 before the start
        angle = a * sine
        return angle, a * w * cosine, -(w * w) * angle


@dataclasses.dataclass(frozen=True, eq=False)
class Chirp:
    r"""Swept sine from ``start_rad_s`` to ``stop_rad_s`` [rad/s] over ``duration_s`` [s].

    ``method="linear"``: :math:`\omega(\tau) = \omega_0 + (\omega_1 - \omega_0)\tau/D`;
    ``method="log"``: :math:`\omega(\tau) = \omega_0 (\omega_1/\omega_0)^{\tau/D}`; the angle
    is :math:`A \sin\varphi(\tau)` with :math:`\varphi = \int_0^\tau \omega`, and it holds its
    last value after the sweep.
    """

    amplitude_rad: float | np.ndarray
    start_rad_s: float
    stop_rad_s: float
    duration_s: float
    method: str = "linear"
    start_s: float = 0.0

    settles = False

    def __post_init__(self):
        if self.method not in ("linear", "log"):
            raise ConfigError(f"chirp: method must be 'linear' or 'log', got {self.method!r}")
        if not self.duration_s > 0:
            raise ConfigError(f"chirp: duration_s must be > 0 s, got {self.duration_s!r}")
        low = 0.0 if self.method == "linear" else None
        for name in ("start_rad_s", "stop_rad_s"):
            value = getattr(self, name)
            if not (value >= 0 if low == 0.0 else value > 0):
                rule = ">= 0" if low == 0.0 else "> 0 (log sweep)"
                raise ConfigError(f"chirp: {name} must be {rule} rad/s, got {value!r}")

    def fin(self, t, left=False):
        """Angle [rad], rate [rad/s], accel. [rad/s^2] at ``t`` [s] (left limits if ``left``)."""
        raw = _since(t, self.start_s)
        on = _after(raw, 0.0, left) & ~_after(raw, self.duration_s, left)
        tau = np.clip(raw, 0.0, self.duration_s)
        w0, w1, d = self.start_rad_s, self.stop_rad_s, self.duration_s
        if self.method == "linear":
            slope = (w1 - w0) / d
            w = w0 + slope * tau
            phase = w0 * tau + 0.5 * slope * tau**2
            dw = slope
        else:
            growth = math.log(w1 / w0) / d
            if growth == 0.0:
                w, phase, dw = w0 + 0.0 * tau, w0 * tau, 0.0
            else:
                w = w0 * np.exp(growth * tau)
                phase = w0 * np.expm1(growth * tau) / growth
                dw = growth * w
        a = self.amplitude_rad
        angle = np.where(raw >= 0, a * np.sin(phase), 0.0)
        rate = np.where(on, a * w * np.cos(phase), 0.0)
        accel = np.where(on, a * (dw * np.cos(phase) - w**2 * np.sin(phase)), 0.0)
        return angle, rate, accel


@dataclasses.dataclass(frozen=True, eq=False)
class Table:
    """Piecewise-linear command through (``time_s`` [s], ``angle_rad`` [rad]) points.

    The angle holds its first value before the first point and its last value after the last;
    the rate is each segment's slope and the acceleration is 0.
    """

    time_s: np.ndarray
    angle_rad: np.ndarray
    source: str = "table"

    settles = True

    def __post_init__(self):
        time = np.asarray(self.time_s, dtype=float)
        angle = np.asarray(self.angle_rad, dtype=float)
        if time.ndim != 1 or time.shape != angle.shape or time.size < 2:
            raise ConfigError(f"{self.source}: need at least 2 (time, angle) points")
        if not (np.isfinite(time).all() and np.isfinite(angle).all()):
            raise ConfigError(f"{self.source}: times and angles must be finite")
        if np.any(np.diff(time) <= 0):
            raise ConfigError(f"{self.source}: times must increase strictly")
        object.__setattr__(self, "time_s", time)
        object.__setattr__(self, "angle_rad", angle)

    @property
    def duration_s(self):
        """Time of the last point [s]."""
        return float(self.time_s[-1])

    def fin(self, t, left=False):
        """Angle [rad], rate [rad/s], accel. [rad/s^2] at ``t`` [s] (left limits if ``left``)."""
        t = np.asarray(t, dtype=float)
        angle = np.interp(t, self.time_s, self.angle_rad)
        slopes = np.diff(self.angle_rad) / np.diff(self.time_s)
        segment = np.searchsorted(self.time_s, t, side="left" if left else "right") - 1
        inside = (segment >= 0) & (segment < slopes.size)
        rate = np.where(inside, slopes[np.clip(segment, 0, slopes.size - 1)], 0.0)
        return angle, rate, np.zeros_like(angle)

    def final_rad(self):
        """The value the command holds at the end [rad]."""
        return np.asarray(self.angle_rad[-1])


@dataclasses.dataclass(frozen=True, eq=False)
class Recorded:
    """A recorded command through (``time_s`` [s], ``angle_rad`` [rad]) samples: a cubic
    interpolating spline (not-a-knot, :class:`scipy.interpolate.CubicSpline`), whose first and
    second derivatives are the rate and acceleration the feed-forward needs.

    For a smooth move (a drive's profile, recorded with its position demand) the spline's
    derivatives stand in for the velocity and acceleration demands the drive used; a command
    with jumps (a step) belongs in :class:`Step`. The angle holds its first value before the
    first sample and its last after the last, with rate and acceleration 0 there.
    """

    time_s: np.ndarray
    angle_rad: np.ndarray
    source: str = "recorded command"

    settles = True

    def __post_init__(self):
        from scipy.interpolate import CubicSpline

        Table(self.time_s, self.angle_rad, self.source)  # the same checks as a table's
        time = np.asarray(self.time_s, dtype=float)
        angle = np.asarray(self.angle_rad, dtype=float)
        object.__setattr__(self, "time_s", time)
        object.__setattr__(self, "angle_rad", angle)
        object.__setattr__(self, "_spline", CubicSpline(time, angle))

    @property
    def duration_s(self):
        """Time of the last sample [s]."""
        return float(self.time_s[-1])

    def fin(self, t, left=False):
        """Angle [rad], rate [rad/s], accel. [rad/s^2] at ``t`` [s] (``left`` is the same: the
        spline is smooth)."""
        t = np.asarray(t, dtype=float)
        inside = (t >= self.time_s[0]) & (t <= self.time_s[-1])
        clipped = np.clip(t, self.time_s[0], self.time_s[-1])
        angle = self._spline(clipped)
        rate = np.where(inside, self._spline(clipped, 1), 0.0)
        accel = np.where(inside, self._spline(clipped, 2), 0.0)
        return angle, rate, accel

    def final_rad(self):
        """The value the command holds at the end [rad]."""
        return np.asarray(self.angle_rad[-1])


@dataclasses.dataclass(frozen=True, eq=False)
class Profile:
    r"""Trapezoidal move of ``distance_rad`` [rad] at the output from ``start_s`` [s], as a drive's
    profile position mode moves (the EPOS4's, with profile velocity, acceleration and
    deceleration; docs/model.md, "Profile moves").

    The speed rises at ``acceleration_rad_s2`` to the peak speed, holds it, and falls at
    ``deceleration_rad_s2`` (default: the acceleration) to stop at the target; the acceleration
    is piecewise constant. With distance :math:`D = |	ext{distance}|`, limits :math:`v, a, d`:

    .. math::

        v_p = \min\left(v, \sqrt{rac{2 D a d}{a + d}}
ight),\quad
        t_a = rac{v_p}{a},\quad t_d = rac{v_p}{d},\quad
        t_c = rac{D}{v_p} - rac{v_p}{2a} - rac{v_p}{2d}

    and the move lasts :math:`T = t_a + t_c + t_d`: a trapezoid when the distance is long enough
    to reach :math:`v` (:math:`t_c > 0`), a triangle (:math:`t_c = 0`) otherwise. A negative
    distance moves the other way. Limits are positive speeds and accelerations (their
    magnitudes); the distance may be an array of shape (n_runs,), the limits scalars.
    """

    distance_rad: float | np.ndarray
    velocity_rad_s: float
    acceleration_rad_s2: float
    deceleration_rad_s2: float | None = None
    start_s: float = 0.0

    #: The response to a move settles: the simulator may extend its horizon until it does.
    settles = True

    def __post_init__(self):
        distance = np.asarray(self.distance_rad, dtype=float)
        if not (np.all(np.isfinite(distance)) and np.all(distance != 0)):
            raise ConfigError(f"profile: distance must be finite and non-zero [rad], got "
                              f"{self.distance_rad!r}")
        if self.deceleration_rad_s2 is None:
            object.__setattr__(self, "deceleration_rad_s2", self.acceleration_rad_s2)
        for name, unit in (("velocity_rad_s", "rad/s"), ("acceleration_rad_s2", "rad/s^2"),
                           ("deceleration_rad_s2", "rad/s^2")):
            value = getattr(self, name)
            ok = isinstance(value, (int, float, np.floating, np.integer)) and \
                not isinstance(value, bool) and math.isfinite(value) and value > 0
            if not ok:
                raise ConfigError(f"profile: {name} must be a finite number > 0 {unit}, "
                                  f"got {value!r}")
        if not (isinstance(self.start_s, (int, float)) and math.isfinite(self.start_s)
                and self.start_s >= 0):
            raise ConfigError(f"profile: start_s must be a finite time >= 0 s, got "
                              f"{self.start_s!r}")
        object.__setattr__(self, "distance_rad", distance if distance.ndim else float(distance))

    @property
    def peak_rate_rad_s(self):
        """Largest speed of the move [rad/s] (> 0): the velocity limit, or less (a triangle)."""
        a, d = self.acceleration_rad_s2, self.deceleration_rad_s2
        reach = np.sqrt(2.0 * np.abs(self.distance_rad) * a * d / (a + d))
        return np.minimum(self.velocity_rad_s, reach)

    def phases(self):
        """(t_a, t_c, t_d) [s]: accelerating, cruising and decelerating times of the move."""
        peak = self.peak_rate_rad_s
        a, d = self.acceleration_rad_s2, self.deceleration_rad_s2
        cruise = np.abs(self.distance_rad) / peak - 0.5 * peak / a - 0.5 * peak / d
        return peak / a, np.maximum(cruise, 0.0), peak / d

    @property
    def move_time_s(self):
        """How long the move lasts [s] (the largest of a batch's)."""
        return float(np.max(sum(self.phases())))

    @property
    def duration_s(self):
        """Time the move ends [s] (from t = 0, as :attr:`Table.duration_s`)."""
        return self.start_s + self.move_time_s

    def fin(self, t, left=False):
        """Angle [rad], rate [rad/s], accel. [rad/s^2] at ``t`` [s] (left limits if ``left``)."""
        tau = _since(t, self.start_s)
        t_a, t_c, t_d = self.phases()
        t_2 = t_a + t_c  # the deceleration starts
        total = t_2 + t_d
        sign = np.sign(self.distance_rad)
        a, d = self.acceleration_rad_s2, self.deceleration_rad_s2
        peak, distance = self.peak_rate_rad_s, np.abs(self.distance_rad)
        accelerating = _after(tau, 0.0, left) & ~_after(tau, t_a, left)
        cruising = _after(tau, t_a, left) & ~_after(tau, t_2, left)
        decelerating = _after(tau, t_2, left) & ~_after(tau, total, left)
        # each phase's closed form on its own interval, clipped so that the angle is continuous
        rising = np.clip(tau, 0.0, t_a)
        remaining = np.clip(total - tau, 0.0, t_d)
        angle = np.where(tau < t_a, 0.5 * a * rising**2,
                         np.where(tau < t_2, 0.5 * a * t_a**2 + peak * (tau - t_a),
                                  distance - 0.5 * d * remaining**2))
        rate = np.where(accelerating, a * rising, 0.0) + np.where(cruising, peak, 0.0) \
            + np.where(decelerating, d * remaining, 0.0)
        accel = np.where(accelerating, a, 0.0) - np.where(decelerating, d, 0.0)
        return sign * angle, sign * rate, sign * accel

    def final_rad(self):
        """The value the command holds at the end [rad]."""
        return np.asarray(self.distance_rad, dtype=float)


def read_command_csv(path):
    """Read a user command: time [s] >= 0 and output angle [deg], as :func:`read_angle_series_csv`.

    Parameters
    ----------
    path : str or Path
        CSV file (comma-separated; lines starting with ``#`` are skipped).

    Returns
    -------
    Table
        The command in SI (angles converted to rad).

    Raises
    ------
    ConfigError
        (a ValueError) naming the file and row of the first bad value.
    """
    time_s, angle_rad = read_angle_series_csv(path, what="command file")
    return Table(time_s, angle_rad, source=str(path))


#: Header names of the time column (any case), with their accepted units and scale to s. A
#: cell names its unit in brackets (``t [s]``) or parentheses, or as a suffix (``time_s``);
#: without one, s.
TIME_COLUMN = (("t", "time"), {"s": 1.0, "ms": 1e-3})
#: Header names of the output-angle column, best first (``delta`` is what ``simulate --csv``
#: writes beside ``command_output``; ``fin_angle`` and ``fin`` are the names of older files),
#: and their units; without one, deg.
ANGLE_COLUMN = (("delta", "output_angle", "fin_angle", "fin", "angle"),
                {"deg": math.pi / 180.0, "rad": 1.0})
_TIME_ACCEPTED = "t or time, in s or ms (e.g. 't [s]', 'time_s')"
_ANGLE_ACCEPTED = "delta, output_angle, fin_angle, fin or angle, in deg or rad (e.g. " \
    "'delta [deg]', 'output_angle_deg')"


def _header_cell(cell):
    """(name, unit or None) of a header cell: ``'delta [deg]'`` → ('delta', 'deg'),
    ``'time_s'`` → ('time', 's'), ``'t'`` → ('t', None); lower case."""
    text = cell.strip().lower()
    match = re.fullmatch(r"(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]", text)
    if match:
        return match.group(1), match.group(2)
    name, _, suffix = text.rpartition("_")
    if name and suffix in {*TIME_COLUMN[1], *ANGLE_COLUMN[1]}:
        return name, suffix
    return text, None


def _find_column(path, row_number, cells, column, accepted):
    """(index, scale) of the first header cell naming ``column`` (names best first), or None.

    Raises ConfigError for a named column in a unit that is not accepted.
    """
    names, units = column
    found = {}
    for index, cell in enumerate(cells):
        name, unit = _header_cell(cell)
        if name in names and name not in found:
            if unit is not None and unit not in units:
                raise ConfigError(f"{path}: row {row_number}: column {cell.strip()!r}: unit "
                                  f"{unit!r} not accepted; expected {accepted}")
            found[name] = (index, units[unit if unit is not None else next(iter(units))])
    return next((found[name] for name in names if name in found), None)


def _header_columns(path, row_number, cells):
    """Columns and scales ``((time index, to s), (angle index, to rad))`` of a header row.

    A header naming both a time and an output-angle column (:data:`TIME_COLUMN`,
    :data:`ANGLE_COLUMN`) selects them, whatever else it holds. A two-column header is time
    and angle whatever it names: a column it names is read in the unit it gives, the other is
    the remaining column (time [s] first, angle [deg] second when it names neither).
    """
    time = _find_column(path, row_number, cells, TIME_COLUMN, _TIME_ACCEPTED)
    angle = _find_column(path, row_number, cells, ANGLE_COLUMN, _ANGLE_ACCEPTED)
    if len(cells) == 2 and (time is None or angle is None):
        if time is None:
            time = (0 if angle is None else 1 - angle[0], 1.0)
        if angle is None:
            angle = (1 - time[0], math.pi / 180.0)
    if time is not None and angle is not None:
        return time, angle
    missing = [f"no {what} column ({accepted})"
               for what, accepted, found in (("time", _TIME_ACCEPTED, time),
                                             ("output angle", _ANGLE_ACCEPTED, angle))
               if found is None]
    shown = ", ".join(repr(cell.strip()[:40]) for cell in cells[:12])
    raise ConfigError(f"{path}: row {row_number}: the header names {' and '.join(missing)}; "
                      f"got {shown}{', ...' if len(cells) > 12 else ''}")


def _cut(row, limit=80):
    """``repr`` of a row, cut to about ``limit`` characters for a message."""
    text = repr(row)
    return text if len(text) <= limit else text[:limit - 5] + " ...]"


def read_angle_series_csv(path, negative_times=False, what="CSV file"):
    """Read an output-angle time series: a time column and an output angle column.

    Either two columns, time [s] and output angle [deg], with an optional header; or a header
    naming the columns (:data:`TIME_COLUMN`, :data:`ANGLE_COLUMN`: ``t [s]`` or ``time_s``,
    ``delta [deg]`` or ``output_angle_deg``, ...), which selects them and their units among any
    number of columns: the CSV that ``cas-freq simulate --csv`` writes (``t [s]``,
    ``command_output [deg]``, ``delta [deg]``, ...; ``command_fin`` in older files) is read as
    time and ``delta``.

    Parameters
    ----------
    path : str or Path
        CSV file (comma-separated; lines starting with ``#`` are skipped).
    negative_times : bool
        Accept times before 0 (a measured response with pre-trigger samples).
    what : str
        What the file is, for messages (:func:`cas_freq.core.fileio.read_input`).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Times [s], strictly increasing, and angles [rad].

    Raises
    ------
    ConfigError
        (a ValueError) naming the file and row of the first bad value, or what a header
        lacks.
    """
    path = Path(path)
    text = read_input(path, what)
    times, angles = [], []
    columns, width = ((0, 1.0), (1, math.pi / 180.0)), 2
    first = True
    for row_number, line in enumerate(text.splitlines(), start=1):
        row = csv_row(path, row_number, line)
        if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
            continue
        if first:
            first = False
            try:
                [float(cell) for cell in row]
            except ValueError:  # a header row
                columns, width = _header_columns(path, row_number, row), len(row)
                continue
        if len(row) != width:
            raise ConfigError(f"{path}: row {row_number}: expected {width} columns, got "
                              f"{len(row)}")
        (time_index, time_scale), (angle_index, angle_scale) = columns
        try:
            time = float(row[time_index]) * time_scale
            angle = float(row[angle_index]) * angle_scale
        except ValueError:
            raise ConfigError(f"{path}: row {row_number}: not numbers: {_cut(row)}") from None
        if not (math.isfinite(time) and math.isfinite(angle)):
            raise ConfigError(f"{path}: row {row_number}: values must be finite, got {_cut(row)}")
        if times and time <= times[-1]:
            raise ConfigError(
                f"{path}: row {row_number}: time {time:g} s does not increase "
                f"(previous {times[-1]:g} s)"
            )
        if time < 0 and not negative_times:
            raise ConfigError(f"{path}: row {row_number}: time must be >= 0 s, got {time:g}")
        times.append(time)
        angles.append(angle)
    if len(times) < 2:
        raise ConfigError(f"{path}: need at least 2 rows of (time [s], angle [deg])")
    return np.array(times), np.array(angles)


def motor_command(command, ratio, t, left=False):
    """Motor-angle command :math:`\\theta_{cmd} = N \\delta_{cmd}` and its derivatives.

    Parameters
    ----------
    command : Step, Ramp, Sine, Chirp, Table or Profile
        Output command.
    ratio : float or numpy.ndarray
        Gear ratio N [-].
    t : numpy.ndarray
        Times [s].
    left : bool
        Left limits (values just before ``t``) instead of right limits: they differ only where the
        command jumps (a step at ``t``) or its rate does.

    Returns
    -------
    tuple of numpy.ndarray
        Angle [rad], rate [rad/s], acceleration [rad/s^2] at the motor.
    """
    return tuple(ratio * part for part in command.fin(t, left=left))


def condition_profile(condition):
    """The :class:`Profile` of a config's profile condition
    (:class:`cas_freq.config.requirement.ProfileCondition`)."""
    return Profile(condition.distance, condition.velocity, condition.acceleration,
                   condition.deceleration)
