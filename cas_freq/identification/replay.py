"""The nonlinear simulator replaying step recordings for many parameter sets at once.

Each recording is replayed as it was recorded: its own command (a :class:`Step` of its step
size when the command steps and holds, else the recorded command as a piecewise-linear
:class:`Table` from the last pre-trigger sample on), its own length, the variant's limits and
controller sampling; the simulated fin angle and motor current are read at the recording's own
sample times (linear interpolation between the simulator's samples, kept at most a quarter of
the recording's shortest interval apart). Every parameter set of a call, times every
recording, is one batch of :func:`cas_freq.simulation.simulate_batch`.
"""

import dataclasses

import numpy as np

from cas_freq.parameters import variant_parameters
from cas_freq.simulation.commands import Step, Table
from cas_freq.simulation.simulator import default_time_step, simulate_batch, step_bound

#: A command is a step when every sample from the trigger on is within this fraction of the
#: step size of the step.
STEP_FLATNESS = 1e-3


def recording_command(recording, step_rad):
    """The command that replays ``recording``: a Step, or a Table of the recorded command."""
    command = recording.command_rad
    after = recording.after
    if command is None or np.all(np.abs(command[after] - step_rad)
                                 <= STEP_FLATNESS * abs(step_rad)):
        return Step(step_rad)
    first = max(int(np.argmax(after)) - 1, 0)
    return Table(recording.time_s[first:], command[first:], source=recording.source)


@dataclasses.dataclass(frozen=True, eq=False)
class Replay:
    """Simulated signals of every parameter set at every recording's samples.

    Attributes
    ----------
    position : list of numpy.ndarray
        Per recording, (n_sets, n_samples) fin angle [rad] from the trigger on.
    current : list of numpy.ndarray
        Per recording, (n_sets, n_samples) motor current [A].
    current_limited, voltage_limited : numpy.ndarray of bool
        (n_sets, n_recordings): whether the limit was active anywhere in the run.
    """

    position: list
    current: list
    current_limited: np.ndarray
    voltage_limited: np.ndarray


class RecordingReplayer:
    """Replays a fixed set of recordings of one variant with some keys changed.

    Parameters
    ----------
    config : cas_freq.config.ActuatorConfig
        The variant the keys are changed in.
    recordings : sequence of Recording
    steps_rad : sequence of float
        Each recording's step [rad].
    """

    def __init__(self, config, recordings, steps_rad):
        self.config = config
        self.recordings = list(recordings)
        self.times = [r.time_s[r.after] for r in self.recordings]
        self.commands = [recording_command(r, s)
                         for r, s in zip(self.recordings, steps_rad, strict=True)]
        self.rates = config.simulation.rates_hz
        one = variant_parameters(config, {})
        periods = [1.0 / rate for rate in self.rates if rate]
        self.dt = default_time_step([*one.tau_c, *one.tau_p], periods, step_bound(one))
        shortest = min(float(np.min(np.diff(t))) if t.size > 1 else np.inf for t in self.times)
        self.record_every = max(1, int(shortest / (4.0 * self.dt)))
        self.t_end = max(float(t[-1]) for t in self.times) + 2 * self.record_every * self.dt

    def replay(self, changes):
        """Simulate every recording for each parameter set.

        Parameters
        ----------
        changes : dict of str to numpy.ndarray
            Dotted key -> values [SI], shape (n_sets,).

        Returns
        -------
        Replay
        """
        n_rec = len(self.recordings)
        n_sets = len(next(iter(changes.values()))) if changes else 1
        runs = {key: np.repeat(np.asarray(values, dtype=float), n_rec)
                for key, values in changes.items()}
        loop = variant_parameters(self.config, runs, n=n_sets * n_rec)
        current_rate, position_rate = self.rates
        result = simulate_batch(loop, self.commands * n_sets, dt=self.dt, t_end=self.t_end,
                                extend=False, current_rate_hz=current_rate,
                                position_rate_hz=position_rate, record_every=self.record_every)
        position, current = [], []
        for r, times in enumerate(self.times):
            rows = range(r, n_sets * n_rec, n_rec)
            position.append(np.stack([np.interp(times, result.t, result.delta[k]) for k in rows]))
            current.append(np.stack([np.interp(times, result.t, result.i[k]) for k in rows]))
        shape = (n_sets, n_rec)
        return Replay(position=position, current=current,
                      current_limited=result.current_limited.any(axis=1).reshape(shape),
                      voltage_limited=result.voltage_limited.any(axis=1).reshape(shape))


__all__ = ["Replay", "RecordingReplayer", "STEP_FLATNESS", "recording_command"]
