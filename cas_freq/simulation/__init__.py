"""Nonlinear time-domain simulation of the actuator loop (numpy, scipy and numba).

- :mod:`~cas_freq.simulation.kernel`: the fixed-step loop compiled with numba (the default
  engine; cached on disk after the first compile), and :mod:`~cas_freq.simulation.engine`, the
  same loop in numpy, kept as the reference the kernel is tested against
  (``simulate_batch(..., engine="reference")`` or ``CAS_FREQ_ENGINE=reference``);
- :mod:`~cas_freq.simulation.commands`: output-angle commands (step, ramp, sine, chirp, CSV table,
  trapezoidal profile move);
- :class:`LoopParameters` (of :mod:`cas_freq.core.parameters`, re-exported): loop parameters of a
  batch of runs;
- :mod:`~cas_freq.simulation.simulator`: :func:`simulate` and :func:`simulate_batch`;
- :mod:`~cas_freq.simulation.step_figures`: rise, overshoot, settling, peak, limits;
- :mod:`~cas_freq.simulation.profile_figures` and :mod:`~cas_freq.studies.profile_run`: a
  profile move's tracking error, overshoot, settling, with and without feed-forward;
- :mod:`~cas_freq.simulation.second_order`: the report's §7 second-order-plus-delay fit, of one
  response or many at once.

Nothing here imports python-control or matplotlib.
"""

from cas_freq.core.parameters import LoopParameters
from cas_freq.simulation.commands import (
    Chirp,
    Profile,
    Ramp,
    Sine,
    Step,
    Table,
    motor_command,
    read_command_csv,
)
from cas_freq.simulation.second_order import (
    SecondOrderFit,
    fit_second_order,
    fit_second_order_batch,
    second_order_step,
)
from cas_freq.simulation.simulator import (
    BatchResult,
    SimulationResult,
    default_time_step,
    simulate,
    simulate_batch,
    step_bound,
)
from cas_freq.simulation.step_figures import StepFigures, simulation_step_figures, step_figures

__all__ = [
    "BatchResult",
    "Chirp",
    "LoopParameters",
    "Profile",
    "Ramp",
    "SecondOrderFit",
    "SimulationResult",
    "Sine",
    "Step",
    "StepFigures",
    "Table",
    "default_time_step",
    "fit_second_order",
    "fit_second_order_batch",
    "motor_command",
    "read_command_csv",
    "second_order_step",
    "simulate",
    "simulate_batch",
    "simulation_step_figures",
    "step_bound",
    "step_figures",
]
