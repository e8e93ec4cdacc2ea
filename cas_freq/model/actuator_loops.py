"""The loops of one actuator as functions of s: continuous (:mod:`cas_freq.model.loops`) or
sampled (:mod:`cas_freq.model.sampled`), as its config declares."""

import numpy as np

import cas_freq.model.parts as parts
import cas_freq.model.sampled as sampled
from cas_freq.model.delay import EXACT
from cas_freq.model.loops import Selector, current_loop, responses
from cas_freq.model.structure import total_delay


class ActuatorLoops:
    """Frequency responses of every loop of one actuator, as functions of s.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig or cas_freq.core.parameters.LoopParameters
        Validated parameters (SI) of one variant.
    delay : DelayModel, optional
        Exact delays (default) or Padé of some order.

    Notes
    -----
    Each method takes complex frequencies ``s`` [rad/s] (use ``1j * omega``) and returns the
    complex response, vectorised over ``s``. All come from :func:`responses`.
    """

    def __init__(self, params, delay=EXACT):
        params = parts.one_variant(params)
        self.params = params
        self.delay = delay
        self._p = Selector(params)()  # one run: every parameter a scalar

    def _responses(self, s, closed=True, feedforward=False, output=None):
        s = np.asarray(s, dtype=complex)
        if self.sampled:
            return sampled.responses(self._p, s, closed, output=output, feedforward=feedforward)
        return responses(self._p, s, closed, self.delay, feedforward, output=output)

    @property
    def sampled(self):
        """True for sampled controllers (``sampling:``): every response is then that of the
        sampled loops at z = e^(j omega T) (:mod:`cas_freq.model.sampled`)."""
        return bool(getattr(self._p, "sample_rates", ()))

    def current_loop(self, s):
        """L_i(s) = C_i(s) e^(-s tau_c) Y(s), broken at the voltage [-]."""
        if self.sampled:
            return self._responses(s, closed=False).current_loop
        return current_loop(self._p, np.asarray(s, dtype=complex), self.delay)

    def current_closed_loop(self, s):
        """T_i(s) = L_i/(1 + L_i) = i/i_cmd [-]."""
        loop = self.current_loop(s)
        return loop / (1.0 + loop)

    def position_loop(self, s):
        """L_p(s) = C_p(s) e^(-s tau_p) T_i(s) M(s), broken at the current command [-]."""
        return self._responses(s, closed=False).position_loop

    def sensitivity(self, s):
        """S(s) = 1/(1 + L_p) [-]."""
        return 1.0 / (1.0 + self.position_loop(s))

    def closed_loop(self, s, feedforward=False):
        """T(s) = theta/theta_cmd = delta/delta_cmd [-] (with the feed-forward if asked)."""
        return self._responses(s, feedforward=feedforward).closed_loop

    def current_response(self, s):
        r"""i/delta_cmd [A/rad]: the motor current per output command, without feed-forward.

        The closed loop read at the current instead of the output:
        :math:`i/\delta_{cmd} = N\, i/\theta_{cmd}`.
        """
        return self._p.ratio * self._responses(s, output="current").closed_loop

    @property
    def total_delay(self):
        """Sum of the transport delays [s] (sets how finely a grid must sample the phase)."""
        return total_delay(self._p)
