r"""Guaranteed bounds over a parameter box: lower bounds of each loop's phase and gain margins
(the position loop's, the current loop's alone and with the outer loops closed, a cascade's
velocity loop's alike) and of the closed-loop bandwidth, and stability of every point of the
box (docs/model.md, "Tolerances and the worst case").

The loops of docs/model.md §3-4: the PID-on-PI's L_p = C_p e^{-sτ_p} F_c T_i M F_p with
T_i = C_i e^{-sτ_c} Y/(1 + L_i), L_i = C_i e^{-sτ_c} Y F_i,
Y = (Js + μ_v)/((Ls + R)(Js + μ_v) + K_e K_m), M = K_m/(s(Js + μ_v)) and the filters F at
their points (fixed: their numbers are the nominal's); a cascade's L_v = C_v e^{-sτ_v} F_c T_i
(K_m/(Js + μ_v)) F_v (F_v the feedback low-pass τ_vf and the velocity filters) and
L_p = C_p e^{-sτ_p} F_vc T_v F_p / s with T_v = L_v/(F_v (1 + L_v)),
is evaluated in **complex interval arithmetic** (rectangles: real and imaginary intervals) over
cells, each a sub-box of the parameters times an interval of frequency. Every operation
encloses its exact result, so the rectangle of a cell holds L_p(jω, p) for every ω and p of
the cell (outward-widened by 1e-9 of its size for the rounding of floating point):

- **phase margin**: where a rectangle can hold a point of modulus 1, the smallest angle between
  it and the negative real axis is a lower bound of the phase margin at any crossover in the
  cell (the argument of a convex set without the origin spans the arguments of its corners);
- **gain margin** (upper, at the phase crossovers where |L| < 1): where a rectangle reaches
  the negative real axis inside the unit circle, -20 log10 of the largest |Re| it reaches there;
- **bandwidth**: T = W L_p/(F_p (1 + L_p)) (no feed-forward; the command's path of a
  derivative on the measurement), enclosed in two forms intersected; the lowest frequency of
  a cell whose rectangle can reach |T| <= 1/sqrt(2) bounds ω_BW from below (T(0) = 1, so ω_BW
  is the first frequency where |T| falls to it);
- **stability** (the zero-exclusion principle): if no rectangle holds -1, for none of the
  loops (current, velocity, position: each with the loops inside it closed), then
  1 + L(jω, p) is never 0 on the frequency axis, so no closed-loop pole crosses it anywhere in
  the box; with the nominal point stable (and the open loops' poles, the integrators, the
  filters' and the inner closed loops', fixed in the left half-plane and at 0), every point of
  the box is stable, loop by loop from the inside out.

A branch and bound refines the cells whose bound is below the worst found (bisecting the
parameter or the frequency interval that is widest in its own scale) until the bound meets
it or the cell budget runs out, best first: each round splits, for each figure, an equal share
of the cells lowest below its target (and every cell that may hold -1), the others waiting in
the pool with their bounds. The bound holds whenever it stops, the gap says how close it got.
The frequencies covered are 1e-9 .. 1e12 rad/s (the analysed range and far beyond it). Where
the loops are not continuous on the motor encoder with a rigid, unloaded gear, or a toleranced
key is not one of the loops' (:data:`FIELDS`), there is no bound (:func:`supported` says why).
"""

import dataclasses
import math

import numpy as np

from cas_freq.model.structure import build

#: The keys a box may tolerance for a bound, and the LoopParameters field each sets.
FIELDS = {
    "motor.R": "R", "motor.L": "L", "motor.Km": "Km", "motor.Ke": "Ke", "motor.J": "J",
    "motor.mu_v": "mu_v", "current_loop.Kp": "ci_Kp", "current_loop.Ki": "ci_Ki",
    "current_loop.delay": "tau_c", "position_loop.Kp": "cp_Kp", "position_loop.Ki": "cp_Ki",
    "position_loop.Kd": "cp_Kd", "position_loop.Tf": "Tf", "position_loop.delay": "tau_p",
    "velocity_loop.Kp": "cv_Kp", "velocity_loop.Ki": "cv_Ki", "velocity_loop.delay": "tau_v",
    "velocity_loop.feedback_filter": "tau_vf", "gear.ratio": "ratio", "gear.efficiency": "eta",
    "gear.stiffness": "K_g", "gear.damping": "c_g", "load.inertia": "J_L",
    "load.damping": "b_L", "load.hinge_stiffness": "K_h",
}
#: Frequencies the cells cover [rad/s] and the first cells per decade.
OMEGA_RANGE = (1e-9, 1e12)
FIRST_CELLS_PER_DECADE = 8
#: Most cells evaluated by one bound, and the cells evaluated at once (memory: ~300 bytes
#: per cell and interval, a few hundred MB per chunk).
MAX_CELLS = 4_000_000
CHUNK = 250_000
#: The loops bounded, by the prefix of their figures: the position loop (""), the current
#: loop alone and with the outer loops closed, a cascade's velocity loop alike.
LOOP_PREFIXES = {"": "position", "current_": "current", "current_aat_": "current_aat",
                 "velocity_": "velocity", "velocity_aat_": "velocity_aat"}
#: The figures bounded from below, per loop: its phase, gain and delay margins and the negative
#: of its sensitivity peak (a lower bound of -Ms is an upper bound of Ms); and the closed
#: loop's bandwidth and the negative of its resonance peak.
LOOP_FIGURES = ("phase_margin_deg", "gain_margin_db", "delay_margin_s",
                "negative_sensitivity_peak_db")
