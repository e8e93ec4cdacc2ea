"""Model layer: the parts of the actuator loop and their frequency responses.

:mod:`~cas_freq.model.parts` (plant and controllers, written once), :mod:`~cas_freq.model.loops`
(responses of any number of variants) and :mod:`~cas_freq.model.delay` need only numpy;
:mod:`~cas_freq.analysis.systems` builds python-control systems and is imported on demand.
"""

from cas_freq.model.actuator_loops import ActuatorLoops
from cas_freq.model.delay import DEFAULT_PADE_ORDER, DelayModel

__all__ = ["DEFAULT_PADE_ORDER", "ActuatorLoops", "DelayModel"]
