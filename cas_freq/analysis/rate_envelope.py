r"""The rate and torque envelope: what the supply and the limits let the output do (numpy only).

A flight-control designer asks of an actuator how fast the output can move, how much torque it
holds, and how large a sine it follows before a limit acts. This module answers from the motor
constants, the supply and the two clamps of the loop (docs/model.md, section 15):

**Steady state** (motor side, speed :math:`\omega \ge 0`, every quantity SI). The drive applies
at most :math:`v_{max}` (``current_loop.v_max``), and the supply :math:`V_s` (``supply.voltage``,
default :math:`v_{max}`) sags by its source resistance :math:`R_s` (``supply.resistance``,
default 0) times the winding current, so :math:`R i + K_e \omega \le \min(v_{max}, V_s - R_s i)`;
the current command is clamped at :math:`i_{max}`. The largest current at speed :math:`\omega`
and the output torque (force at a linear output) it gives through the gear are

.. math::
    i(\omega) = \min\left(i_{max}, \frac{v_{max} - K_e\omega}{R},
                          \frac{V_s - K_e\omega}{R + R_s}\right), \qquad
    \tau_{out}(\omega) = \eta N \left(K_m i(\omega) - \mu_v \omega - F_c\right)

at the output rate :math:`\Omega = \omega / N` (:math:`\mu_v` the motor's viscous friction,
:math:`F_c` its Coulomb friction ``motor.coulomb_friction``; the load's own damping and spring
are the load's, not the actuator's). The **no-load rate** is where :math:`\tau_{out} = 0`: on a
voltage branch :math:`(V, R_e)`

.. math::
    \Omega_0 = \frac{1}{N}\,\frac{K_m V - R_e F_c}{K_m K_e + R_e \mu_v}
             = \frac{V}{N K_e}\,\frac{1}{1 + R_e\mu_v/(K_m K_e)} \quad (F_c = 0),

i.e. :math:`V/K_e` through the gear less what the viscous friction takes, the smallest over
the branches (and :math:`(K_m i_{max} - F_c)/(N \mu_v)` if the current limit is reached first).
The **stall torque** is :math:`\tau_{out}(0) = \eta N (K_m i_0 - F_c)` with
:math:`i_0 = \min(i_{max}, v_{max}/R, V_s/(R + R_s))`: :math:`K_m i_{max} N \eta` when the current
limit decides (``stall_limited_by``).

**Largest sine** at each frequency, from the linear closed loop with the feed-forward as the
simulator applies it: the current command at the clamp :math:`u = i/(T_i P_f)` (the current
over the current loop's :math:`T_i` and the filters between the clamp and the current loop) and
the voltage :math:`V = (L s + R)\,i + K_e\,\omega` per output command :math:`\delta_{cmd}`,

.. math::
    A_i(\omega) = \frac{i_{max}}{|u/\delta_{cmd}(j\omega)|}, \qquad
    A_v(\omega) = \min\left(\frac{v_{max}}{|V/\delta_{cmd}|},
                  \frac{V_s}{|V/\delta_{cmd}| + R_s |i/\delta_{cmd}|}\right)

(the second term a bound: the sag's peak and the voltage's need not coincide). A sine of
amplitude :math:`A < \min(A_i, A_v)` stays out of both clamps; above it the sine-dwell response
falls below T, and the limit with the smaller amplitude is the one that acts. The delays are
exact (a delay does not change a magnitude). With sampled controllers the amplitudes are those
of the continuous loops (said in the result's ``basis``).
"""

import dataclasses

import numpy as np

from cas_freq.model import parts
from cas_freq.model.loops import Selector, current_loop, responses
from cas_freq.model.structure import build

#: Points of the torque-speed curve, from stall to the no-load rate.
CURVE_POINTS = 41
#: The sine-amplitude grid: this many log-spaced points over SPAN x the linear bandwidth.
SINE_POINTS = 33
SINE_SPAN = (0.05, 10.0)
#: The grid of a loop without a bandwidth [rad/s].
FALLBACK_SINE_RANGE_RAD_S = (10.0, 1e4)