FIGURES = (*(prefix + name for prefix in LOOP_PREFIXES for name in LOOP_FIGURES),
           "bandwidth_rad_s", "negative_peak_db")
#: Each figure's bound where a cell's rectangle is not finite (it holds anything): a phase
#: margin -180 deg, a peak no bound (-inf on its negative), the others 0.
UNKNOWN = {name: -180.0 if name.endswith("phase_margin_deg") else
           -math.inf if "negative_" in name else 0.0 for name in FIGURES}
#: The points of fixed filters the enclosures take (docs/model.md, "Filters").
FILTER_POINTS = ("current_feedback", "current_command", "velocity_feedback",
                 "velocity_command", "position_feedback", "position_command")
#: Relative outward widening of every rectangle (floating-point rounding).
WIDEN = 1e-9
#: |T| at the bandwidth: 1/sqrt(2), 3.01 dB below T(0) = 1 (docs/model.md §7).
HALF_POWER = 1.0 / math.sqrt(2.0)


def supported(params, keys):
    """None if a bound can be established for ``params`` (one run of LoopParameters) over
    ``keys``, else why not."""
    if params.feedback_output or params.sample_rates:
        return "the bound is established for continuous loops on the motor encoder"
    other = [key for key in keys if key not in FIELDS and key not in (
        "motor.no_load.current", "motor.no_load.speed")]
    if other:
        return f"{', '.join(other)}: not a key of the position loop (no bound)"
    return None


# --- interval arithmetic: a real interval is (low, high), a complex one (re, im) -----------

def _mul(a, b):
    products = (a[0] * b[0], a[0] * b[1], a[1] * b[0], a[1] * b[1])
    return np.minimum.reduce(products), np.maximum.reduce(products)


def _add(a, b):
    return a[0] + b[0], a[1] + b[1]


def _sub(a, b):
    return a[0] - b[1], a[1] - b[0]


def _square(a):
    low, high = a[0] * a[0], a[1] * a[1]
    inside = (a[0] <= 0) & (a[1] >= 0)
    return np.where(inside, 0.0, np.minimum(low, high)), np.maximum(low, high)


def _cmul(z, w):
    (a, b), (c, d) = z, w
    return _sub(_mul(a, c), _mul(b, d)), _add(_mul(a, d), _mul(b, c))


def _cadd(z, w):
    return _add(z[0], w[0]), _add(z[1], w[1])


def _cdiv(z, w):
    """z / w, w's rectangle away from 0 (else an unbounded rectangle)."""
    c, d = w
    modulus = _add(_square(c), _square(d))
    positive = modulus[0] > 0
    low = np.where(positive, modulus[0], 1.0)
    inverse = (1.0 / modulus[1], 1.0 / low)
    conjugate = (c, (-d[1], -d[0]))
    re, im = _cmul(z, conjugate)
    re, im = _mul(re, inverse), _mul(im, inverse)
    infinite = np.where(positive, 0.0, np.inf)
    return (re[0] - infinite, re[1] + infinite), (im[0] - infinite, im[1] + infinite)


def _meet(z, w):
    """The intersection of two rectangles that both hold the same value (each may be
    unbounded)."""
    # fmax/fmin: an end that is NaN (inf - inf in an unbounded form) is no end
    return ((np.fmax(z[0][0], w[0][0]), np.fmin(z[0][1], w[0][1])),
            (np.fmax(z[1][0], w[1][0]), np.fmin(z[1][1], w[1][1])))


def _real(a):
    return a, (np.zeros_like(a[0]), np.zeros_like(a[0]))


def _cos_range(low, high):
    """Range of cos over [low, high] (arrays)."""
    values = np.stack([np.cos(low), np.cos(high)])
    top = np.minimum.reduce(values), np.maximum.reduce(values)
    has_max = np.floor(high / (2 * math.pi)) >= np.ceil(low / (2 * math.pi))
    has_min = np.floor((high - math.pi) / (2 * math.pi)) >= np.ceil((low - math.pi) /
                                                                    (2 * math.pi))
    return np.where(has_min, -1.0, top[0]), np.where(has_max, 1.0, top[1])


def _exp_minus_j(theta):
    """e^{-jθ} for θ in an interval: (cos θ, -sin θ) ranges."""
    cos = _cos_range(*theta)
    sin = _cos_range(theta[0] - math.pi / 2, theta[1] - math.pi / 2)
    return cos, (-sin[1], -sin[0])


def _widen(z):
    (a, b), (c, d) = z
    size = np.maximum.reduce([np.abs(a), np.abs(b), np.abs(c), np.abs(d)]) * WIDEN
    return (a - size, b + size), (c - size, d + size)


@dataclasses.dataclass(frozen=True)
class Shape:
    """What of the loop is fixed over a box: its architecture, where the position loop's
    derivative acts, and its filters with their numbers (the nominal's: a filter's numbers are
    not toleranced), per point (:data:`FILTER_POINTS`) a tuple of (numerator, denominator)
    coefficient tuples, highest power first."""

    cascade: bool = False
    on_measurement: bool = False
    filters: tuple = ()
    loaded: bool = False
    compliant: bool = False

    def blocks(self, point):
        return dict(self.filters).get(point, ())


