"""The loop parameters of a batch of simulation runs, one array of shape (n_runs,) per parameter.

A sweep changes a few parameters across hundreds of runs; the simulator advances all runs at once
with numpy, so it takes every parameter as an array. :meth:`LoopParameters.from_configs` builds
them from validated configs; :meth:`LoopParameters.replace` broadcasts and changes some, e.g.
``LoopParameters.from_config(params).replace(cp_Kp=np.linspace(3, 9, 200))``.
"""

import dataclasses

import numpy as np

from cas_freq.exceptions import ConfigError

#: Field name -> (unit, lower bound, strict) of every numeric parameter.
_FIELDS = {
    "R": ("ohm", 0.0, True),
    "L": ("H", 0.0, True),
    "Km": ("N*m/A", 0.0, True),
    "Ke": ("V*s/rad", 0.0, True),
    "J": ("kg*m^2", 0.0, True),
    "mu_v": ("N*m*s/rad", 0.0, False),
    "ratio": ("-", 0.0, True),
    "ci_Kp": ("V/A", 0.0, False),
    "ci_Ki": ("V/(A*s)", 0.0, False),
    "v_max": ("V", 0.0, True),
    "tau_c": ("s", 0.0, False),
    "cp_Kp": ("A/rad", 0.0, False),
    "cp_Ki": ("A/(rad*s)", 0.0, False),
    "cp_Kd": ("A*s/rad", 0.0, False),
    "Tf": ("s", 0.0, False),
    "ff_v": ("A*s/rad", None, False),
    "ff_a": ("A*s^2/rad", None, False),
    "i_max": ("A", 0.0, True),
    "tau_p": ("s", 0.0, False),
}


@dataclasses.dataclass(frozen=True, eq=False)
class LoopParameters:
    """Parameters of ``n_runs`` actuators, in SI, motor-shaft coordinates (MODEL.md).

    Every attribute is a read-only float array of shape (n_runs,), except
    ``derivative_on_measurement`` (bool array).

    Attributes
    ----------
    R, L, Km, Ke, J, mu_v : numpy.ndarray
        Motor: resistance [ohm], inductance [H], torque constant [N*m/A], back-EMF constant
        [V*s/rad], inertia [kg*m^2], viscous friction [N*m*s/rad].
    ratio : numpy.ndarray
        Gear ratio N [-]: motor angle = N * fin angle.
    ci_Kp, ci_Ki, v_max, tau_c : numpy.ndarray
        Current loop: PI gains [V/A], [V/(A*s)], output limit [V], transport delay [s].
    cp_Kp, cp_Ki, cp_Kd, Tf : numpy.ndarray
        Position loop: PID gains [A/rad], [A/(rad*s)], [A*s/rad] and derivative filter time
        constant [s] (0 only where ``cp_Kd`` is 0).
    ff_v, ff_a : numpy.ndarray
        Feed-forward of the motor-angle command rate [A*s/rad] and acceleration [A*s^2/rad].
    i_max, tau_p : numpy.ndarray
        Current-command limit [A] and position-loop transport delay [s].
    derivative_on_measurement : numpy.ndarray of bool
        True where the derivative acts on -theta instead of on the error.
    """

    R: np.ndarray
    L: np.ndarray
    Km: np.ndarray
    Ke: np.ndarray
    J: np.ndarray
    mu_v: np.ndarray
    ratio: np.ndarray
    ci_Kp: np.ndarray
    ci_Ki: np.ndarray
    v_max: np.ndarray
    tau_c: np.ndarray
    cp_Kp: np.ndarray
    cp_Ki: np.ndarray
    cp_Kd: np.ndarray
    Tf: np.ndarray
    ff_v: np.ndarray
    ff_a: np.ndarray
    i_max: np.ndarray
    tau_p: np.ndarray
    derivative_on_measurement: np.ndarray

    def __post_init__(self):
        names = [*_FIELDS, "derivative_on_measurement"]
        try:
            arrays = np.broadcast_arrays(*(np.atleast_1d(getattr(self, n)) for n in names))
        except ValueError:
            shapes = {n: np.shape(getattr(self, n)) for n in names}
            raise ConfigError(f"simulation parameters: shapes do not broadcast: {shapes}") from None
        for name, array in zip(names, arrays, strict=True):
            if array.ndim != 1:
                raise ConfigError(f"simulation parameters: {name}: must be 1-D, got {array.shape}")
            dtype = bool if name == "derivative_on_measurement" else float
            array = np.array(array, dtype=dtype)
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        for name, (unit, bound, strict) in _FIELDS.items():
            _check(name, getattr(self, name), unit, bound, strict)
        bad = (self.cp_Kd > 0) & ~(self.Tf > 0)
        if bad.any():
            raise ConfigError(
                f"simulation parameters: Tf: must be > 0 s where cp_Kd > 0 (runs {_where(bad)})"
            )

    @property
    def n_runs(self):
        """Number of runs."""
        return self.R.shape[0]

    @classmethod
    def from_configs(cls, configs):
        """One run per validated :class:`cas_freq.config.ActuatorConfig`."""
        configs = list(configs)
        if not configs:
            raise ConfigError("simulation parameters: need at least one config")
        rows = [_row(config) for config in configs]
        return cls(**{key: np.array([row[key] for row in rows]) for key in rows[0]})

    @classmethod
    def from_config(cls, config):
        """A single run from one validated :class:`cas_freq.config.ActuatorConfig`."""
        return cls.from_configs([config])

    def replace(self, **changes):
        """A copy with some parameters changed; every array is broadcast to a common length."""
        unknown = set(changes) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            raise ConfigError(f"simulation parameters: unknown names {sorted(unknown)}")
        return dataclasses.replace(self, **changes)

    def without_feedforward(self):
        """A copy with ff_v = ff_a = 0: the loop of MODEL.md's T, whose bandwidth is ω_BW."""
        zero = np.zeros(self.n_runs)
        return self.replace(ff_v=zero, ff_a=zero)

    def take(self, rows):
        """The runs ``rows`` (a slice, or an array of run indices, repeats allowed)."""
        names = [f.name for f in dataclasses.fields(self)]
        return dataclasses.replace(self, **{name: getattr(self, name)[rows] for name in names})

    def run(self, index):
        """The parameters of run ``index`` alone (n_runs = 1)."""
        return self.take(slice(index, index + 1))


def _row(config):
    motor, current, position = config.motor, config.current_loop, config.position_loop
    return {
        "R": motor.R, "L": motor.L, "Km": motor.Km, "Ke": motor.Ke, "J": motor.J,
        "mu_v": motor.viscous_friction, "ratio": config.gear.ratio,
        "ci_Kp": current.Kp, "ci_Ki": current.Ki, "v_max": current.v_max, "tau_c": current.delay,
        "cp_Kp": position.Kp, "cp_Ki": position.Ki, "cp_Kd": position.Kd,
        "Tf": position.filter_time_constant, "ff_v": position.ff_v, "ff_a": position.ff_a,
        "i_max": position.i_max, "tau_p": position.delay,
        "derivative_on_measurement": position.derivative_on == "measurement",
    }


def _where(mask):
    return np.flatnonzero(mask)[:10].tolist()


def _check(name, values, unit, bound, strict):
    bad = ~np.isfinite(values)
    if bound is not None:
        bad |= ~(values > bound) if strict else ~(values >= bound)
    if bad.any():
        rule = "finite" if bound is None else f"{'>' if strict else '>='} {bound:g} {unit}"
        first = values[bad][0]
        raise ConfigError(
            f"simulation parameters: {name}: must be {rule}, got {first!r} {unit} "
            f"(runs {_where(bad)})"
        )
