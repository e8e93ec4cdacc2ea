"""
# Margins of any loop

`cf.loop_margins` gives every gain and phase crossover, the phase and gain margins (upper and
lower), the delay margin, the sensitivity peak Ms and the disk margin of any loop, with the
engine of the actuator's figures: a python-control system (with an exact delay), a callable of
s, or frequency-response data. Here MATLAB's `allmargin` example, L = 25/(s³ + 10s² + 10s + 10)
with a 0.1 s delay.
"""

import control

import cas_freq as cf

L = control.tf(25, [1, 10, 10, 10])
m = cf.loop_margins(L, delay=0.1)
print(f"PM {m.phase_margin_deg:.2f} deg at {m.crossover_rad_s:.4g} rad/s, "
      f"GM {m.gain_margin_db:.2f} dB at {m.phase_crossover_rad_s:.4g} rad/s")
print(f"delay margin {m.delay_margin_s:.4f} s, Ms {m.sensitivity_peak_db:.2f} dB, "
      f"disk margin ±{m.disk_margin_gain_db:.2f} dB, ±{m.disk_margin_phase_deg:.2f} deg")
print(f"{len(m.phase_crossovers)} phase crossovers up to {m.omega_range_rad_s[1]:g} rad/s "
      "(the delay's phase keeps falling)")
fig = m.plot()

# %%
# The closed loop's bandwidth (-3.01 dB), peak and -90° frequency, here of the loop without
# the delay closed with unit feedback:

T = cf.closed_loop_figures(control.feedback(L, 1))
print(f"bandwidth {T.bandwidth_rad_s:.4g} rad/s, peak {T.peak_db:.2f} dB at "
      f"{T.peak_rad_s:.4g} rad/s")
fig_closed = T.plot()