def shape_of(params):
    """The :class:`Shape` of one run of LoopParameters, from its structure
    (:func:`cas_freq.model.structure.build`); the velocity loop's low-pass tau_vf is not among
    the filters (it is a key)."""
    loops = build(params).loops
    by_point = {"current_feedback": loops[0].sensor, "position_feedback": loops[-1].sensor,
                "position_command": build(params).command}
    if params.cascade:
        by_point.update(current_command=loops[1].path, velocity_command=loops[2].path,
                        velocity_feedback=tuple(block for block in loops[1].sensor
                                                if block.name != "velocity filter"))
    else:
        by_point["current_command"] = loops[1].path

    def numbers(block):
        return tuple(tuple(float(np.asarray(c).reshape(-1)[0]) for c in polynomial)
                     for polynomial in (block.numerator, block.denominator))

    linear_load = any(float(np.asarray(getattr(params, name)).reshape(-1)[0]) != 0.0
                      for name in ("J_L", "b_L", "K_h", "K_g"))
    return Shape(bool(params.cascade), bool(np.asarray(params.derivative_on_measurement)
                                            .reshape(-1)[0]),
                 tuple((point, tuple(numbers(block) for block in blocks))
                       for point, blocks in by_point.items() if blocks),
                 loaded=linear_load, compliant=bool(np.asarray(params.K_g).reshape(-1)[0] > 0))


def enclosures(values, omega, shape=Shape()):
    """Rectangles holding each loop's L(jω) and T(jω) over cells.

    Parameters
    ----------
    values : dict of str to (numpy.ndarray, numpy.ndarray)
        Each LoopParameters field (:data:`FIELDS`' values) as an interval (low, high) per
        cell (a point: low = high).
    omega : (numpy.ndarray, numpy.ndarray)
        The cells' frequency intervals [rad/s], > 0.
    shape : Shape
        The architecture and the fixed filters.

    Returns
    -------
    dict
        Each ((re low, re high), (im low, im high)) per cell: ``current`` (the outer loops
        open), ``current_aat`` (the outer loops closed), ``velocity`` and ``velocity_aat`` (a
        cascade's), ``position``, and ``closed`` (T, no feed-forward).
    """
    # a divisor whose interval reaches 0 gives an unbounded rectangle, and inf - inf or
    # 0 * inf a NaN end: both are handled (NaN ends are no ends, :func:`_meet`; a rectangle
    # that is not finite holds anything, :func:`bounds`), so numpy need not warn of them
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        return _enclosures(values, omega, shape)


def _polynomial(coefficients, omega):
    """A real polynomial (highest power first) at s = jω for ω in an interval (> 0)."""
    zero = np.zeros_like(omega[0])
    re, im = (zero, zero), (zero, zero)
    for power, c in enumerate(reversed(coefficients)):
        if c == 0.0:
            continue
        # c (jω)^k: real for even k, imaginary for odd, with the sign of j^k
        term = _mul((np.full_like(zero, c), np.full_like(zero, c)),
                    (omega[0] ** power, omega[1] ** power))
        if power % 4 in (2, 3):
            term = (-term[1], -term[0])
        re, im = (_add(re, term), im) if power % 2 == 0 else (re, _add(im, term))
    return re, im


def _filters(shape, point, omega):
    """The fixed filters at ``point`` in series (None for none)."""
    out = None
    for numerator, denominator in shape.blocks(point):
        block = _cdiv(_polynomial(numerator, omega), _polynomial(denominator, omega))
        out = block if out is None else _cmul(out, block)
    return out


def _times(z, w):
    """z w, w None meaning 1."""
    return z if w is None else _cmul(z, w)


