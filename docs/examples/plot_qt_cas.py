"""
# The QT-CAS loops

Analyze the shipped QT-CAS fin actuator (ARL-TR-9136) and draw the Bode of its current loop
L_i, position loop L_p and closed loop T, every crossover and margin marked. `cf.load()`
without a path loads the shipped config; its variants are the report's catalog motor (`base`),
the fitted motor (`fitted`), a less aggressive tuning (`relaxed`) and the loaded fin
(`loaded`).
"""

import cas_freq as cf

act = cf.load(variant="fitted")
print(act.variants)
res = act.analyze()
print(res)

# %%
# Each figure is an attribute (`None` where it does not exist); `res.to_dict()` is what
# `cas-freq analyze --json` prints.

print(f"PM {res.position_loop.phase_margin_deg:.4g} deg at {res.position_loop.crossover_rad_s:.4g}"
      f" rad/s, GM {res.position_loop.gain_margin_db:.4g} dB, "
      f"bandwidth {res.closed_loop.bandwidth_rad_s:.4g} rad/s")
fig = res.plot()
