"""cas_freq: frequency-domain analysis of servo actuators.

The first model is the QT-CAS fin actuator of ARL-TR-9136 (Maxon EC-4pole 22 motor,
20:1 worm gear, EPOS4 PI current loop inside a PID position loop). docs/model.md defines
every figure.

The Python API (:mod:`cas_freq.api`)::

    import cas_freq as cf
    act = cf.load("configs/qt_cas.yaml", variant="fitted", set={"position_loop.Kp": "5 A/rad"})
    act.analyze().closed_loop.bandwidth_rad_s

The package is layered one way (docs/layout.md): the tables, ``config``, ``model``,
``simulation``, ``analysis``, ``studies``, ``verify``/``tuning``, ``plots``, ``report``, the API,
the CLI.
Importing it is cheap: ``load``, ``Actuator`` and ``ActuatorSet`` are imported from
:mod:`cas_freq.api` on first use, and nothing here imports python-control or matplotlib.
"""

__version__ = "0.1.0"

#: Names exported from :mod:`cas_freq.api`, imported on first access.
_API = ("load", "Actuator", "ActuatorSet")

#: Names exported from :mod:`cas_freq.api.any_loop` (margins of any loop), imported on first access.
_ANY_LOOP = ("loop_margins", "closed_loop_figures")

__all__ = [*_API, *_ANY_LOOP, "__version__"]


def __getattr__(name):
    if name in _API:
        from cas_freq import api

        return getattr(api, name)
    if name in _ANY_LOOP:
        from cas_freq.api import any_loop

        return getattr(any_loop, name)
    raise AttributeError(f"module 'cas_freq' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_API, *_ANY_LOOP])