def _enclosures(values, omega, shape):
    v = values
    zero = np.zeros_like(omega[0])
    jw = (zero, zero), omega
    over_jw = (zero, zero), (-1.0 / omega[0], -1.0 / omega[1])
    # two forms each, their rectangles intersected (both hold the exact value): interval
    # arithmetic widens every repeated occurrence of an interval, so Y = 1/(Ls + R +
    # Ke Km/(Js + mu_v)) and T_i = 1/(1/(C_i Y) + F), where each enters once, are tight where
    # they are finite, and the plain forms hold where those divide by an interval through 0
    one = _real((np.ones_like(zero), np.ones_like(zero)))
    filters = {point: _filters(shape, point, omega) for point in FILTER_POINTS}
    # J s + mu_v, and a load's torque per motor speed reflected through the gear
    mechanical, output = _mechanics(v, jw, over_jw, one, shape)
    electrical = _cadd(_cmul(_real(v["L"]), jw), _real(v["R"]))  # L s + R
    coupling = _real(_mul(v["Ke"], v["Km"]))
    y = _meet(_cdiv(one, _cadd(electrical, _cdiv(coupling, mechanical))),
              _cdiv(mechanical, _cadd(_cmul(electrical, mechanical), coupling)))
    c_i = _cadd(_real(v["ci_Kp"]), _cmul(_real(v["ci_Ki"]), over_jw))
    forward_i = _widen(_cmul(_cmul(c_i, _exp_minus_j(_mul(omega, v["tau_c"]))), y))
    sensor_i = filters["current_feedback"]
    l_i = forward_i if sensor_i is None else _widen(_cmul(forward_i, sensor_i))
    t_i = _closed(forward_i, l_i, sensor_i, one)  # i / i_cmd
    path = filters["current_command"]
    sensor_p = filters["position_feedback"]
    if shape.cascade:
        speed = _cdiv(_real(v["Km"]), mechanical)  # omega / i
        c_v = _cadd(_real(v["cv_Kp"]), _cmul(_real(v["cv_Ki"]), over_jw))
        outer_v = _times(_cmul(c_v, _exp_minus_j(_mul(omega, v["tau_v"]))), path)
        sensor_v = _times(_low_pass(v["tau_vf"], jw, one), filters["velocity_feedback"])
        forward_v = _cmul(_cmul(outer_v, t_i), speed)
        l_v = _widen(_times(forward_v, sensor_v))
        t_v = _closed(forward_v, l_v, sensor_v, one)  # omega / omega_cmd
        c_p = _cadd(_real(v["cp_Kp"]), _cmul(_real(v["cp_Ki"]), over_jw))
        outer = _times(_cmul(_cmul(c_p, _exp_minus_j(_mul(omega, v["tau_p"]))), over_jw),
                       filters["velocity_command"])  # C_p e^{-sτp} F / s
        forward = _cmul(outer, t_v)
        # broken at the voltage, or at the current command, with the outer loops closed
        # (docs/model.md §7): the speed's and the angle's paths back to the current command
        back = _cmul(speed, _cadd(_one_or(sensor_v, one), _times(outer, sensor_p)))
        current_back = _cmul(outer_v, back)
        velocity = {"velocity": l_v, "velocity_aat": _widen(_cmul(_cmul(outer_v, t_i), back))}
        reference = forward
    else:
        derivative = _cdiv(_cmul(_real(v["cp_Kd"]), jw), _cadd(one, _cmul(_real(v["Tf"]), jw)))
        proportional_integral = _cadd(_real(v["cp_Kp"]), _cmul(_real(v["cp_Ki"]), over_jw))
        delay_p = _exp_minus_j(_mul(omega, v["tau_p"]))
        m = _cdiv(_real(v["Km"]), _cmul(jw, mechanical))  # theta / i
        outer = _times(_cmul(_cmul(_cadd(proportional_integral, derivative), delay_p), m),
                       path)  # C_p e^{-sτp} F M
        forward = _cmul(outer, t_i)
        current_back = _times(outer, sensor_p)
        velocity = {}
        reference = forward
        if shape.on_measurement:  # the command sees Kp + Ki/s (docs/model.md §3)
            reference = _cmul(_times(_cmul(_cmul(proportional_integral, delay_p), m), path),
                              t_i)
    l_p = _widen(_times(forward, sensor_p))
    # the current loop broken at the voltage with the outer loops closed (docs/model.md §7):
    # L_i,aat = C_i e^{-sτc} Y (F_i + the outer loops' path back)
    l_aat = _widen(_cmul(forward_i, _cadd(_one_or(sensor_i, one), current_back)))
    closed = (_closed(forward, l_p, sensor_p, one) if reference is forward
              else _cdiv(reference, _cadd(one, l_p)))
    return {"current": l_i, "current_aat": l_aat, **velocity, "position": l_p,
            "closed": _times(_times(closed, output), filters["position_command"])}


def _mechanics(v, jw, over_jw, one, shape):
    r"""The motor's torque per speed with the load reflected, :math:`D/s` of docs/model.md
    §5 (:func:`cas_freq.model.parts.mechanics`): :math:`J s + \mu_v + (e/N^2) Q/s` with
    :math:`P_L = J_L s^2 + b_L s + K_h`, Q = P_L on a rigid gear and
    :math:`Q = 1/(1/G + 1/P_L)` (G = K_g + c_g s, both forms intersected) on a compliant one;
    and the output on the motor's scale per motor angle, :math:`N\delta/\theta = G/(P_L + G)`
    (None: 1)."""
    mechanical = _cadd(_cmul(_real(v["J"]), jw), _real(v["mu_v"]))
    if not shape.loaded:
        return mechanical, None
    load = _cadd(_cmul(_cadd(_cmul(_real(v["J_L"]), jw), _real(v["b_L"])), jw), _real(v["K_h"]))
    reflection = _real(_mul((1.0 / v["eta"][1], 1.0 / v["eta"][0]),
                            (1.0 / v["ratio"][1] ** 2, 1.0 / v["ratio"][0] ** 2)))
    if not shape.compliant:
        return _cadd(mechanical, _cmul(_cmul(reflection, load), over_jw)), None
    gear = _cadd(_real(v["K_g"]), _cmul(_real(v["c_g"]), jw))
    coupled = _meet(_cdiv(one, _cadd(_cdiv(one, gear), _cdiv(one, load))),
                    _cdiv(_cmul(gear, load), _cadd(gear, load)))
    output = _meet(_cdiv(one, _cadd(one, _cdiv(load, gear))),
                   _cdiv(gear, _cadd(load, gear)))
    return _cadd(mechanical, _cmul(_cmul(reflection, coupled), over_jw)), output


def _one_or(z, one):
    return one if z is None else z


def _low_pass(tau, jw, one):
    """1/(τ s + 1) over an interval of τ (None where τ is 0 throughout)."""
    if not np.any(tau[1] > 0):
        return None
    return _cdiv(one, _cadd(one, _cmul(_real(tau), jw)))


