"""
# A cascade axis: every loop's margins

`configs/cascade_axis.yaml` ships a cascade (a velocity loop between the position and the
current loops, docs/model.md §13). `analyze()` then gives a third loop, `velocity_loop`, each
loop broken where docs/model.md says with the others closed.
"""

import cas_freq as cf
from cas_freq.config.loader import shipped_configs_dir

act = cf.load(shipped_configs_dir() / "cascade_axis.yaml")
res = act.analyze()
for name in ("current_loop", "velocity_loop", "position_loop"):
    loop = getattr(res, name)
    print(f"{name:14s} crossover {loop.crossover_rad_s:8.4g} rad/s  "
          f"PM {loop.phase_margin_deg:6.4g} deg  GM {loop.gain_margin_db:6.4g} dB  "
          f"delay margin {1e3 * loop.delay_margin_s:.4g} ms")
print(f"closed loop: bandwidth {res.closed_loop.bandwidth_rad_s:.4g} rad/s, "
      f"{res.stability.verdict}")
fig = res.plot()
