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

#: The prefixes of the figures computed here (cas_freq.core.figures): a study computes them
#: (:func:`batch_disturbance_figures`) where a requirement names one.
PREFIXES = ("stiffness.", "effort.", "noise.")

#: Runs evaluated together by :func:`batch_disturbance_figures` (bounds its memory: a few
#: complex arrays of runs x grid points, ~10 MB each on the analysis grid).
CHUNK = 256

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


def _least(fun, omega, n):
    """Each of ``n`` runs' least value of ``fun`` on the grid ``omega`` [rad/s], refined between
    the grid points around it (:func:`~cas_freq.analysis.roots.refine_maxima` of -``fun`` in
    log frequency) where it is not at an end of the grid.

    ``fun(which, w)``: the values of runs ``which`` (int array) at frequencies ``w`` [rad/s],
    shaped (len(which), m) on the grid or (len(which),) one per run.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        Frequency [rad/s], value and whether it lies at an end of the grid, each (n,).
    """
    every = np.arange(n)
    values = fun(every, np.broadcast_to(omega, (n, omega.size)))
    index = np.argmin(values, axis=1)
    at, least = omega[index].astype(float), values[every, index].astype(float)
    inner = np.flatnonzero((index > 0) & (index < omega.size - 1))
    if inner.size:
        x, i = np.log(omega), index[inner]
        found_at, found = refine_maxima(
            lambda v, which: -fun(inner[which], np.exp(v)), x[i - 1], x[i + 1],
            -values[inner, i - 1], -values[inner, i], -values[inner, i + 1], mid=x[i])
        better = -found < least[inner]
        at[inner[better]], least[inner[better]] = found_at[better], -found[better]
    return at, least, (index == 0) | (index == omega.size - 1)


def _stiffness_values(runs, delay):
    """``fun`` of :func:`_least` for the dynamic stiffness 1/|delta/M| (``runs(which, column)``:
    the runs' parameters, shaped (k, 1) with ``column``)."""
    def fun(which, w):
        p = runs(which, np.ndim(w) == 2)
        return 1.0 / np.abs(load_response(p, 1j * w, delay))
    return fun


def _effort_values(runs, delay):
    """``fun`` of :func:`_least` for minus the control effort |N i/delta_cmd| (no
    feed-forward)."""
    def fun(which, w):
        p = runs(which, np.ndim(w) == 2)
        current = responses(p, 1j * w, delay=delay, output="current")
        return -np.abs(p.ratio * current.closed_loop)
    return fun


def _one(p):
    """One run's parameters as ``runs(which, column)`` of :func:`_stiffness_values`."""
    return lambda which, column: p


def stiffness(p, omega, linear=False, delay=EXACT):
    """The :class:`Stiffness` of one run ``p`` (a :class:`~cas_freq.model.loops.Selector`'s
    call) on the grid ``omega`` [rad/s]."""
    at, value, edge = _least(_stiffness_values(_one(p), delay), omega, 1)
    return Stiffness(float(value[0]), float(at[0]), linear, bool(edge[0]))


def effort(p, omega, linear=False, delay=EXACT):
    """The :class:`Effort` of one run ``p`` on the grid ``omega`` [rad/s]."""
    at, value, edge = _least(_effort_values(_one(p), delay), omega, 1)
    note = "the peak lies at an end of the analysed range" if edge[0] else ""
    return Effort(float(-value[0]), float(at[0]), linear, note)


def _noise_rms(p, low, band, counts_per_rev, delay=EXACT):
    r"""RMS current [A] of the quantisation noise of :func:`noise`, of every run of ``p``
    (parameters shaped (k, 1), or one run's scalars): shape (k,) or ()."""
    weights = encoder_weights(p)
    quantum = 2.0 * math.pi / counts_per_rev
    points = max(int(NOISE_POINTS_PER_DECADE * math.log10(band / low)), 2) + 1
    w = np.geomspace(low, band, points)
    power = np.abs(noise_current(p, 1j * w, weights, delay)) ** 2
    integral = power[..., 0] * low + np.sum(0.5 * (power[..., 1:] + power[..., :-1])
                                            * np.diff(w), axis=-1)
    return quantum / math.sqrt(12.0) * np.sqrt(integral / band)