def _closed(forward, loop, sensor, one):
    """forward / (1 + loop) with loop = forward * sensor, in two forms intersected: as it
    stands and 1 / (1/forward + sensor)."""
    return _meet(_cdiv(forward, _cadd(one, loop)),
                 _cdiv(one, _cadd(_cdiv(one, forward), _one_or(sensor, one))))


# --- what a rectangle says ---------------------------------------------------------------

def _corner_moduli(z):
    (a, b), (c, d) = z
    corners = np.stack([np.hypot(a, c), np.hypot(a, d), np.hypot(b, c), np.hypot(b, d)])
    # the nearest point to the origin: clamp 0 into each interval
    near_re = np.where((a <= 0) & (b >= 0), 0.0, np.minimum(np.abs(a), np.abs(b)))
    near_im = np.where((c <= 0) & (d >= 0), 0.0, np.minimum(np.abs(c), np.abs(d)))
    return np.hypot(near_re, near_im), np.maximum.reduce(corners)


def _angles(a, b, c, d):
    """The angles [rad] from the negative real axis of a rectangle's four corners."""
    return np.stack([np.abs(np.angle(-(x + 1j * y))) for x in (a, b) for y in (c, d)])


def phase_margin_bound(z):
    """Per cell: lower bounds [deg] of the phase margin, signed, and of its magnitude, at
    any crossover the cell can hold (+inf where it holds none: its moduli exclude 1).

    PM = 180 deg + angle(L) in (-180, 180] is positive below the real axis and negative
    above it. Below, the rectangle's smallest angle from the negative real axis bounds it;
    a rectangle that reaches the upper half plane is bounded by minus its upper part's
    largest angle (-180 deg where it reaches the positive real axis or the origin).
    """
    (a, b), (c, d) = z
    nearest, farthest = _corner_moduli(z)
    relevant = (nearest <= 1.0) & (farthest >= 1.0)
    # the negative real axis is reached: 0; else the corners' angles from it
    on_axis = (c <= 0) & (d >= 0) & (a <= 0)
    magnitude = np.where(on_axis, 0.0, np.degrees(np.min(_angles(a, b, c, d), axis=0)))
    upper = np.degrees(np.max(_angles(a, b, np.maximum(c, 0.0), d), axis=0))
    upper = np.where((b >= 0) & (c <= 0), 180.0, upper)
    signed = np.where(d < 0, magnitude, -upper)
    return np.where(relevant, signed, np.inf), np.where(relevant, magnitude, np.inf)


def gain_margin_bound(z):
    """Per cell: a lower bound of the (upper) gain margin [dB] at any phase crossover inside
    the unit circle the cell can hold (+inf where it holds none): the largest |Re| it reaches
    on the negative real axis there is at most -Re's low end (and 1)."""
    (a, b), (c, d) = z
    inside = (c <= 0) & (d >= 0) & (a < 0) & (b > -1.0)
    with np.errstate(divide="ignore"):
        bound = -20.0 * np.log10(np.minimum(-np.minimum(a, 0.0), 1.0))
    return np.where(inside, bound, np.inf)


def _smallest(values, where):
    """The smallest of ``values`` where ``where`` holds (+inf where it holds nowhere)."""
    return float(np.min(values[where])) if where.any() else math.inf


def bandwidth_bound(t, w_low):
    """Per cell: a lower bound of ω_BW that the cell allows: the cell's lowest frequency where
    its rectangle of T can reach |T| <= 1/sqrt(2) (T(0) = 1), else +inf; a rectangle that is
    not finite reaches it anywhere."""
    nearest, _ = _corner_moduli(t)
    reach = ~_finite(t) | ~(nearest > HALF_POWER)
    return np.where(reach, w_low, np.inf)


def _finite(z):
    (a, b), (c, d) = z
    return np.isfinite(a) & np.isfinite(b) & np.isfinite(c) & np.isfinite(d)


def holds_minus_one(z):
    """Per cell: the rectangle holds -1."""
    (a, b), (c, d) = z
    return (a <= -1.0) & (b >= -1.0) & (c <= 0.0) & (d >= 0.0)


# --- the branch and bound -----------------------------------------------------------------

def _values(base, keys, low, high):
    """Each field's interval per cell: the toleranced keys' from the cells, the others the
    base run's point; mu_v follows Km where the config derives it (``base['derive_mu']``)."""
    out = {}
    for field in set(FIELDS.values()):
        value = np.full(low.shape[0], float(base[field]))
        out[field] = (value, value.copy())
    for j, key in enumerate(keys):
        if key in FIELDS:
            out[FIELDS[key]] = (low[:, j], high[:, j])
    if base.get("derive_tf"):  # Tf = Kd / (10 Kp), each of them possibly toleranced
        kp = out["cp_Kp"]
        out["Tf"] = _mul(out["cp_Kd"], (1.0 / (10.0 * kp[1]), 1.0 / (10.0 * kp[0])))
    derive = base.get("derive_mu")
    if derive is not None:  # mu_v = Km I0 / w0, each of them possibly toleranced
        current, speed = derive
        i0 = (np.full(low.shape[0], current), np.full(low.shape[0], current))
        w0 = (np.full(low.shape[0], speed), np.full(low.shape[0], speed))
        for j, key in enumerate(keys):
            if key == "motor.no_load.current":
                i0 = (low[:, j], high[:, j])
            elif key == "motor.no_load.speed":
                w0 = (low[:, j], high[:, j])
        out["mu_v"] = _mul(_mul(out["Km"], i0), (1.0 / w0[1], 1.0 / w0[0]))
    return out


