"""Write the SYNTHETIC example step recordings of this folder (see README.md).

Three 10 deg steps of the report's own second-order-plus-delay model (ARL-TR-9136 §7:
wn = 462 rad/s, zeta = 0.54, td = 2 ms; :func:`cas_freq.simulation.second_order.second_order_step`),
as a bench logger would record them:

* sampled irregularly around 10 kHz (each interval 100 us +- 20 %, uniform), with a sample at
  the trigger t = 0 (the logger triggers on the command) and 5 ms of pre-trigger;
* the command column steps from 0 to 10 deg at t = 0;
* the fin angle read by the motor encoder: 512 counts per motor revolution, x4 quadrature =
  2048 counts/rev, through the 20:1 gear, so one count is 360 / (2048 * 20) deg = 0.00879 deg
  at the fin (an assumption: the report gives the encoder's 512 counts, not how it was decoded);
* an encoder zero offset (a different one per run, 0.2-0.5 deg) and Gaussian noise of
  0.03 deg RMS added before the quantisation.

Seeded: running it again writes the same files. Run from the repository's root:

    python examples/recordings/make_recordings.py
"""

import math
from pathlib import Path

import numpy as np

from cas_freq.simulation.second_order import second_order_step

WN_RAD_S, ZETA, TD_S = 462.0, 0.54, 2e-3
STEP_DEG = 10.0
PERIOD_S, JITTER = 1e-4, 0.2
PRE_TRIGGER_S, POST_TRIGGER_S = 5e-3, 50e-3
COUNT_DEG = 360.0 / (2048 * 20)
NOISE_DEG = 0.03
SEED = 3
RUNS = 3


def sample_times(rng):
    """Irregular times [s]: a sample at 0, intervals of PERIOD_S +- JITTER either side."""
    def side(length):
        steps = PERIOD_S * (1.0 + JITTER * rng.uniform(-1.0, 1.0, int(1.5 * length / PERIOD_S)))
        times = np.cumsum(steps)
        return times[times <= length]

    return np.concatenate([-side(PRE_TRIGGER_S)[::-1], [0.0], side(POST_TRIGGER_S)])


def recording(rng):
    """(time [s], command [deg], position [deg], offset [deg]) of one run."""
    t = sample_times(rng)
    command = np.where(t >= 0.0, STEP_DEG, 0.0)
    true = np.degrees(second_order_step(t, WN_RAD_S, ZETA, TD_S, math.radians(STEP_DEG)))
    offset = rng.uniform(0.2, 0.5)
    measured = true + offset + NOISE_DEG * rng.standard_normal(t.size)
    position = np.round(measured / COUNT_DEG) * COUNT_DEG
    return t, command, position, offset


def main(folder=None):
    """Write step_run1.csv .. step_run3.csv into ``folder`` (default: this file's folder)."""
    folder = Path(folder) if folder is not None else Path(__file__).resolve().parent
    rng = np.random.default_rng(SEED)
    paths = []
    for run in range(1, RUNS + 1):
        t, command, position, offset = recording(rng)
        lines = [
            "# SYNTHETIC recording, not bench data: made by examples/recordings/make_recordings.py",
            f"# from the second-order-plus-delay model wn = {WN_RAD_S:g} rad/s, zeta = {ZETA:g}, "
            f"td = {TD_S * 1e3:g} ms (ARL-TR-9136 §7), {STEP_DEG:g} deg step at t = 0,",
            f"# sampled irregularly around 10 kHz, encoder offset {offset:.4f} deg, Gaussian "
            f"noise {NOISE_DEG:g} deg RMS, quantised to {COUNT_DEG:.6g} deg",
            f"# (512-count encoder x4 quadrature, 20:1 gear); run {run} of {RUNS}, seed {SEED}",
            "time_s,command_deg,position_deg",
        ]
        lines += [f"{ti:.7f},{ci:g},{pi:.6f}" for ti, ci, pi in zip(t, command, position,
                                                                  strict=True)]
        path = folder / f"step_run{run}.csv"
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
        paths.append(path)
    return paths


if __name__ == "__main__":
    for written in main():
        print(f"wrote {written}")
