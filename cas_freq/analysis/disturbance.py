r"""The closed loop's figures besides the command (what the flight-control system sees of a
control surface): the dynamic stiffness, the control effort and the current of the encoder's
quantisation noise (docs/model.md, "15. Stiffness, effort and noise": "Dynamic stiffness",
"Disturbance and noise").

Each is read from the continuous loops' responses of :mod:`cas_freq.model.disturbance` and
:mod:`cas_freq.model.loops` on the analysis grid, a minimum or a peak refined by a bounded
search on log frequency between its grid neighbours. With sampled controllers the figures are
those of the same loops run continuously (said in ``note``). Only a stable closed loop has
them: an unstable loop's responses have no steady state.
"""

import dataclasses
import math

import numpy as np

from cas_freq.analysis.roots import refine_maxima
from cas_freq.config.wording import GENERIC
from cas_freq.model.delay import EXACT
from cas_freq.model.disturbance import encoder_weights, load_response, noise_current
from cas_freq.model.loops import Selector, responses
from cas_freq.model.structure import build

#: Grid density of the noise integral [points per decade].
NOISE_POINTS_PER_DECADE = 400

_CONTINUOUS = "the continuous loops' figure: the controllers are sampled"
_UNSTABLE = "the closed loop is not stable"


@dataclasses.dataclass(frozen=True)
class Stiffness:
    """The dynamic stiffness 1/|delta/M(j omega)| of the output, every loop closed.

    ``minimum`` is in N*m/rad at a rotary output, N/m at a linear one (``linear``); the JSON
    names it ``min_N_m_per_rad`` or ``min_N_per_m``. None (with ``note``) where it does not
    exist.
    """

    minimum: float | None
    min_at_rad_s: float | None
    linear: bool = False
    at_range_edge: bool | None = None
    note: str = ""

    @property
    def min_N_m_per_rad(self):  # noqa: N802 (the figure's name, unit included)
        """The minimum at a rotary output [N*m/rad], None at a linear one."""
        return None if self.linear else self.minimum

    @property
    def min_N_per_m(self):  # noqa: N802
        """The minimum at a linear output [N/m], None at a rotary one."""
        return self.minimum if self.linear else None

    def to_json(self):
        """The ``stiffness`` section of analyze's JSON."""
        key = "min_N_per_m" if self.linear else "min_N_m_per_rad"
        return {key: self.minimum, "min_at_rad_s": self.min_at_rad_s,
                "min_at_range_edge": self.at_range_edge, "note": self.note}


@dataclasses.dataclass(frozen=True)
class Effort:
    """The control effort |i/delta_cmd(j omega)| (without feed-forward): its peak and where.

    ``peak`` is in A/rad at a rotary output, A/m at a linear one.
    """

    peak: float | None
    peak_at_rad_s: float | None
    linear: bool = False
    note: str = ""

    @property
    def peak_A_per_rad(self):  # noqa: N802
        """The peak at a rotary output [A/rad]."""
        return None if self.linear else self.peak

    @property
    def peak_A_per_m(self):  # noqa: N802
        """The peak at a linear output [A/m]."""
        return self.peak if self.linear else None

    def to_json(self):
        """The ``effort`` section of analyze's JSON."""
        key = "peak_A_per_m" if self.linear else "peak_A_per_rad"
        return {key: self.peak, "peak_at_rad_s": self.peak_at_rad_s, "note": self.note}


@dataclasses.dataclass(frozen=True)
class Noise:
    """The RMS motor current from the encoder's quantisation noise, through the controllers.

    Attributes
    ----------
    current_rms_A : float or None
        RMS current [A]; None (``note`` says why) without ``sensors.counts_per_rev``.
    counts_per_rev : float or None
        The encoder's counts per revolution.
    quantum_rad : float or None
        q = 2 pi/counts [rad] of the angle the encoder reads.
    band_rad_s : float or None
        The noise is white over 0..band [rad/s].
    note : str
    """

    current_rms_A: float | None  # noqa: N815
    counts_per_rev: float | None = None
    quantum_rad: float | None = None
    band_rad_s: float | None = None
    note: str = ""

    def to_json(self):
        """The ``noise`` section of analyze's JSON."""
        return dataclasses.asdict(self)