def _size(loops):
    """Per cell and loop (:data:`SIZED`): its rectangle's diagonal relative to 1 + the
    modulus of its middle (inf where it is not finite); and ``size``, the largest."""
    sizes = {}
    for name in SIZED:
        if name not in loops:  # a PID-on-PI's velocity loop
            sizes[f"size_{name}"] = np.zeros_like(loops["closed"][0][0])
            continue
        (a, b), (c, d) = loops[name]
        with np.errstate(invalid="ignore"):
            size = np.hypot(b - a, d - c) / (1.0 + np.hypot(0.5 * (a + b), 0.5 * (c + d)))
        sizes[f"size_{name}"] = np.where(np.isnan(size), np.inf, size)
    return {**sizes, "size": np.maximum.reduce(list(sizes.values()))}


def _cell_bounds(base, keys, shape, p_low, p_high, w_low, w_high):
    """Each figure's bound per cell, whether the cell may hold -1 (of any loop's L), and its
    rectangles' size (:func:`_size`)."""
    loops = enclosures(_values(base, keys, p_low, p_high), (w_low, w_high), shape)
    # a rectangle that is not finite (a divisor's interval reached 0) holds anything
    lost = ~np.logical_and.reduce([_finite(z) for z in loops.values()])
    none = np.full(w_low.shape, np.inf)
    with np.errstate(invalid="ignore", divide="ignore"):
        found = {"bandwidth_rad_s": bandwidth_bound(loops["closed"], w_low),
                 # |T| <= the farthest corner's modulus, T(0) = 1
                 "negative_peak_db": -20.0 * np.log10(_corner_moduli(loops["closed"])[1])}
        for prefix, loop in LOOP_PREFIXES.items():
            z = loops.get(loop)
            if z is None:
                found.update({prefix + name: none for name in LOOP_FIGURES})
                continue
            phase, magnitude = phase_margin_bound(z)
            found[prefix + "phase_margin_deg"] = phase
            found[prefix + "gain_margin_db"] = gain_margin_bound(z)
            # at a crossover in the cell, the margin's angle over a frequency below its top
            # (PM/w_c, or (360 deg - |PM|)/w_c for a negative PM: at least |PM|/w_c)
            found[prefix + "delay_margin_s"] = np.radians(magnitude) / w_high
            # |1 + L| >= the distance from -1 to the rectangle
            found[prefix + "negative_sensitivity_peak_db"] = 20.0 * np.log10(
                _corner_moduli(_cadd(z, _real((np.ones_like(w_low), np.ones_like(w_low)))))[0])
    found = {name: np.where(lost | np.isnan(values), UNKNOWN[name], values)
             for name, values in found.items()}
    minus_one = np.logical_or.reduce([holds_minus_one(loops[name]) for name in
                                      ("current", "velocity", "position") if name in loops])
    return found, minus_one | lost, _size(loops)


def bounds(base, keys, low, high, targets, max_cells=MAX_CELLS, shape=Shape()):
    """Guaranteed lower bounds of the position loop's phase and gain margins and the
    stability verdict over a box.

    Parameters
    ----------
    base : dict
        The nominal run's fields (:data:`FIELDS`' values), ``derive_mu`` (None, or the
        no-load current [A] and speed [rad/s] that mu_v = Km I0/w0 follows) and
        ``derive_tf`` (True where Tf = Kd/(10 Kp) follows the gains).
    keys : sequence of str
        The toleranced keys.
    low, high : numpy.ndarray
        The box [SI] per key.
    targets : dict
        Figure (:data:`FIGURES`) -> the worst found, the level the refinement aims at (the
        figures without a target are bounded by the cells as they end up).
    max_cells : int
        Most cells evaluated.
    shape : Shape
        The loop's architecture and fixed filters (:func:`shape_of`).

    Returns
    -------
    dict
        Each figure of :data:`FIGURES` -> its bound; ``stable``: True when no cell holds -1
        (False: not proved); ``cells``: evaluated.
    """
    d = len(keys)
    decades = math.log10(OMEGA_RANGE[1] / OMEGA_RANGE[0])
    count = int(math.ceil(decades * FIRST_CELLS_PER_DECADE))
    edges = np.geomspace(*OMEGA_RANGE, count + 1)
    # cells: parameter sub-boxes (unit coordinates), log-frequency intervals, and their
    # parent's size and split (none yet)
    cells = {"low": np.zeros((count, d)), "high": np.ones((count, d)),
             "w_low": edges[:-1].copy(), "w_high": edges[1:].copy(),
             **{f"parent_{name}": np.full(count, np.inf) for name in SIZES},
             "split": np.full(count, NO_SPLIT)}
    span = high - low
    evaluated = 0
    # the smallest bound of the cells retired (not refined further), per figure
    floors = dict.fromkeys(FIGURES, math.inf)
    # the open cells (their bounds still count) and how far each falls short of the targets
    pool = None
    while True:
        found, minus_one, size = _evaluate(base, keys, shape, low, span, cells)
        evaluated += cells["w_low"].size
        shortfall = np.where(minus_one, np.inf, 0.0)
        for name, target in targets.items():
            short = (_level(name, target) - found[name]) / (abs(target) or 1.0)
            shortfall = np.maximum(shortfall, np.where(short > 0, short, 0.0))
        retired = shortfall == 0
        for name, values in found.items():
            if retired.any():
                floors[name] = min(floors[name], float(np.min(values[retired])))
        cells.update(found, **size, shortfall=shortfall, minus_one=minus_one)
        pool = _joined(pool, _taken(cells, ~retired))
        count = pool["w_low"].size
        if not count or evaluated + 2 * min(count, REFINED) > max_cells:
            out = {name: min(floors[name], _smallest(pool[name], np.ones(count, bool)))
                   for name in FIGURES}
            return {**out, "stable": not bool(pool["minus_one"].any()), "cells": evaluated}
        # best first: the cells furthest below each figure's target are split, the rest wait
        # in the pool
        chosen = np.zeros(count, bool)
        chosen[_chosen(pool, targets, REFINED)] = True
        cells = _taken(pool, chosen)
        pool = _taken(pool, ~chosen)
        # a cell with a rectangle that is not finite: its size at its middle frequency
        # (the keys' share) says whether the frequency interval made it so (not for the
        # figures whose splits are not steered)
        probed = ~np.isfinite(cells["size"]) & ~_governing(cells, targets)[2]
        if evaluated + 2 * probed.size + np.count_nonzero(probed) > max_cells:
            probed[:] = False  # the budget's last round: no probe
        middle = np.sqrt(cells["w_low"][probed] * cells["w_high"][probed])
        tight_at_middle = np.zeros(probed.size, bool)
        if probed.any():
            at_middle = _evaluate(base, keys, shape, low, span, {
                "low": cells["low"][probed], "high": cells["high"][probed], "w_low": middle,
                "w_high": middle})[2]
            tight_at_middle[probed] = np.logical_or.reduce([
                ~np.isfinite(cells[f"size_{loop}"][probed]) & (at_middle[f"size_{loop}"] < TIGHT)
                for loop in SIZED])
            evaluated += middle.size
        cells = _split(cells, tight_at_middle, targets)


