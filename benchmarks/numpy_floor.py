"""A plain numpy evaluation of the loops of ``benchmarks/architectures.py``: the floor its
cas_freq batches are held against.

For each architecture the loops are written out by hand (docs/model.md's equations, exact
delays e^(-j w tau)) and evaluated for every variant on the grid ``batch_analyze`` uses by
default (:func:`cas_freq.analysis.frequency.frequency_grid`: 200 points a decade over
1e-2..1e6 rad/s, densified where the loops' delays turn the phase fast), in chunks of
variants; each loop's phase and gain margins and T's
-3.0103 dB bandwidth are read off the grid by linear interpolation at the first crossing.
Nothing is refined, no loop-at-a-time view is computed and stability is not checked: it is
the least work that gives the same kind of figures, so the ratio cascade / PID-on-PI of this
floor is what the extra loop and filters cost by themselves. The figures agree with cas_freq's
where both take the same crossing (to ~3e-4 deg and dB on the grid's interpolation); where a
loop crosses more than once the floor takes the first, not the one docs/model.md defines.

The plant's polynomials come from :func:`cas_freq.model.parts.mechanics` (the two-mass gear
and load) so both sides evaluate the same plant; everything else is written here.
"""

import numpy as np

from cas_freq.analysis.frequency import (
    DEFAULT_POINTS_PER_DECADE,
    DEFAULT_RANGE_RAD_S,
    frequency_grid,
)
from cas_freq.model import parts
from cas_freq.model.loops import Selector
from cas_freq.model.structure import total_delay

#: Variants evaluated at once (bounds the memory: chunk x grid complex numbers per array).
CHUNK = 250
#: -3.0103 dB as a magnitude.
HALF_POWER = 1.0 / np.sqrt(2.0)


def _poly(coefficients, s):
    """A polynomial whose coefficients are scalars or columns (k, 1), at ``s`` (1, m)."""
    out = 0.0
    for c in coefficients:
        out = out * s + c
    return out


def _second_order(w0, zeta, s):
    return 1.0 / (s * s / (w0 * w0) + 2.0 * zeta * s / w0 + 1.0)


def _filter(item, s):
    """A config filter 1 at s = 0 (docs/model.md "Filters")."""
    w0 = item.frequency
    if item.kind == "lowpass1":
        return 1.0 / (s / w0 + 1.0)
    if item.kind == "lowpass2":
        return _second_order(w0, item.damping, s)
    zeta = item.width / (2.0 * w0)
    depth = 10.0 ** (item.depth_db / 20.0)
    return (s * s / (w0 * w0) + 2.0 * depth * zeta * s / w0 + 1.0) * _second_order(w0, zeta, s)


def _filters(p, at, s):
    out = 1.0
    for item in p.filters:
        if item.at == at:
            out = out * _filter(item, s)
    return out


def _pi(kp, ki, s):
    return kp + ki / s


def _loops(p, s):
    """{name: L} and T of the runs ``p`` (columns) at ``s`` (a row)."""
    d, n_theta, n_out = (_poly(c, s) for c in parts.mechanics(p))
    z_e = p.L * s + p.R
    delta = z_e * d + p.Ke * p.Km * s * n_theta
    l_i = _pi(p.ci_Kp, p.ci_Ki, s) * np.exp(-s * p.tau_c) * d / delta
    angle_per_current = l_i / (1.0 + l_i) * p.Km * n_theta / d  # theta / i_cmd
    shaping = _filters(p, "current_command", s)
    output = n_out / n_theta  # N delta / theta
    if not p.cascade:
        c_p = p.cp_Kp + p.cp_Ki / s + p.cp_Kd * s / (p.Tf * s + 1.0)
        forward = c_p * np.exp(-s * p.tau_p) * shaping * angle_per_current
        return {"current_loop": l_i, "position_loop": forward}, forward * output / (1.0 + forward)
    sensed = _filters(p, "velocity_feedback", s) / (p.tau_vf * s + 1.0)
    velocity = (_pi(p.cv_Kp, p.cv_Ki, s) * np.exp(-s * p.tau_v) * shaping * angle_per_current
                * s)  # omega / e_v
    l_v = velocity * sensed
    l_p = _pi(p.cp_Kp, p.cp_Ki, s) * np.exp(-s * p.tau_p) * velocity / (1.0 + l_v) / s
    return ({"current_loop": l_i, "velocity_loop": l_v, "position_loop": l_p},
            l_p * output / (1.0 + l_p))


def _first_crossing(values, level, w):
    """Per row, the log-interpolated frequency where ``values`` first falls through ``level``,
    and the interpolation weights (index, fraction); NaN where it never does."""
    below = values < level
    index = np.argmax(below[:, 1:] & ~below[:, :-1], axis=1)
    found = below[np.arange(len(values)), index + 1] & ~below[np.arange(len(values)), index]
    rows = np.arange(len(values))
    a, b = values[rows, index], values[rows, index + 1]
    fraction = np.where(found, (a - level) / np.where(a != b, a - b, 1.0), np.nan)
    log_w = np.log(w)
    return np.exp(log_w[index] + fraction * (log_w[index + 1] - log_w[index])), index, fraction


def _at(values, index, fraction):
    rows = np.arange(len(values))
    return values[rows, index] + fraction * (values[rows, index + 1] - values[rows, index])


def margins(loop, w):
    """Phase margin [deg] and gain margin [dB] of each row's loop ``loop`` on the grid."""
    magnitude = np.abs(loop)
    phase = np.degrees(np.unwrap(np.angle(loop), axis=1))
    _, index, fraction = _first_crossing(magnitude, 1.0, w)
    phase_margin = (_at(phase, index, fraction) + 360.0) % 360.0 - 180.0  # in [-180, 180)
    _, index, fraction = _first_crossing(phase, -180.0, w)
    gain_margin = -20.0 * np.log10(_at(magnitude, index, fraction))
    return phase_margin, gain_margin


def figures(params):
    """Every loop's margins and T's bandwidth for every run of ``params`` (LoopParameters).

    Returns
    -------
    dict
        name -> (phase margin [deg], gain margin [dB]) arrays (n,), and ``"bandwidth"`` ->
        array (n,) [rad/s].
    """
    select = Selector(params)
    w = frequency_grid(*DEFAULT_RANGE_RAD_S, DEFAULT_POINTS_PER_DECADE, total_delay(select()))
    s = 1j * w[None, :]
    out = {}
    for start in range(0, params.n_runs, CHUNK):
        runs = np.arange(start, min(start + CHUNK, params.n_runs))
        loops, closed = _loops(select(runs, column=True), s)
        shape = (len(runs), len(w))  # a loop of parameters common to the chunk is one row
        for name, loop in loops.items():
            out.setdefault(name, []).append(margins(np.broadcast_to(loop, shape), w))
        out.setdefault("bandwidth", []).append(
            _first_crossing(np.abs(np.broadcast_to(closed, shape)), HALF_POWER, w)[0])
    return {name: (np.concatenate(values) if name == "bandwidth" else
                   tuple(np.concatenate(part) for part in zip(*values, strict=True)))
            for name, values in out.items()}
