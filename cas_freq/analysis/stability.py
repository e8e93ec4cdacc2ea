"""Closed-loop stability from the poles of the Padé model (MODEL.md, "Stability").

The position closed loop contains the current closed loop, so its poles decide both. A pole
whose real part is within a relative 1e-9 of zero is called marginal: the loop neither grows nor
decays there, and no frequency-domain figure of it is trustworthy.
"""

import dataclasses

import numpy as np

#: |Re p| <= MARGINAL_TOLERANCE * max(1, |p|) counts as on the imaginary axis.
MARGINAL_TOLERANCE = 1e-9


@dataclasses.dataclass(frozen=True)
class Stability:
    """Closed-loop stability verdict.

    Attributes
    ----------
    verdict : str
        ``"stable"``, ``"marginal"`` or ``"unstable"``.
    pade_order : int
        Padé order of the delays in the model whose poles were computed.
    current_loop_verdict : str
        The same verdict for the current loop T_i alone.
    poles : tuple of (float, float)
        Closed-loop poles of T as (real, imaginary) [rad/s], sorted by real part, largest first.
    """

    verdict: str
    pade_order: int
    current_loop_verdict: str
    poles: tuple

    @property
    def stable(self):
        """True only for a strictly stable closed loop."""
        return self.verdict == "stable"


def pole_verdict(poles):
    """``"stable"``, ``"marginal"`` or ``"unstable"`` for continuous-time poles [rad/s]."""
    poles = np.asarray(poles, dtype=complex)
    if poles.size == 0:
        return "stable"
    tolerance = MARGINAL_TOLERANCE * np.maximum(1.0, np.abs(poles))
    if np.any(poles.real > tolerance):
        return "unstable"
    if np.any(np.abs(poles.real) <= tolerance):
        return "marginal"
    return "stable"


def closed_loop_stability(params, pade_order):
    """Stability of the current loop and of the whole actuator, from Padé-model poles.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        Validated parameters.
    pade_order : int
        Padé order of the delays.

    Returns
    -------
    Stability
    """
    from cas_freq.model.systems import linear_model

    model = linear_model(params, pade_order)
    poles = np.asarray(model.closed_loop.poles(), dtype=complex)
    poles = poles[np.argsort(-poles.real, kind="stable")]
    return Stability(
        verdict=pole_verdict(poles),
        pade_order=pade_order,
        current_loop_verdict=pole_verdict(model.current_closed_loop.poles()),
        poles=tuple((float(p.real), float(p.imag)) for p in poles),
    )
