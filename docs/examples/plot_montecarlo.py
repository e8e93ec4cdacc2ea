"""
# A Monte Carlo of 200 samples

The QT-CAS's margins and bandwidth when the motor's torque constant and inertia vary within
their tolerances (normal, ±10 % and ±5 % at 3 sigma), in the frequency domain only:
`act.vary` evaluates all 200 variants at once with the batch engine of `cas-freq montecarlo`.
"""

import matplotlib.pyplot as plt
import numpy as np

import cas_freq as cf

act = cf.load()
rng = np.random.default_rng(1)
n = 200
km = act.params.motor.Km * (1 + 0.10 / 3 * rng.standard_normal(n))
j = act.params.motor.J * (1 + 0.05 / 3 * rng.standard_normal(n))
res = act.vary({"motor.Km": km, "motor.J": j}).analyze()

bandwidth = res.closed_loop.bandwidth_rad_s          # one value per sample [rad/s]
phase_margin = res.position_loop.phase_margin_deg    # [deg]
print(f"bandwidth p5..p95: {np.percentile(bandwidth, 5):.4g}..{np.percentile(bandwidth, 95):.4g}"
      f" rad/s; phase margin p5..p95: {np.percentile(phase_margin, 5):.4g}.."
      f"{np.percentile(phase_margin, 95):.4g} deg")

fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.5), layout="constrained")
left.hist(bandwidth, bins=20)
left.set_xlabel("closed-loop bandwidth [rad/s]")
left.set_ylabel("samples")
right.scatter(km / act.params.motor.Km, phase_margin, s=8)
right.set_xlabel("Km / nominal Km")
right.set_ylabel("position-loop phase margin [deg]")