def _refined(fun, omega, values, index):
    """The extremum ``values[index]`` (a minimum of ``fun``, frequencies [rad/s] -> values)
    refined between the grid points around it (:func:`~cas_freq.analysis.roots.refine_maxima`
    of -``fun`` in log frequency): (frequency, value)."""
    if 0 < index < omega.size - 1:
        x = np.log(omega[index - 1:index + 2])
        at, value = refine_maxima(lambda v, _: -fun(np.exp(v)), x[:1], x[2:],
                                  *(-values[index - 1:index + 2, None]), mid=x[1:2])
        if -value[0] < values[index]:
            return float(at[0]), float(-value[0])
    return float(omega[index]), float(values[index])


def stiffness(p, omega, linear=False, delay=EXACT):
    """The :class:`Stiffness` of one run ``p`` (a :class:`~cas_freq.model.loops.Selector`'s
    call) on the grid ``omega`` [rad/s]."""
    def fun(w):
        return 1.0 / np.abs(load_response(p, 1j * np.atleast_1d(w), delay))

    values = fun(omega)
    index = int(np.argmin(values))
    at, value = _refined(fun, omega, values, index)
    return Stiffness(value, at, linear, index in (0, omega.size - 1))


def effort(p, omega, linear=False, delay=EXACT):
    """The :class:`Effort` of one run ``p`` on the grid ``omega`` [rad/s]."""
    def fun(w):
        current = responses(p, 1j * np.atleast_1d(w), delay=delay, output="current")
        return -np.abs(p.ratio * current.closed_loop)

    values = fun(omega)
    index = int(np.argmin(values))
    at, value = _refined(fun, omega, values, index)
    note = "" if 0 < index < omega.size - 1 else "the peak lies at an end of the analysed range"
    return Effort(-value, at, linear, note)


def noise(p, low, band, counts_per_rev, delay=EXACT):
    r"""The :class:`Noise` of one run ``p``: quantisation noise of variance
    :math:`q^2/12` (:math:`q = 2\pi`/counts) white over 0..``band`` [rad/s] on the angle the
    position loop's encoder reads, through :func:`~cas_freq.model.disturbance.noise_current`:
    :math:`i_{rms}^2 = \frac{q^2}{12\,\omega_b} \int_0^{\omega_b} |i/\nu(j\omega)|^2 d\omega`,
    by the trapezoid rule on a log grid from ``low`` (below it |i/nu| is taken as at ``low``).
    """
    weights = encoder_weights(p)
    quantum = 2.0 * math.pi / counts_per_rev
    points = max(int(NOISE_POINTS_PER_DECADE * math.log10(band / low)), 2) + 1
    w = np.geomspace(low, band, points)
    power = np.abs(noise_current(p, 1j * w, weights, delay)) ** 2
    integral = power[0] * low + float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(w)))
    rms = quantum / math.sqrt(12.0) * math.sqrt(integral / band)
    return Noise(rms, float(counts_per_rev), quantum, float(band))