def _level(name, target):
    """The level a figure's bound must reach: its target, less 1e-4 of it for the bandwidth
    and a delay margin, or 1e-3 deg or dB for the others."""
    relative = name == "bandwidth_rad_s" or name.endswith("_s")
    return target - (1e-4 * abs(target) if relative else 1e-3)


def _chosen(pool, targets, count):
    """The pool's cells to split: every one that may hold -1, and for each figure an equal
    share of the cells whose bounds are lowest below its target (at most ``count``, those
    furthest short first)."""
    share = max(1, count // max(len(targets), 1))
    picks = [np.flatnonzero(pool["minus_one"])]
    for name, target in targets.items():
        below = np.flatnonzero(pool[name] < _level(name, target))
        picks.append(below[np.argsort(pool[name][below], kind="stable")[:share]])
    chosen = np.unique(np.concatenate(picks))
    if chosen.size > count:
        chosen = chosen[np.argsort(-pool["shortfall"][chosen], kind="stable")[:count]]
    return chosen


#: Cells split per round of the branch and bound, the ones that fall furthest short of the
#: worst found first (each gives two: one chunk of cells evaluated per round).
REFINED = CHUNK // 2
#: The frequency's share of a rectangle's size above which its cell splits the frequency
#: (:func:`_split_frequency`).
FREQUENCY_BOUND = 0.95
#: The size at a cell's middle frequency below which a cell whose rectangles are not finite
#: splits its frequency (the keys alone give a tight rectangle, :func:`_split_frequency`).
TIGHT = 0.1
#: The figures whose cells split their widest dimension, unsteered by the sizes (and every
#: loop's sensitivity peak).
UNSTEERED = ("bandwidth_rad_s", "negative_peak_db")
#: The loops whose rectangles' sizes steer the splits (:func:`_size`), and the loop of each
#: figure.
SIZED = ("current", "current_aat", "velocity", "velocity_aat", "position", "closed")
SIZES = (*(f"size_{name}" for name in SIZED), "size")
FIGURE_LOOPS = {**{prefix + name: loop for prefix, loop in LOOP_PREFIXES.items()
                   for name in LOOP_FIGURES},
                "bandwidth_rad_s": "closed", "negative_peak_db": "closed"}
#: A cell's last split: none (a first cell), along a key, along the frequency.
NO_SPLIT, KEY_SPLIT, FREQUENCY_SPLIT = -1, 0, 1


def _evaluate(base, keys, shape, low, span, cells):
    """Each figure's bound per cell, whether the cell may hold -1 and its rectangles' size
    (in chunks)."""
    parts = [_cell_bounds(base, keys, shape, low + cells["low"][k:k + CHUNK] * span,
                          low + cells["high"][k:k + CHUNK] * span,
                          cells["w_low"][k:k + CHUNK], cells["w_high"][k:k + CHUNK])
             for k in range(0, cells["w_low"].size, CHUNK)]
    return ({name: np.concatenate([part[0][name] for part in parts]) for name in FIGURES},
            np.concatenate([part[1] for part in parts]),
            {name: np.concatenate([part[2][name] for part in parts]) for name in parts[0][2]})


def _joined(a, b):
    """Two pools of cells (dicts of arrays by cell, a None: none) as one."""
    return b if a is None else {name: np.concatenate([a[name], b[name]]) for name in a}


def _taken(cells, rows):
    return {name: values[rows] for name, values in cells.items()}


def _governing(cells, targets):
    """Per cell: its rectangles' size and its parent's (:func:`_size`) of the loop whose
    figure falls furthest short of its target (of every loop where the cell may hold -1),
    and whether that figure is the bandwidth or a peak (:data:`UNSTEERED`)."""
    names = list(targets)
    size, parent = cells["size"].copy(), cells["parent_size"].copy()
    if not names:
        return size, parent, np.zeros(size.size, bool)
    short = np.stack([(_level(name, targets[name]) - cells[name]) / (abs(targets[name]) or 1.0)
                      for name in names])
    worst = np.argmax(short, axis=0)
    unsteered = np.zeros(size.size, bool)
    for k, name in enumerate(names):
        rows = (worst == k) & ~cells["minus_one"]
        loop = FIGURE_LOOPS[name]
        size[rows], parent[rows] = cells[f"size_{loop}"][rows], cells[f"parent_size_{loop}"][rows]
        unsteered |= rows & (name in UNSTEERED or name.endswith("sensitivity_peak_db"))
    return size, parent, unsteered


def _split_frequency(cells, tight_at_middle, targets):
    """Per cell: whether its frequency interval is split (else its widest key in unit width).

    The widest dimension in its own scale is split (a key in unit width, the frequency in
    tenths of a decade), except where the frequency makes most of the rectangle: the size
    (:func:`_size`) of the rectangle of the loop whose figure falls furthest short
    (:func:`_governing`) is taken as the sum of a share of the frequency's and one of the
    keys'. The last split halved its dimension's share, so the share it keeps is what the
    split took off (``parent_size - size``); where the frequency's share is above
    :data:`FREQUENCY_BOUND` of the size (near a lightly damped mode the keys' is a
    thousandth), the frequency is split. A cell whose size is not finite splits its
    frequency where ``tight_at_middle``: a loop's rectangle that is not finite over the cell
    is tight (size below :data:`TIGHT`) at its middle frequency. A cell short of the
    bandwidth (whose bound is its lowest frequency) or of a peak splits its widest dimension
    (measured: steered, the QT-CAS's sensitivity peak's gap over Km x Ki grows from 0.25 to
    6.3 dB)."""
    key_widths = cells["high"] - cells["low"]
    tenths = np.log10(cells["w_high"] / cells["w_low"]) * 10.0
    widest = tenths > np.max(key_widths, axis=1, initial=0.0)
    size, parent, bandwidth = _governing(cells, targets)
    informed = np.isfinite(size) & np.isfinite(parent) & (parent > 0) & (
        cells["split"] != NO_SPLIT) & ~bandwidth
    # the share of the dimension last split (halved: parent - size), the rest the other's
    with np.errstate(invalid="ignore"):
        last = np.clip(parent - size, 0.0, size)
    frequency_share = np.where(cells["split"] == FREQUENCY_SPLIT, last, size - last)
    steered = informed & (frequency_share > FREQUENCY_BOUND * size)
    probed = tight_at_middle
    return widest | steered | (probed & ~bandwidth)


def _split(cells, tight_at_middle, targets):
    """Each cell split in two halves (:func:`_split_frequency`): along its frequency (in
    decades) or along its widest key."""
    d = cells["low"].shape[1]
    frequency = _split_frequency(cells, tight_at_middle, targets) | (d == 0)
    along = np.where(frequency, d, np.argmax(cells["high"] - cells["low"], axis=1)
                     if d else 0)
    new_low_p, new_high_p = (np.repeat(cells[name], 2, axis=0) for name in ("low", "high"))
    new_low_w, new_high_w = (np.repeat(cells[name], 2) for name in ("w_low", "w_high"))
    first = np.arange(0, 2 * along.size, 2)
    rows = np.flatnonzero(~frequency)
    middle = 0.5 * (cells["low"][rows, along[rows]] + cells["high"][rows, along[rows]])
    new_high_p[first[rows], along[rows]] = middle
    new_low_p[first[rows] + 1, along[rows]] = middle
    rows = np.flatnonzero(frequency)
    middle = np.sqrt(cells["w_low"][rows] * cells["w_high"][rows])
    new_high_w[first[rows]] = middle
    new_low_w[first[rows] + 1] = middle
    return {"low": new_low_p, "high": new_high_p, "w_low": new_low_w, "w_high": new_high_w,
            **{f"parent_{name}": np.repeat(cells[name], 2) for name in SIZES},
            "split": np.repeat(np.where(frequency, FREQUENCY_SPLIT, KEY_SPLIT), 2)}


def box_bounds(config, params, keys, low, high, targets, max_cells=MAX_CELLS):
    """:func:`bounds` of a validated config's nominal run ``params`` (LoopParameters, one
    run) over the box of ``keys`` (its derived mu_v and Tf following their keys), or None
    with the reason where no bound is established (:func:`supported`)."""
    reason = supported(params, keys)
    if reason:
        return None, reason
    base = {field: float(getattr(params, field)[0]) for field in set(FIELDS.values())}
    motor = config.motor
    base["derive_mu"] = ((motor.no_load.current, motor.no_load.speed)
                         if motor.mu_v is None else None)
    base["derive_tf"] = config.position_loop.Tf is None
    return bounds(base, keys, np.asarray(low, float), np.asarray(high, float), targets,
                  max_cells, shape_of(params)), None