def noise(p, low, band, counts_per_rev, delay=EXACT):
    r"""The :class:`Noise` of one run ``p``: quantisation noise of variance
    :math:`q^2/12` (:math:`q = 2\pi`/counts) white over 0..``band`` [rad/s] on the angle the
    position loop's encoder reads, through :func:`~cas_freq.model.disturbance.noise_current`:
    :math:`i_{rms}^2 = \frac{q^2}{12\,\omega_b} \int_0^{\omega_b} |i/\nu(j\omega)|^2 d\omega`,
    by the trapezoid rule on a log grid from ``low`` (below it |i/nu| is taken as at ``low``).
    """
    rms = float(_noise_rms(p, low, band, counts_per_rev, delay))
    return Noise(rms, float(counts_per_rev), 2.0 * math.pi / counts_per_rev, float(band))


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


def batch_disturbance_figures(params, omega, counts_per_rev=None, linear=False, stable=None,
                              delay=EXACT):
    """The stiffness, effort and noise figures of every run of a batch, as
    :func:`disturbance_figures` gives them for one (the continuous loops'; NaN where a run is
    not stable, the noise NaN where it has no figure).

    Parameters
    ----------
    params : cas_freq.core.parameters.LoopParameters
        The runs (n).
    omega : numpy.ndarray
        The analysis grid [rad/s].
    counts_per_rev : float or None
        Counts per revolution of the encoder the position loop reads.
    linear : bool
        A linear output: the figures per m (``stiffness.min_N_per_m``, ``effort.peak_A_per_m``).
    stable : numpy.ndarray, optional
        Bool (n,): the runs whose closed loop is stable (default every run).
    delay : DelayModel
        Exact (default) or Padé delays.

    Returns
    -------
    dict of str to numpy.ndarray
        Figure name (``stiffness.*``, ``effort.*``, ``noise.current_rms_A``) -> (n,) values.
    """
    n = params.n_runs
    stable = np.ones(n, dtype=bool) if stable is None else np.asarray(stable, dtype=bool)
    selector = Selector(params)
    rates = dict(selector.scalars.get("sample_rates", ()) or ())
    selector.scalars["sample_rates"] = ()  # the continuous loops' figures
    suffix = "m" if linear else "rad"
    names = (f"stiffness.min_N_{'per_m' if linear else 'm_per_rad'}", "stiffness.min_at_rad_s",
             f"effort.peak_A_per_{suffix}", "effort.peak_at_rad_s", "noise.current_rms_A")
    out = {name: np.full(n, np.nan) for name in names}
    stable_runs = np.flatnonzero(stable)
    # in chunks of runs: a chunk's responses on the grid are (chunk, grid) complex arrays
    for start in range(0, stable_runs.size, CHUNK):
        kept = stable_runs[start:start + CHUNK]

        def runs(which, column, kept=kept):
            return selector(kept[which], column)

        at, value, _ = _least(_stiffness_values(runs, delay), omega, kept.size)
        out[names[0]][kept], out[names[1]][kept] = value, at
        at, value, _ = _least(_effort_values(runs, delay), omega, kept.size)
        out[names[2]][kept], out[names[3]][kept] = -value, at
        every = runs(np.arange(kept.size), True)
        on_output = build(every).loops[-1].feedback == "output_angle"
        if counts_per_rev is not None and not (linear and on_output):
            band = (math.pi * rates["position_loop"] if "position_loop" in rates
                    else float(omega[-1]))
            out[names[4]][kept] = _noise_rms(every, float(omega[0]), band, counts_per_rev,
                                             delay)
    return out


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
