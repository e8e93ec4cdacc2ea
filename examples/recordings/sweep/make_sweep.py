"""Write the SYNTHETIC example sweep recording of this folder (see README.md).

A logarithmic chirp of the fin command, 0.5 deg from 30 to 3000 rad/s over 1 s, run through the
package's nonlinear simulator (:func:`cas_freq.simulation.simulate`, continuous controllers)
on the shipped config's ``fitted`` variant with the feed-forward off (the loop of docs/model.md's
T, as ``cas-freq sinedwell`` measures it by default). At 0.5 deg neither the current limit nor the
voltage limit acts (checked: the script stops if one does), so the recording is the linear
loop's response. It is then recorded as a bench logger would:

* sampled irregularly around 5 kHz (each interval 200 us +- 20 %, uniform);
* 20 ms of pre-trigger hold (command 0) before the chirp starts, 20 ms of hold after it;
* the fin angle read by the motor encoder: 360 / (2048 * 20) deg per count at the fin (512
  counts x4 quadrature through the 20:1 gear; the assumption of ../README.md), after Gaussian
  noise of 0.005 deg RMS;
* the motor current with Gaussian noise of 0.02 A RMS, quantised to 1 mA; the current command
  (the simulator's ``current_command``, the position controller's output at the current
  controller) quantised to 1 mA.

Seeded: running it again writes the same file. Run from the repository's root:

    python examples/recordings/sweep/make_sweep.py
"""

import math
from pathlib import Path

import numpy as np

from cas_freq.config import load_variant
from cas_freq.core.parameters import LoopParameters
from cas_freq.simulation import simulate
from cas_freq.simulation.commands import Chirp

CONFIG, VARIANT = "configs/qt_cas.yaml", "fitted"
AMPLITUDE_DEG, START_RAD_S, STOP_RAD_S, DURATION_S = 0.5, 30.0, 3000.0, 1.0
HOLD_S = 20e-3
PERIOD_S, JITTER = 2e-4, 0.2
COUNT_DEG = 360.0 / (2048 * 20)
NOISE_DEG, NOISE_A, CURRENT_STEP_A = 0.005, 0.02, 1e-3
SEED = 5


def simulated(root):
    """(times [s], command [rad], fin angle [rad], current [A], current command [A]) of the
    simulated chirp, the chirp starting at HOLD_S."""
    loaded = load_variant(root / CONFIG, VARIANT)
    params = LoopParameters.from_config(loaded.params).without_feedforward()
    chirp = Chirp(math.radians(AMPLITUDE_DEG), START_RAD_S, STOP_RAD_S, DURATION_S, "log",
                  start_s=HOLD_S)
    run = simulate(params, chirp, t_end=DURATION_S + 2 * HOLD_S)
    if np.any(run.current_limited) or np.any(run.voltage_limited):
        raise SystemExit("make_sweep: a limit acted; lower AMPLITUDE_DEG")
    return run.t, run.command, run.delta, run.i, run.current_command


def main(folder=None):
    """Write sweep_chirp.csv into ``folder`` (default: this file's folder)."""
    here = Path(__file__).resolve().parent
    folder = Path(folder) if folder is not None else here
    t_sim, command, delta, current, current_command = simulated(here.parents[2])
    rng = np.random.default_rng(SEED)
    steps = PERIOD_S * (1.0 + JITTER * rng.uniform(-1.0, 1.0, int(1.5 * t_sim[-1] / PERIOD_S)))
    t = np.concatenate([[0.0], np.cumsum(steps)])
    t = t[t <= t_sim[-1]]
    sample = {name: np.interp(t, t_sim, values) for name, values in
              (("command", command), ("delta", delta), ("i", current),
               ("i_cmd", current_command))}
    position = np.degrees(sample["delta"]) + NOISE_DEG * rng.standard_normal(t.size)
    position = np.round(position / COUNT_DEG) * COUNT_DEG + 0.0
    i = np.round((sample["i"] + NOISE_A * rng.standard_normal(t.size)) / CURRENT_STEP_A) + 0.0
    i_cmd = np.round(sample["i_cmd"] / CURRENT_STEP_A) + 0.0
    lines = [
        "# SYNTHETIC recording, not bench data: made by "
        "examples/recordings/sweep/make_sweep.py",
        f"# log chirp {AMPLITUDE_DEG:g} deg, {START_RAD_S:g} to {STOP_RAD_S:g} rad/s over "
        f"{DURATION_S:g} s from t = {HOLD_S * 1e3:g} ms, simulated (nonlinear simulator, "
        f"no limit active) on {CONFIG} variant {VARIANT}, feed-forward off;",
        f"# sampled irregularly around {1 / PERIOD_S / 1e3:g} kHz, fin angle with "
        f"{NOISE_DEG:g} deg RMS noise quantised to {COUNT_DEG:.6g} deg (512-count encoder x4,",
        f"# 20:1 gear), current with {NOISE_A:g} A RMS noise, currents quantised to 1 mA; "
        f"seed {SEED}",
        "time_s,command_deg,position_deg,current_a,current_command_a",
    ]
    lines += [f"{ti:.7f},{ci:.6f},{pi:.6f},{ii * CURRENT_STEP_A:.3f},{ki * CURRENT_STEP_A:.3f}"
              for ti, ci, pi, ii, ki in zip(t, np.degrees(sample["command"]), position, i,
                                            i_cmd, strict=True)]
    path = folder / "sweep_chirp.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return [path]


if __name__ == "__main__":
    for written in main():
        print(written)
