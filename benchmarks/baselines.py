"""python-control baselines of the frequency-domain benchmark: how a competent user would
compute the margins and bandwidth of many variants with python-control alone.

``naive_figures`` (in run.py) builds each loop with ``control.tf`` arithmetic and calls
``stability_margins`` and ``bandwidth`` per variant. :class:`ImprovedBaseline` is what an
engineer who has profiled that loop writes instead:

- the transfer functions are built from numpy polynomials (``np.polymul``), not by
  ``TransferFunction`` arithmetic (which simplifies and checks at every product);
- the current loop (L_i, its margins and T_i) is computed once per distinct set of
  current-loop values and reused (a Kp x Kd grid then builds it once);
- the margins come from ``control.stability_margins`` (python-control's own, on the Padé
  model: the same method as the naive loop);
- the bandwidth is read off |T(jw)| on a fixed log grid (numpy ``polyval``), interpolated
  linearly in log frequency at the first -3.0103 dB crossing: no root search per variant.

Both use Padé-6 delays: python-control has no exact delay in a transfer function.

:class:`CarefulBaseline` is the strongest fair python-control loop for the same figures, the
one the speed claims are held against (issue 40): the delays exact, as a careful user puts
them in (the rational parts' ``control.frequency_response`` on one grid, vectorised over it,
times :math:`e^{-j\\omega\tau}`); the current loop computed once per distinct set of its
values; each figure read off the grid at its first crossing and refined by interpolation in
log frequency between the two grid points around it (no root search, no Padé model); the
transfer functions built from numpy polynomials, not by transfer-function arithmetic. The grid
is cas_freq's own (:func:`cas_freq.analysis.frequency.frequency_grid`, densified where the
delays turn the phase), so both sides look at the same points.
"""

import math

import numpy as np

#: -3.0103 dB: the half-power level cas_freq's bandwidth is defined at (docs/model.md).
HALF_POWER_DB = 20 * math.log10(1 / math.sqrt(2))


def variant_values(params, changes, index):
    """The values of variant ``index`` (``changes``: key -> array; the others the config's):
    (Km, J, mu_v, current Kp, current Ki, position Kp, Ki, Kd, Tf)."""
    def value(key, default):
        return float(changes[key][index]) if key in changes else default

    motor, cur, pos = params.motor, params.current_loop, params.position_loop
    km, j = value("motor.Km", motor.Km), value("motor.J", motor.J)
    mu = motor.viscous_friction * km / motor.Km if motor.mu_v is None else motor.mu_v
    kp, ki, kd = (value("position_loop.Kp", pos.Kp), value("position_loop.Ki", pos.Ki),
                  value("position_loop.Kd", pos.Kd))
    tf = pos.Tf if pos.Tf is not None else kd / (10 * kp)
    return km, j, mu, value("current_loop.Kp", cur.Kp), cur.Ki, kp, ki, kd, tf


def _pade(delay, order):
    import control

    return control.pade(delay, order) if delay > 0 else ([1.0], [1.0])


class ImprovedBaseline:
    """Margins and bandwidth per variant, python-control with the care of a competent user.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        The base config.
    order : int
        Padé order of both delays.
    grid_rad_s : numpy.ndarray, optional
        Fixed frequency grid of the bandwidth [rad/s] (default 2,000 points over 0.1..1e6).
    """

    def __init__(self, params, order=6, grid_rad_s=None):
        self.params, self.order = params, order
        self.w = np.logspace(-1, 6, 2000) if grid_rad_s is None else np.asarray(grid_rad_s)
        self.jw = 1j * self.w
        self._current = {}

    def _current_loop(self, kp_i, ki_i, km, j, mu):
        """(T_i numerator, denominator, PM of L_i [deg]) for these current-loop values."""
        import control

        key = (kp_i, ki_i, km, j, mu)
        if key not in self._current:
            m, cur = self.params.motor, self.params.current_loop
            y_num = np.array([j, mu])
            y_den = np.polyadd(np.polymul([m.L, m.R], [j, mu]), [m.Ke * km])
            d_num, d_den = _pade(cur.delay, self.order)
            num = np.polymul(np.polymul([kp_i, ki_i], d_num), y_num)
            den = np.polymul(np.polymul([1.0, 0.0], d_den), y_den)
            with np.errstate(over="ignore"):
                _, pm_i, *_ = control.stability_margins(control.tf(num, den))
            self._current[key] = (num, np.polyadd(den, num), pm_i)
        return self._current[key]

    def figures(self, changes, index):
        """PM of both loops [deg], the position crossover [rad/s] and the bandwidth [rad/s]."""
        import control

        km, j, mu, kp_i, ki_i, kp, ki, kd, tf = variant_values(self.params, changes, index)
        ti_num, ti_den, pm_i = self._current_loop(kp_i, ki_i, km, j, mu)
        pos = self.params.position_loop
        # C_p = (Kp s (Tf s + 1) + Ki (Tf s + 1) + Kd s^2) / (s (Tf s + 1)); M = Km / (s (J s + mu))
        c_num = np.polyadd(np.polyadd(np.polymul([kp, 0.0], [tf, 1.0]), ki * np.array([tf, 1.0])),
                           [kd, 0.0, 0.0])
        c_den = [tf, 1.0, 0.0]
        d_num, d_den = _pade(pos.delay, self.order)
        num = np.polymul(np.polymul(np.polymul(c_num, d_num), ti_num), [km])
        den = np.polymul(np.polymul(np.polymul(c_den, d_den), ti_den), [j, mu, 0.0])
        with np.errstate(over="ignore"):
            _, pm_p, _, _, wc_p, _ = control.stability_margins(control.tf(num, den))
        t_db = 20 * np.log10(np.abs(np.polyval(num, self.jw)
                                    / np.polyval(np.polyadd(den, num), self.jw)))
        return {"current_loop.phase_margin_deg": pm_i, "position_loop.phase_margin_deg": pm_p,
                "position_loop.crossover_rad_s": wc_p,
                "closed_loop.bandwidth_rad_s": self._bandwidth(t_db)}

    def _bandwidth(self, t_db):
        """First frequency where |T| falls below its DC value - 3.0103 dB, interpolated [rad/s]."""
        level = t_db[0] + HALF_POWER_DB
        below = np.flatnonzero(t_db < level)
        if below.size == 0 or below[0] == 0:
            return math.nan
        k = below[0]
        x0, x1 = math.log(self.w[k - 1]), math.log(self.w[k])
        y0, y1 = t_db[k - 1], t_db[k]
        return math.exp(x0 + (level - y0) * (x1 - x0) / (y1 - y0))


