"""Both simulation engines' signals on a set of architectures, dumped for an old/new comparison.

A change to either engine (the numpy reference or the compiled kernel) must keep every signal of
every architecture, continuous and sampled, to the bit or say which moved. Run this on the tree
before the change and after it, then compare::

    python benchmarks/engine_dump.py before.npz     # on the old tree (PYTHONPATH=old checkout)
    python benchmarks/engine_dump.py after.npz
    python benchmarks/engine_dump.py --compare before.npz after.npz

The cases: the QT-CAS PID-on-PI (continuous, each loop sampled alone and both), with filters at
the current command and on both measurements, loaded with output feedback, and the shipped
cascade axis continuous and with each mix of sampled loops; 10 deg and 0.5 deg steps, 30 ms.
"""
import dataclasses
import math
import sys

import numpy as np

from cas_freq.config.loader import load_variant, shipped_configs_dir
from cas_freq.core.filters_config import Filter
from cas_freq.core.parameters import LoopParameters
from cas_freq.simulation import Step, simulate_batch


def lp(path, variant="base"):
    return LoopParameters.from_config(load_variant(path, variant).params)

cas = shipped_configs_dir() / "cascade_axis.yaml"


def base():
    return lp(None)


cases = {
    "pid_base": (base, {}),
    "pid_sampled": (base, dict(current_rate_hz=25000.0, position_rate_hz=2500.0)),
    "pid_sampled_c": (base, dict(current_rate_hz=25000.0)),
    "pid_sampled_p": (base, dict(position_rate_hz=2500.0)),
    "pid_filters": (lambda: dataclasses.replace(base(), filters=(
        Filter("current_command", "notch", 3000.0, width=1500.0, depth_db=-20.0),
        Filter("current_command", "lowpass2", 8000.0, damping=0.7),
        Filter("current_feedback", "lowpass1", 20000.0),
        Filter("position_feedback", "lowpass1", 5000.0))), {}),
    "pid_filters_sampled": (lambda: dataclasses.replace(base(), filters=(
        Filter("current_command", "lowpass2", 8000.0, damping=0.7),
        Filter("current_feedback", "lowpass1", 20000.0),
        Filter("position_feedback", "lowpass1", 5000.0))),
        dict(current_rate_hz=25000.0, position_rate_hz=2500.0)),
    "loaded_output": (lambda: dataclasses.replace(lp(None, "loaded"), feedback_output=True), {}),
    "loaded_output_sampled": (
        lambda: dataclasses.replace(lp(None, "loaded"), feedback_output=True),
                              dict(current_rate_hz=25000.0, position_rate_hz=2500.0)),
    "cascade": (lambda: lp(cas), {}),
    "cascade_sampled": (lambda: lp(cas), dict(current_rate_hz=20000.0, velocity_rate_hz=10000.0,
                                              position_rate_hz=2500.0)),
    "cascade_sampled_v": (lambda: lp(cas), dict(velocity_rate_hz=10000.0)),
    "cascade_sampled_cv": (lambda: lp(cas),
                           dict(current_rate_hz=20000.0, velocity_rate_hz=10000.0)),
    "cascade_sampled_p": (lambda: lp(cas), dict(position_rate_hz=2500.0)),
}


def compare(before, after):
    """Print each signal that differs between two dumps, with its largest relative change."""
    a, b = np.load(before), np.load(after)
    moved = 0
    for key in sorted(set(a.files) | set(b.files)):
        if key not in a.files or key not in b.files:
            print(f"{key}: only in one dump")
            moved += 1
            continue
        x, y = a[key].astype(float), b[key].astype(float)
        if x.shape != y.shape or not np.array_equal(x, y):
            scale = max(float(np.max(np.abs(x))), 1e-300)
            change = float(np.max(np.abs(x - y))) / scale if x.shape == y.shape else np.inf
            print(f"{key}: max |change| / max |value| = {change:.3g}")
            moved += 1
    print(f"{moved} of {len(a.files)} signals differ")
    return 1 if moved else 0


if len(sys.argv) == 4 and sys.argv[1] == "--compare":
    sys.exit(compare(sys.argv[2], sys.argv[3]))
out = {}
names = ("delta", "theta", "omega", "i", "V", "current_command", "position_integral",
         "current_limited", "voltage_limited")
for case, (build, rates) in cases.items():
    p = build()
    for engine in ("compiled", "reference"):
        for amp in (10.0, 0.5):
            r = simulate_batch(p, Step(math.radians(amp)), t_end=0.03, extend=False,
                               engine=engine, **rates)
            for n in names:
                out[f"{case}/{engine}/{amp}/{n}"] = np.asarray(getattr(r, n))
np.savez(sys.argv[1], **out)
print(len(out))
