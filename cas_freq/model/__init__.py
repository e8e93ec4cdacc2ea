"""Model layer: transfer functions and systems of the actuator (imports config only).

:mod:`~cas_freq.model.transfer` and :mod:`~cas_freq.model.delay` need only numpy;
:mod:`~cas_freq.model.systems` builds python-control systems and is imported on demand.
"""

from cas_freq.model.delay import DEFAULT_PADE_ORDER, DelayModel
from cas_freq.model.transfer import ActuatorLoops

__all__ = ["DEFAULT_PADE_ORDER", "ActuatorLoops", "DelayModel"]
