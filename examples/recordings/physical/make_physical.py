"""Write the SYNTHETIC physical-model step recordings of this folder (see README.md).

Steps of the shipped QT-CAS config's nonlinear model (``cas_freq.simulation.simulate_batch``,
limits and delays as in configs/qt_cas.yaml) with KNOWN parameters, as a bench logger would
record them:

* ``step_*.csv``: the ``fitted`` variant (report Table 4: Km = 0.0075 N*m/A, J = 7.19e-7
  kg*m^2, mu_v = 1.2e-6 N*m*s/rad; Ke stays 0.0105 V*s/rad): two 10 deg steps (the current
  limit is reached) and a 2 deg step (it is not);
* ``friction_*.csv``: the same with a Coulomb friction of 2 mN*m at the motor
  (``motor.coulomb_friction``), two 10 deg steps and a 2 deg step: data for a model
  comparison (viscous only, or viscous and Coulomb);
* sampled irregularly around 10 kHz (each interval 100 us +- 20 %), a sample at the trigger
  t = 0 and 5 ms of pre-trigger, 60 ms after it;
* the fin angle: an encoder zero offset (0.2-0.5 deg per run), Gaussian noise 0.02 deg RMS,
  quantised to 360 / (2048 * 20) deg (512-count encoder, x4 quadrature, 20:1 gear: the same
  assumption as ../README.md);
* the motor current: Gaussian noise 0.05 A RMS, quantised to 1 mA.

Seeded: running it again writes the same files (to the printed digits). From the repository's
root:

    python examples/recordings/physical/make_physical.py
"""

from pathlib import Path

import numpy as np

from cas_freq.config import load_variant
from cas_freq.simulation import simulate_batch
from cas_freq.simulation.commands import Step

PERIOD_S, JITTER = 1e-4, 0.2
PRE_TRIGGER_S, POST_TRIGGER_S = 5e-3, 60e-3
COUNT_DEG = 360.0 / (2048 * 20)
NOISE_DEG, NOISE_A, CURRENT_LSB_A = 0.02, 0.05, 1e-3
SEED = 11
STEPS_DEG = (10.0, 10.0, 2.0)
#: file prefix -> (variant, --set overrides, what the truth is)
SETS = {
    "step": ("fitted", (), "variant fitted (Table 4)"),
    "friction": ("fitted", (("motor.coulomb_friction", 2e-3),),
                 "variant fitted (Table 4) with motor.coulomb_friction = 2 mN*m"),
}


def sample_times(rng):
    """Irregular times [s]: a sample at 0, intervals of PERIOD_S +- JITTER either side."""
    def side(length):
        steps = PERIOD_S * (1.0 + JITTER * rng.uniform(-1.0, 1.0, int(1.5 * length / PERIOD_S)))
        times = np.cumsum(steps)
        return times[times <= length]

    return np.concatenate([-side(PRE_TRIGGER_S)[::-1], [0.0], side(POST_TRIGGER_S)])


def simulated(variant, overrides, steps_deg):
    """(t [s], fin angle [rad] rows, current [A] rows) of the true model's steps."""
    loaded = load_variant(Path(__file__).resolve().parents[3] / "configs" / "qt_cas.yaml",
                          variant, overrides)
    current_rate, position_rate = loaded.params.simulation.rates_hz
    result = simulate_batch([loaded.params] * len(steps_deg), Step(np.radians(steps_deg)),
                            t_end=POST_TRIGGER_S + 1e-3, extend=False,
                            current_rate_hz=current_rate, position_rate_hz=position_rate)
    return result.t, result.delta, result.i


def main(folder=None):
    """Write the recordings into ``folder`` (default: this file's folder)."""
    folder = Path(folder) if folder is not None else Path(__file__).resolve().parent
    rng = np.random.default_rng(SEED)
    paths = []
    for prefix, (variant, overrides, truth) in SETS.items():
        t_sim, delta, current = simulated(variant, overrides, STEPS_DEG)
        for run, step in enumerate(STEPS_DEG):
            t = sample_times(rng)
            after = np.clip(t, 0.0, None)
            angle = np.where(t >= 0, np.degrees(np.interp(after, t_sim, delta[run])), 0.0)
            amps = np.where(t >= 0, np.interp(after, t_sim, current[run]), 0.0)
            offset = rng.uniform(0.2, 0.5)
            position = np.round((angle + offset + NOISE_DEG * rng.standard_normal(t.size))
                                / COUNT_DEG) * COUNT_DEG
            amps = np.round((amps + NOISE_A * rng.standard_normal(t.size)) / CURRENT_LSB_A) \
                * CURRENT_LSB_A
            command = np.where(t >= 0.0, step, 0.0)
            lines = [
                "# SYNTHETIC recording, not bench data: made by "
                "examples/recordings/physical/make_physical.py",
                f"# from configs/qt_cas.yaml {truth}, nonlinear simulator, {step:g} deg step at "
                "t = 0,",
                f"# sampled irregularly around 10 kHz, encoder offset {offset:.4f} deg, noise "
                f"{NOISE_DEG:g} deg RMS quantised to {COUNT_DEG:.6g} deg,",
                f"# current noise {NOISE_A:g} A RMS quantised to {CURRENT_LSB_A:g} A; run "
                f"{run + 1} of {len(STEPS_DEG)}, seed {SEED}",
                "time_s,command_deg,position_deg,current_a",
            ]
            lines += [f"{ti:.7f},{ci:g},{pi:.6f},{ii:.3f}"
                      for ti, ci, pi, ii in zip(t, command, position, amps, strict=True)]
            path = folder / f"{prefix}_{run + 1}_{step:g}deg.csv"
            path.write_text("\n".join(lines) + "\n", encoding="utf-8")
            paths.append(path)
    return paths


if __name__ == "__main__":
    for written in main():
        print(f"wrote {written}")