def _crossing(values, level, log_w):
    """(index k, fraction) of the first fall of ``values`` through ``level`` between grid
    points k and k + 1, None where there is none."""
    below = values < level
    found = np.flatnonzero(below[1:] & ~below[:-1])
    if found.size == 0:
        return None
    k = int(found[0])
    return k, (values[k] - level) / (values[k] - values[k + 1])


class CarefulBaseline:
    """Margins and bandwidth per variant with exact delays, python-control as a careful user
    writes it (module notes): PM of both loops [deg], the position loop's crossover [rad/s]
    and the -3.0103 dB bandwidth of T [rad/s], the figures of :class:`ImprovedBaseline`.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        The base config (the report's PID-on-PI drive).
    omega : numpy.ndarray
        The frequency grid [rad/s].
    """

    def __init__(self, params, omega):
        self.params = params
        self.w = np.asarray(omega, dtype=float)
        self.log_w = np.log(self.w)
        self._current = {}

    def _response(self, system):
        import control

        return control.frequency_response(system, self.w).complex

    def _current_loop(self, kp_i, ki_i, km, j, mu):
        """(T_i on the grid, PM of L_i [deg]) for these current-loop values."""
        import control

        key = (kp_i, ki_i, km, j, mu)
        if key not in self._current:
            m, cur = self.params.motor, self.params.current_loop
            y_den = np.polyadd(np.polymul([m.L, m.R], [j, mu]), [m.Ke * km])
            rational = control.tf(np.polymul([kp_i, ki_i], [j, mu]), np.polymul([1.0, 0.0], y_den))
            l_i = self._response(rational) * np.exp(-1j * self.w * cur.delay)
            self._current[key] = (l_i / (1.0 + l_i), self._phase_margin(l_i)[0])
        return self._current[key]

    def _phase_margin(self, loop):
        """(PM [deg], crossover [rad/s]) at the first fall of |L| through 1."""
        magnitude = np.log(np.abs(loop))
        found = _crossing(magnitude, 0.0, self.log_w)
        if found is None:
            return math.nan, math.nan
        k, f = found
        phase = np.unwrap(np.angle(loop[k:k + 2]))
        at = phase[0] + f * (phase[1] - phase[0])
        w = math.exp(self.log_w[k] + f * (self.log_w[k + 1] - self.log_w[k]))
        return (math.degrees(at) + 360.0) % 360.0 - 180.0, w

    def figures(self, changes, index):
        """PM of both loops [deg], the position crossover [rad/s] and the bandwidth [rad/s]."""
        import control

        km, j, mu, kp_i, ki_i, kp, ki, kd, tf = variant_values(self.params, changes, index)
        t_i, pm_i = self._current_loop(kp_i, ki_i, km, j, mu)
        pos = self.params.position_loop
        # C_p M = (Kp s (Tf s + 1) + Ki (Tf s + 1) + Kd s^2) Km / (s (Tf s + 1) s (J s + mu)),
        # multiplied out in numpy (python-control's transfer-function arithmetic costs ~10 ms)
        c_num = np.polyadd(np.polyadd(np.polymul([kp, 0.0], [tf, 1.0]), ki * np.array([tf, 1.0])),
                           [kd, 0.0, 0.0])
        rational = control.tf(km * c_num, np.polymul([tf, 1.0, 0.0], [j, mu, 0.0]))
        l_p = self._response(rational) * np.exp(-1j * self.w * pos.delay) * t_i
        pm_p, wc_p = self._phase_margin(l_p)
        t_db = 20 * np.log10(np.abs(l_p / (1.0 + l_p)))
        found = _crossing(t_db, t_db[0] + HALF_POWER_DB, self.log_w)
        bandwidth = math.nan
        if found is not None:
            k, f = found
            bandwidth = math.exp(self.log_w[k] + f * (self.log_w[k + 1] - self.log_w[k]))
        return {"current_loop.phase_margin_deg": pm_i, "position_loop.phase_margin_deg": pm_p,
                "position_loop.crossover_rad_s": wc_p, "closed_loop.bandwidth_rad_s": bandwidth}
