"""Both simulation engines' signals on a set of architectures, dumped for an old/new comparison.

A change to either engine (the numpy reference or the compiled kernel) must keep every signal of
every architecture, continuous and sampled, to the bit or say which moved. Run this on the tree
before the change and after it, then compare::

    PYTHONPATH=/path/to/old/checkout python benchmarks/engine_dump.py before.npz
    python benchmarks/engine_dump.py after.npz
    python benchmarks/engine_dump.py --compare before.npz after.npz   # exit 1 if any differ

The cases: the QT-CAS PID-on-PI (continuous, each loop sampled alone and both), with filters at
the current command and on both measurements, loaded with output feedback, and the shipped
cascade axis continuous and with each mix of sampled loops; 10 deg and 0.5 deg steps, 30 ms.
"""

import argparse
import dataclasses
import math
import sys

import numpy as np

from cas_freq.config.loader import load_variant, shipped_configs_dir
from cas_freq.core.filters_config import Filter
from cas_freq.core.parameters import LoopParameters
from cas_freq.simulation import Step, simulate_batch

#: The recorded signals compared.
SIGNALS = ("delta", "theta", "omega", "i", "V", "current_command", "position_integral",
           "current_limited", "voltage_limited")
#: Analog filters on both measurements (the current's and the position loop's).
MEASUREMENT_FILTERS = (Filter("current_feedback", "lowpass1", 20000.0),
                       Filter("position_feedback", "lowpass1", 5000.0))
PID_SAMPLED = dict(current_rate_hz=25000.0, position_rate_hz=2500.0)


def _params(config=None, variant="base", **changes):
    p = LoopParameters.from_config(load_variant(config, variant).params)
    return dataclasses.replace(p, **changes) if changes else p


def cases():
    """Case name -> (parameters, sampling rates of ``simulate_batch``)."""
    cascade = shipped_configs_dir() / "cascade_axis.yaml"
    filters = (Filter("current_command", "notch", 3000.0, width=1500.0, depth_db=-20.0),
               Filter("current_command", "lowpass2", 8000.0, damping=0.7),
               *MEASUREMENT_FILTERS)
    output = _params(variant="loaded", feedback_output=True)
    return {
        "pid_base": (_params(), {}),
        "pid_sampled": (_params(), PID_SAMPLED),
        "pid_sampled_c": (_params(), dict(current_rate_hz=25000.0)),
        "pid_sampled_p": (_params(), dict(position_rate_hz=2500.0)),
        "pid_filters": (_params(filters=filters), {}),
        "pid_filters_sampled": (_params(filters=filters[1:]), PID_SAMPLED),
        "loaded_output": (output, {}),
        "loaded_output_sampled": (output, PID_SAMPLED),
        "cascade": (_params(cascade), {}),
        "cascade_sampled": (_params(cascade), dict(current_rate_hz=20000.0,
                                                   velocity_rate_hz=10000.0,
                                                   position_rate_hz=2500.0)),
        "cascade_sampled_v": (_params(cascade), dict(velocity_rate_hz=10000.0)),
        "cascade_sampled_cv": (_params(cascade), dict(current_rate_hz=20000.0,
                                                      velocity_rate_hz=10000.0)),
        "cascade_sampled_p": (_params(cascade), dict(position_rate_hz=2500.0)),
    }


def dump(path):
    """Write every case's signals, both engines, both steps, to ``path`` (npz)."""
    out = {}
    for case, (p, rates) in cases().items():
        for engine in ("compiled", "reference"):
            for amplitude_deg in (10.0, 0.5):
                run = simulate_batch(p, Step(math.radians(amplitude_deg)), t_end=0.03,
                                     extend=False, engine=engine, **rates)
                for name in SIGNALS:
                    out[f"{case}/{engine}/{amplitude_deg}/{name}"] = np.asarray(
                        getattr(run, name))
    np.savez(path, **out)
    print(f"{len(out)} signals written to {path}")


def compare(before, after):
    """Print each signal that differs between two dumps, with its largest relative change;
    1 if any differs, else 0."""
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


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("paths", nargs="+", help="the dump to write, or two to compare")
    parser.add_argument("--compare", action="store_true", help="compare two dumps")
    args = parser.parse_args(argv)
    if args.compare:
        if len(args.paths) != 2:
            parser.error("--compare takes two dumps")
        return compare(*args.paths)
    if len(args.paths) != 1:
        parser.error("give one path to write")
    dump(args.paths[0])
    return 0


if __name__ == "__main__":
    sys.exit(main())