@dataclasses.dataclass(frozen=True, eq=False)
class RateEnvelope:
    """The rate and torque envelope of one actuator (module notes; docs/model.md §15).

    Output quantities are at the output in SI: rad, rad/s, N*m at a rotary output; m, m/s, N
    at a linear one (the field names keep the rotary case, as every typed record does:
    :mod:`cas_freq.core.output`).

    Attributes
    ----------
    supply_voltage_v, supply_resistance_ohm : float
        The supply [V], [ohm].
    voltage_limit_v, current_limit_a : float
        The loop's clamps v_max [V] and i_max [A].
    no_load_rate_rad_s : float
        Output rate with no load at the supply [rad/s or m/s].
    stall_torque_N_m : float
        Output torque (force) at stall [N*m or N].
    stall_limited_by : str
        ``"current"`` (i_max) or ``"voltage"`` (the supply over the resistance).
    rate_limited_by : str
        ``"supply"``, or ``"velocity command"`` where a cascade's velocity-command clamp
        ``position_loop.omega_max`` (over N) is below the supply's no-load rate.
    curve_rate_rad_s, curve_torque_N_m : numpy.ndarray
        The torque-speed curve at the output, from stall to the no-load rate.
    frequencies_rad_s : numpy.ndarray
        Frequencies of the sine limits [rad/s].
    current_amplitude_rad, voltage_amplitude_rad : numpy.ndarray
        Largest output sine amplitude [rad or m] that keeps the current command (the voltage)
        inside its clamp, per frequency.
    basis : str
        ``"continuous loops"`` or, with sampled controllers, what was computed instead.
    feedforward : bool
        Whether the config's feed-forward acts in the sine limits (it does in ``analyze``,
        as in flight and in the simulator; the sine-dwell leaves it off by default).
    """

    supply_voltage_v: float
    supply_resistance_ohm: float
    voltage_limit_v: float
    current_limit_a: float
    no_load_rate_rad_s: float
    stall_torque_N_m: float
    stall_limited_by: str
    rate_limited_by: str
    curve_rate_rad_s: np.ndarray
    curve_torque_N_m: np.ndarray
    frequencies_rad_s: np.ndarray
    current_amplitude_rad: np.ndarray
    voltage_amplitude_rad: np.ndarray
    basis: str = "continuous loops"
    feedforward: bool = True

    @property
    def amplitude_rad(self):
        """Largest sine amplitude inside both limits, per frequency [rad or m]."""
        return np.minimum(self.current_amplitude_rad, self.voltage_amplitude_rad)

    @property
    def limited_by(self):
        """Per frequency, the limit a larger sine reaches first: ``"current"``/``"voltage"``."""
        return tuple(np.where(self.current_amplitude_rad <= self.voltage_amplitude_rad,
                              "current", "voltage").tolist())

    def to_dict(self, unit):
        """JSON-ready dict in the output's unit (:class:`cas_freq.core.output.OutputUnit`): a
        rotary output in rad/s, N*m and deg; a linear one in m/s (and mm/s), N and mm."""
        linear = unit.linear
        rate, torque, amplitude = (("m_s", "N", "mm") if linear else ("rad_s", "N_m", "deg"))
        force = "force" if linear else "torque"
        scale = unit.scale  # SI -> shown (deg per rad, mm per m)
        out = {
            "supply_voltage_v": self.supply_voltage_v,
            "supply_resistance_ohm": self.supply_resistance_ohm,
            "voltage_limit_v": self.voltage_limit_v,
            "current_limit_a": self.current_limit_a,
            f"no_load_rate_{rate}": self.no_load_rate_rad_s,
            f"no_load_rate_{unit.shown}_s": self.no_load_rate_rad_s * scale,
            f"stall_{force}_{torque}": self.stall_torque_N_m,
            "stall_limited_by": self.stall_limited_by,
            "rate_limited_by": self.rate_limited_by,
            "torque_speed": {f"rate_{rate}": self.curve_rate_rad_s.tolist(),
                             f"{force}_{torque}": self.curve_torque_N_m.tolist()},
            "sine_limit": {
                "frequencies_rad_s": self.frequencies_rad_s.tolist(),
                f"current_amplitude_{amplitude}": (self.current_amplitude_rad * scale).tolist(),
                f"voltage_amplitude_{amplitude}": (self.voltage_amplitude_rad * scale).tolist(),
                f"amplitude_{amplitude}": (self.amplitude_rad * scale).tolist(),
                "limited_by": list(self.limited_by),
            },
            "basis": self.basis,
            "feedforward": self.feedforward,
        }
        return out


def supply_of(config):
    """(supply voltage [V], source resistance [ohm]) of a validated config: ``supply.voltage``
    (default ``current_loop.v_max``) and ``supply.resistance`` (default 0)."""
    supply = getattr(config, "supply", None)
    voltage = getattr(supply, "voltage", None)
    resistance = getattr(supply, "resistance", 0.0) or 0.0
    return (float(config.current_loop.v_max) if voltage is None else float(voltage),
            float(resistance))


