"""cas_freq: frequency-domain analysis of servo actuators.

The first model is the QT-CAS fin actuator of ARL-TR-9136 (Maxon EC-4pole 22 motor,
20:1 worm gear, EPOS4 PI current loop inside a PID position loop). See MODEL.md in the
project's shared notes for the definition of every figure.

The package is layered one way: ``config`` -> ``model`` -> ``analysis`` -> ``cli``.
Importing it is cheap: nothing here imports python-control or matplotlib.
"""

__version__ = "0.1.0"
