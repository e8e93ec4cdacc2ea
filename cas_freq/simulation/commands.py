r"""Command signals at the fin, with the rate and acceleration the feed-forward needs.

Each command gives the fin angle :math:`\delta_{cmd}(t)` [rad] and its first two derivatives;
the loops are closed on the motor shaft, so the simulator uses
:math:`\theta_{cmd} = N \delta_{cmd}` (:func:`motor_command`, docs/model.md). Amplitudes and
frequencies may be arrays of shape (n_runs,): ``Step(np.radians([1, 5, 10]))`` is three runs.

A step has no usable derivative (docs/model.md): its rate and acceleration are 0, so the
feed-forward does nothing. Corners (start of a ramp, ends of table segments) likewise
contribute no impulse.
"""

import csv
import dataclasses
import math
from pathlib import Path

import numpy as np

from cas_freq.exceptions import ConfigError


def _since(t, start):
    return np.asarray(t, dtype=float) - start


def _after(t, start, left):
    """Whether ``t`` is past ``start``: from ``start`` on (right limit) or only after it (left)."""
    t = np.asarray(t, dtype=float)
    return t > start if left else t >= start


@dataclasses.dataclass(frozen=True, eq=False)
class Step:
    """Step of ``amplitude_rad`` [rad] at the fin at ``start_s`` [s]."""

    amplitude_rad: float | np.ndarray
    start_s: float = 0.0

    #: The response of a step settles: the simulator may extend its horizon until it does.
    settles = True
    duration_s = None

    def fin(self, t, left=False):
        """Angle [rad], rate [rad/s], accel. [rad/s^2] at ``t`` [s] (left limits if ``left``)."""
        angle = np.where(_after(t, self.start_s, left), self.amplitude_rad, 0.0)
        return angle, np.zeros_like(angle), np.zeros_like(angle)

    def final_rad(self):
        """The value the command holds at the end [rad]."""
        return np.asarray(self.amplitude_rad, dtype=float)


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
        on = _after(tau, 0.0, left)
        w = self.frequency_rad_s
        phase = w * np.maximum(tau, 0.0)
        a = self.amplitude_rad
        return (
            np.where(on, a * np.sin(phase), 0.0),
            np.where(on, a * w * np.cos(phase), 0.0),
            np.where(on, -a * w**2 * np.sin(phase), 0.0),
        )


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


def read_command_csv(path):
    """Read a user command: two columns, time [s] >= 0 and fin angle [deg]; an optional header.

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
    time_s, angle_rad = read_angle_series_csv(path)
    return Table(time_s, angle_rad, source=str(path))


def read_angle_series_csv(path, negative_times=False):
    """Read a fin-angle time series: time [s] and angle [deg] columns, an optional header.

    Parameters
    ----------
    path : str or Path
        CSV file (comma-separated; lines starting with ``#`` are skipped).
    negative_times : bool
        Accept times before 0 (a measured response with pre-trigger samples).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Times [s], strictly increasing, and angles [rad].

    Raises
    ------
    ConfigError
        (a ValueError) naming the file and row of the first bad value.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the file ({exc})") from None
    times, angles = [], []
    for row_number, row in enumerate(csv.reader(text.splitlines()), start=1):
        if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
            continue
        if len(row) != 2:
            raise ConfigError(f"{path}: row {row_number}: expected 2 columns, got {len(row)}")
        try:
            time, angle = float(row[0]), float(row[1])
        except ValueError:
            if not times:  # a header row
                continue
            raise ConfigError(f"{path}: row {row_number}: not numbers: {row!r}") from None
        if not (math.isfinite(time) and math.isfinite(angle)):
            raise ConfigError(f"{path}: row {row_number}: values must be finite, got {row!r}")
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
    return np.array(times), np.radians(angles)


def motor_command(command, ratio, t, left=False):
    """Motor-angle command :math:`\\theta_{cmd} = N \\delta_{cmd}` and its derivatives.

    Parameters
    ----------
    command : Step, Ramp, Sine, Chirp or Table
        Fin command.
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