def steady_state(p, supply_voltage, supply_resistance, points=CURVE_POINTS):
    """No-load rate, stall torque and the torque-speed curve at the output (module notes).

    Parameters
    ----------
    p : cas_freq.core.parameters.LoopParameters or types.SimpleNamespace
        One actuator (scalars or arrays of one run): R [ohm], Ke [V*s/rad], Km [N*m/A],
        mu_v [N*m*s/rad], F_c [N*m], ratio N [-], eta [-], v_max [V], i_max [A].
    supply_voltage : float
        V_s [V].
    supply_resistance : float
        R_s [ohm].
    points : int
        Points of the curve.

    Returns
    -------
    (float, float, str, numpy.ndarray, numpy.ndarray, str)
        No-load rate [rad/s or m/s], stall torque [N*m or N], what limits the stall current
        (``"current"`` or ``"voltage"``), the curve's rates and torques, what limits the rate
        (``"supply"``, or ``"velocity command"``: a cascade's ``position_loop.omega_max``).
    """
    r, ke, km = _scalar(p.R), _scalar(p.Ke), _scalar(p.Km)
    mu, fc = _scalar(p.mu_v), _scalar(getattr(p, "F_c", 0.0))
    n, eta = _scalar(p.ratio), _scalar(getattr(p, "eta", 1.0))
    v_max, i_max = _scalar(p.v_max), _scalar(p.i_max)
    branches = ((v_max, r), (supply_voltage, r + supply_resistance))  # (V, R_e) of each line
    # motor speed where the available torque meets the friction, on each voltage line ...
    speeds = [(km * v - r_e * fc) / (km * ke + r_e * mu) for v, r_e in branches]
    if mu > 0:  # ... and on the current limit, if the friction takes all of it first
        speeds.append((km * i_max - fc) / mu)
    omega_max = _scalar(getattr(p, "omega_max", np.inf))
    clamped = omega_max < min(speeds)  # a cascade's velocity-command clamp comes first
    top = max(0.0, min(*speeds, omega_max))
    omega = np.linspace(0.0, top, points)
    current = np.minimum.reduce([np.full(points, i_max),
                                 *((v - ke * omega) / r_e for v, r_e in branches)])
    torque = np.maximum(eta * n * (km * current - mu * omega - fc), 0.0)
    stall_current = min(i_max, *(v / r_e for v, r_e in branches))
    limited_by = "current" if stall_current == i_max else "voltage"
    stall = max(0.0, eta * n * (km * stall_current - fc))
    return top / n, stall, limited_by, omega / n, torque, ("velocity command" if clamped
                                                           else "supply")


def limit_responses(params, omega):
    """The current command at its clamp and the motor voltage per output command, and the
    current per output command, at ``omega`` (module notes).

    Parameters
    ----------
    params : cas_freq.core.parameters.LoopParameters
        One actuator with continuous controllers.
    omega : numpy.ndarray
        Frequencies [rad/s].

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        u/delta_cmd [A/rad], V/delta_cmd [V/rad], i/delta_cmd [A/rad] (per m at a linear
        output), complex, with the feed-forward.
    """
    p = Selector(params)()
    s = 1j * np.asarray(omega, dtype=float)
    n = p.ratio  # delta_cmd = theta_cmd / N: per output command is N times per motor command
    current = n * responses(p, s, feedforward=True, output="current").closed_loop
    speed = n * responses(p, s, feedforward=True, output="motor_velocity").closed_loop
    voltage = parts.polyval(parts.electrical(p), s) * current + p.Ke * speed
    loop = current_loop(p, s)
    commanded = current * (1.0 + loop) / loop  # i / T_i: the current loop's command
    for block in build(p).loops[1].path:  # filters between the clamp and the current loop
        commanded = commanded * parts.polyval(block.denominator, s) / parts.polyval(
            block.numerator, s)
    return commanded, voltage, current


def sine_limits(params, omega, supply_voltage, supply_resistance):
    """Largest output sine amplitude inside the current and the voltage clamp at ``omega``.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        A_i, A_v [rad or m] (module notes).
    """
    commanded, voltage, current = limit_responses(params, omega)
    v_max, i_max = _scalar(params.v_max), _scalar(params.i_max)
    with np.errstate(divide="ignore"):
        a_i = i_max / np.abs(commanded)
        a_v = np.minimum(v_max / np.abs(voltage),
                         supply_voltage / (np.abs(voltage) + supply_resistance * np.abs(current)))
    return a_i, a_v


