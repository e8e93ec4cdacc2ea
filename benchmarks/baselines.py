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
"""

import math

import numpy as np

#: -3.0103 dB: the half-power level cas_freq's bandwidth is defined at (docs/model.md).
HALF_POWER_DB = 20 * math.log10(1 / math.sqrt(2))


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

        def value(key, default):
            return float(changes[key][index]) if key in changes else default

        motor, cur, pos = self.params.motor, self.params.current_loop, self.params.position_loop
        km, j = value("motor.Km", motor.Km), value("motor.J", motor.J)
        mu = motor.viscous_friction * km / motor.Km if motor.mu_v is None else motor.mu_v
        ti_num, ti_den, pm_i = self._current_loop(value("current_loop.Kp", cur.Kp), cur.Ki,
                                                  km, j, mu)
        kp, ki, kd = (value("position_loop.Kp", pos.Kp), value("position_loop.Ki", pos.Ki),
                      value("position_loop.Kd", pos.Kd))
        tf = pos.Tf if pos.Tf is not None else kd / (10 * kp)
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
