"""Every frequency-domain figure of one actuator variant (the ``analyze`` command's data).

:func:`analyze` composes the loops of :mod:`cas_freq.model`, finds the margins of both loops,
the closed-loop figures and the Padé-model stability, and, on request, the same figures at Padé
orders 1..n beside the exact-delay ones. The result is plain frozen data; :func:`to_dict` turns
it into JSON-ready dicts (non-finite numbers become None).
"""

import dataclasses

import numpy as np

from cas_freq.analysis.closed_loop import ClosedLoopFigures, closed_loop_figures
from cas_freq.analysis.frequency import (
    DEFAULT_POINTS_PER_DECADE,
    DEFAULT_RANGE_RAD_S,
    frequency_grid,
)
from cas_freq.analysis.margins import LoopMargins, loop_margins, without_closed_loop_figures
from cas_freq.analysis.stability import Stability, closed_loop_stability
from cas_freq.fileio import json_ready
from cas_freq.model import DEFAULT_PADE_ORDER, ActuatorLoops, DelayModel
from cas_freq.model.delay import EXACT


@dataclasses.dataclass(frozen=True)
class PadeComparison:
    """Headline figures at one delay model (a row of the Padé-vs-exact table).

    ``closed_loop_max_error`` is max |T_pade - T_exact| over the analysis grid (0 for exact).
    """

    delay_model: str
    current_phase_margin_deg: float | None
    current_crossover_rad_s: float | None
    current_gain_margin_db: float | None
    position_phase_margin_deg: float | None
    position_crossover_rad_s: float | None
    position_gain_margin_db: float | None
    position_gain_margin_low_db: float | None
    bandwidth_rad_s: float | None
    peak_db: float
    phase_90_rad_s: float | None
    closed_loop_max_error: float


@dataclasses.dataclass(frozen=True)
class Analysis:
    """Every figure of one variant under one delay model. See MODEL.md for the definitions.

    Closed-loop figures are None when the closed loop is not stable: a frequency response of
    an unstable loop has no steady state to measure.
    """

    config: str
    config_path: str
    variant: str
    overrides: tuple
    delay_model: str
    frequency_range_rad_s: tuple[float, float]
    stable: bool
    stability: Stability
    current_loop: LoopMargins
    position_loop: LoopMargins
    closed_loop: ClosedLoopFigures | None
    pade_vs_exact: tuple[PadeComparison, ...]
    notes: tuple[str, ...]


def _comparison(label, current, position, closed, error):
    return PadeComparison(
        delay_model=label,
        current_phase_margin_deg=current.phase_margin_deg,
        current_crossover_rad_s=current.crossover_rad_s,
        current_gain_margin_db=current.gain_margin_db,
        position_phase_margin_deg=position.phase_margin_deg,
        position_crossover_rad_s=position.crossover_rad_s,
        position_gain_margin_db=position.gain_margin_db,
        position_gain_margin_low_db=position.gain_margin_low_db,
        bandwidth_rad_s=closed.bandwidth_rad_s,
        peak_db=closed.peak_db,
        phase_90_rad_s=closed.phase_90_rad_s,
        closed_loop_max_error=error,
    )


def pade_study(params, max_order, omega):
    """Headline figures with Padé delays of order 1..max_order, then with exact delays.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        Validated parameters.
    max_order : int
        Highest Padé order, >= 1.
    omega : numpy.ndarray
        Analysis grid [rad/s].

    Returns
    -------
    tuple of PadeComparison
        One row per order, the exact row last.
    """
    exact = ActuatorLoops(params, DelayModel())
    reference = exact.closed_loop(1j * omega)
    rows = []
    for order in [*range(1, max_order + 1), None]:
        loops = ActuatorLoops(params, DelayModel(order))
        response = loops.closed_loop(1j * omega)
        rows.append(
            _comparison(
                loops.delay.label,
                loop_margins(loops.current_loop, omega),
                loop_margins(loops.position_loop, omega),
                closed_loop_figures(loops.closed_loop, omega),
                float(np.max(np.abs(response - reference))),
            )
        )
    return tuple(rows)


def analyze(
    loaded,
    delay=EXACT,
    frequency_range=DEFAULT_RANGE_RAD_S,
    points_per_decade=DEFAULT_POINTS_PER_DECADE,
    pade_orders=0,
):
    """Analyse one loaded config variant.

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant
        The variant to analyse.
    delay : DelayModel
        Delay representation for every frequency response (exact by default).
    frequency_range : (float, float)
        Analysed range [rad/s]; crossings outside it are not reported.
    points_per_decade : int
        Grid density before refinement [1/decade].
    pade_orders : int
        If > 0, also tabulate the headline figures at Padé orders 1..pade_orders and exact.

    Returns
    -------
    Analysis
    """
    params = loaded.params
    loops = ActuatorLoops(params, delay)
    omega = frequency_grid(*frequency_range, points_per_decade, loops.total_delay)
    stability = closed_loop_stability(params, delay.order or DEFAULT_PADE_ORDER)
    notes = []
    if delay.exact:
        notes.append(
            f"stability from the poles of the Padé model of order {stability.pade_order}; "
            "every frequency figure uses exact delays"
        )
    closed = None
    if stability.stable:
        closed = closed_loop_figures(loops.closed_loop, omega)
    else:
        notes.append(
            f"closed loop is {stability.verdict}: closed-loop figures (bandwidth, peak) are not "
            "reported; the open-loop margins still say how far the loop is from stability"
        )
    if stability.current_loop_verdict != "stable":
        notes.append(f"the current loop alone is {stability.current_loop_verdict}")
    current = loop_margins(loops.current_loop, omega)
    position = loop_margins(loops.position_loop, omega)
    if stability.current_loop_verdict != "stable":
        current = without_closed_loop_figures(current)
    if not stability.stable:
        position = without_closed_loop_figures(position)
        notes.append("sensitivity peak and disk margin are not reported for a loop that is "
                     "not stable")
    rows = pade_study(params, pade_orders, omega) if pade_orders > 0 else ()
    return Analysis(
        config=params.name,
        config_path=loaded.source,
        variant=loaded.variant,
        overrides=tuple(f"{key}={value}" for key, value in loaded.overrides),
        delay_model=delay.label,
        frequency_range_rad_s=(float(omega[0]), float(omega[-1])),
        stable=stability.stable,
        stability=stability,
        current_loop=current,
        position_loop=position,
        closed_loop=closed,
        pade_vs_exact=rows,
        notes=tuple(notes),
    )


def to_dict(analysis):
    """JSON-ready dict of an :class:`Analysis` (non-finite numbers become None)."""
    data = dataclasses.asdict(analysis)
    stability = data.pop("stability")
    data["stability"] = stability["verdict"]
    data["stability_pade_order"] = stability["pade_order"]
    data["current_loop"]["stability"] = stability["current_loop_verdict"]
    data["closed_loop_poles"] = [list(pole) for pole in stability["poles"]]
    if data["closed_loop"] is None:
        data["closed_loop"] = {
            field.name: None for field in dataclasses.fields(ClosedLoopFigures)
        }
    return json_ready(data)