def sine_frequencies(bandwidth_rad_s):
    """The grid of the sine limits [rad/s]: SINE_POINTS log-spaced over SINE_SPAN x the linear
    bandwidth (4 significant digits), FALLBACK_SINE_RANGE_RAD_S without one."""
    if bandwidth_rad_s is None or not np.isfinite(bandwidth_rad_s) or bandwidth_rad_s <= 0:
        low, high = FALLBACK_SINE_RANGE_RAD_S
    else:
        low, high = SINE_SPAN[0] * bandwidth_rad_s, SINE_SPAN[1] * bandwidth_rad_s
    return np.array([float(f"{w:.4g}") for w in np.geomspace(low, high, SINE_POINTS)])


def rate_envelope(config, params, frequencies_rad_s, feedforward=True):
    """The rate and torque envelope of one actuator.

    Parameters
    ----------
    config : cas_freq.config.ActuatorConfig
        The validated variant (its ``supply:``).
    params : cas_freq.core.parameters.LoopParameters
        The same variant's loop parameters (one run).
    frequencies_rad_s : array_like
        Frequencies of the sine limits [rad/s].
    feedforward : bool
        Let the config's feed-forward act on the sines (False: as ``sinedwell`` by default).

    Returns
    -------
    RateEnvelope
    """
    voltage, resistance = supply_of(config)
    if not feedforward:
        params = params.without_feedforward()
    basis = "continuous loops"
    if params.sample_rates:
        params = dataclasses.replace(params, sample_rates=())
        basis = ("continuous loops (the controllers are sampled: the sine limits are those of "
                 "the same loops run continuously)")
    if params.cascade and np.isfinite(_scalar(params.omega_max)):
        basis += ("; the velocity-command clamp position_loop.omega_max is not part of the "
                  "sine limits")
    rate, stall, limited_by, speeds, torques, rate_by = steady_state(params, voltage,
                                                                     resistance)
    omega = np.asarray(frequencies_rad_s, dtype=float)
    a_i, a_v = sine_limits(params, omega, voltage, resistance)
    return RateEnvelope(
        supply_voltage_v=voltage, supply_resistance_ohm=resistance,
        voltage_limit_v=_scalar(params.v_max), current_limit_a=_scalar(params.i_max),
        no_load_rate_rad_s=float(rate), stall_torque_N_m=float(stall),
        stall_limited_by=limited_by, rate_limited_by=rate_by, curve_rate_rad_s=speeds,
        curve_torque_N_m=torques,
        frequencies_rad_s=omega, current_amplitude_rad=a_i, voltage_amplitude_rad=a_v,
        basis=basis, feedforward=feedforward,
    )


def envelope_lines(envelope, unit, output="output"):
    """The envelope in a few lines of text (``analyze``'s table), in the output's unit."""
    if unit.linear:
        rate = f"{envelope.no_load_rate_rad_s * 1e3:.4g} mm/s"
        stall = f"stall force {envelope.stall_torque_N_m:.4g} N"
    else:
        rate = (f"{envelope.no_load_rate_rad_s:.4g} rad/s "
                f"({np.degrees(envelope.no_load_rate_rad_s):.4g} deg/s)")
        stall = f"stall torque {envelope.stall_torque_N_m:.4g} N*m"
    if envelope.rate_limited_by != "supply":
        rate += " (the velocity-command clamp)"
    lines = [f"envelope ({output}): no-load rate {rate}; {stall} "
             f"({envelope.stall_limited_by} limit); supply {envelope.supply_voltage_v:g} V"
             + (f", {envelope.supply_resistance_ohm:g} ohm" if envelope.supply_resistance_ohm
                else "")]
    w = envelope.frequencies_rad_s
    if not w.size:
        lines.append("largest sine inside the limits: not reported (the closed loop is not "
                     "stable)")
        return lines
    amplitude = envelope.amplitude_rad
    picks = np.unique(np.linspace(0, w.size - 1, 5).round().astype(int))
    shown = ", ".join(f"{w[k]:.4g} rad/s: {unit.from_si(amplitude[k]):.3g} {unit.shown} "
                      f"({envelope.limited_by[k]})" for k in picks)
    with_ff = "with" if envelope.feedforward else "without"
    lines.append(f"largest sine inside the limits ({with_ff} the feed-forward): {shown}")
    if envelope.basis.startswith("continuous loops ("):
        lines.append("(the controllers are sampled: the sine limits are those of the same "
                     "loops run continuously)")
    if "omega_max" in envelope.basis:
        lines.append("(the velocity-command clamp position_loop.omega_max is not part of the "
                     "sine limits)")
    return lines


def _scalar(value):
    return float(np.asarray(value, dtype=float).reshape(-1)[0])