def disturbance_figures(params, omega, counts_per_rev=None, words=GENERIC, stable=True,
                        delay=EXACT):
    """(Stiffness, Effort, Noise) of one variant.

    Parameters
    ----------
    params : cas_freq.core.parameters.LoopParameters
        One variant.
    omega : numpy.ndarray
        The analysis grid [rad/s] (its ends bound every search and, for continuous
        controllers, the noise's band).
    counts_per_rev : float or None
        ``sensors.counts_per_rev``.
    words : cas_freq.config.wording.OutputWords
        The config's output: a linear one has figures per m; the notes name it.
    stable : bool
        The closed loop's verdict: only a stable loop has these figures.
    """
    linear = words.linear
    rates = dict(getattr(params, "sample_rates", ()) or ())
    p = Selector(params)()
    if rates:
        p.sample_rates = ()
    suffix = f"; {_CONTINUOUS}" if rates else ""
    if not stable:
        return (Stiffness(None, None, linear, None, _UNSTABLE),
                Effort(None, None, linear, _UNSTABLE), Noise(None, note=_UNSTABLE))
    stiff = stiffness(p, omega, linear, delay)
    stiff = dataclasses.replace(stiff, note=(
        ("the minimum lies at an end of the analysed range; " if stiff.at_range_edge else "")
        + f"{words.compliance} with every loop closed{suffix}"))
    push = effort(p, omega, linear, delay)
    push = dataclasses.replace(push, note=(push.note + "; " if push.note else "")
                               + f"{words.effort} without feed-forward{suffix}")
    return stiff, push, _noise(p, params, omega, counts_per_rev, rates, linear, delay)


def position_encoder_counts(config):
    """Counts per revolution of the encoder a validated config's position loop reads: the
    output's (``sensors.output_counts_per_rev``) with ``position_loop.feedback: output``, else
    the motor's (``sensors.counts_per_rev``); None if not given."""
    sensors = config.sensors
    if config.position_loop.feedback == "output":
        return sensors.output_counts_per_rev
    return sensors.counts_per_rev


def _noise(p, params, omega, counts_per_rev, rates, linear, delay):
    structure = build(p)
    on_output = structure.loops[-1].feedback == "output_angle"
    if linear and on_output:
        return Noise(None, note=("the position loop reads a linear output's encoder, whose "
                                 "resolution is not modelled"))
    if counts_per_rev is None:
        key = "sensors.output_counts_per_rev" if on_output else "sensors.counts_per_rev"
        return Noise(None, note=f"no {key} in the config (the encoder the position loop reads)")
    if "position_loop" in rates:
        band = math.pi * rates["position_loop"]
        where = (f"white up to the position loop's Nyquist frequency pi*f_s = {band:.6g} "
                 f"rad/s, through the continuous loops")
    else:
        band = float(omega[-1])
        where = f"white over the analysed band 0..{band:.6g} rad/s"
    found = noise(p, float(omega[0]), band, counts_per_rev, delay)
    encoder = ("the motor encoder (position loop"
               + (" and the speed the velocity loop derives from it)"
                  if len(encoder_weights(p, structure)) > 1 else ")")
               if structure.loops[-1].feedback == "motor_angle" else
               "the output encoder (position loop; the velocity loop's motor encoder left out)"
               if len(structure.loops) > 2 else "the output encoder (position loop)")
    return dataclasses.replace(found, note=(
        f"quantisation noise q^2/12, q = 2*pi/{counts_per_rev:g} rad, on {encoder}, {where}"))


def text_lines(stiff, push, noise, fmt, words=GENERIC):
    """The analyze text's block of these figures (``fmt(value, unit)`` formats a number) under
    ``words.seen``."""
    if stiff is None:
        return []
    per = "m" if stiff.linear else "rad"
    unit = "N/m" if stiff.linear else "N*m/rad"
    lines = [f"  {words.seen} (every loop closed)"]
    if stiff.minimum is None:
        lines.append(f"    not reported: {stiff.note}")
        return lines
    lines += [
        f"    dynamic stiffness  min {fmt(stiff.minimum, unit)} at "
        f"{fmt(stiff.min_at_rad_s, 'rad/s')}",
        f"    control effort     peak {fmt(push.peak, f'A/{per}')} at "
        f"{fmt(push.peak_at_rad_s, 'rad/s')}",
        "    encoder noise      " + (f"{fmt(noise.current_rms_A * 1e3, 'mA')} RMS"
                                     if noise.current_rms_A is not None else "not reported"),
    ]
    notes = [stiff.note, push.note, noise.note]
    lines += [f"    ({note})" for note in dict.fromkeys(notes) if note]
    return lines
