"""The ``simulate`` command's data: a fin step, its figures and its second-order fit."""

import dataclasses
import io

import numpy as np

from cas_freq.fileio import json_ready
from cas_freq.simulation.commands import Step
from cas_freq.simulation.second_order import fit_second_order
from cas_freq.simulation.simulator import simulate
from cas_freq.simulation.step_figures import simulation_step_figures

#: Columns of the time-series CSV, with their units.
CSV_COLUMNS = (
    ("t", "s"), ("command_fin", "deg"), ("delta", "deg"), ("theta", "rad"), ("omega", "rad/s"),
    ("i", "A"), ("V", "V"), ("current_limited", "0/1"), ("voltage_limited", "0/1"),
)


@dataclasses.dataclass(frozen=True, eq=False)
class StepRun:
    """A simulated fin step of one variant, with its figures and second-order fit."""

    config: str
    config_path: str
    variant: str
    overrides: tuple
    result: object
    step: object
    fit: object


def step_run(loaded, amplitude_rad):
    """Simulate a fin step of ``amplitude_rad`` [rad] on one loaded variant and analyse it."""
    result = simulate(loaded.params, Step(amplitude_rad))
    figures = simulation_step_figures(result, amplitude_rad)
    fit = fit_second_order(result.t, result.delta, amplitude_rad)
    return StepRun(
        config=loaded.params.name,
        config_path=loaded.source,
        variant=loaded.variant,
        overrides=tuple(f"{key}={value}" for key, value in loaded.overrides),
        result=result,
        step=figures,
        fit=fit,
    )


def step_run_dict(run):
    """JSON-ready dict of a :class:`StepRun` (non-finite numbers become None)."""
    result = run.result
    return json_ready({
        "config": run.config,
        "config_path": run.config_path,
        "variant": run.variant,
        "overrides": list(run.overrides),
        "step": dataclasses.asdict(run.step),
        "fit": dataclasses.asdict(run.fit),
        "simulation": {
            "dt_s": result.dt_s,
            "t_end_s": result.t_end_s,
            "extended": result.extended,
            "settled": result.settled,
        },
    })


def step_csv_name(path, run, count):
    """CSV path for ``run``: ``path`` itself, or ``stem.<variant>.csv`` for several variants."""
    from pathlib import Path

    path = Path(path)
    return path if count == 1 else path.with_name(f"{path.stem}.{run.variant}{path.suffix}")


def step_run_csv(run):
    """The run's time series as CSV text (header names carry units)."""
    r = run.result
    columns = np.column_stack([
        r.t, np.degrees(r.command), np.degrees(r.delta), r.theta, r.omega, r.i, r.V,
        r.current_limited.astype(int), r.voltage_limited.astype(int),
    ])
    out = io.StringIO()
    out.write(",".join(f"{name} [{unit}]" for name, unit in CSV_COLUMNS) + "\n")
    np.savetxt(out, columns, delimiter=",", fmt="%.9g")
    return out.getvalue()
