"""The nonlinear simulator replaying step recordings for many parameter sets at once.

Each recording is replayed as it was recorded: its own command, its own length, the variant's
limits and controller sampling. The command is a :class:`Step` of the recording's step size at
the trigger when the recorded command steps and holds (fitted from the trigger on); else the
recorded command as a :class:`Recorded` spline, whose derivatives feed the feed-forward,
simulated from the recording's first sample and fitted from where the command starts to move.
The simulated output angle and motor current are read at the recording's own sample times
(linear interpolation between the simulator's samples, kept at most a quarter of the
recording's shortest interval apart). Every parameter set of a call, times every recording, is
one batch of :func:`cas_freq.simulation.simulate_batch`.
"""

import dataclasses

import numpy as np

from cas_freq.core.parameters import variant_parameters
from cas_freq.simulation.commands import Recorded, Step
from cas_freq.simulation.simulator import loop_time_step, simulate_batch

#: A command is a step when every sample from the trigger on is within this fraction of the
#: step size of the step.
STEP_FLATNESS = 1e-3


def recording_command(recording, step_rad):
    """(command, origin [s], fitted samples) that replay ``recording``.

    A Step at the trigger (origin 0, the samples from the trigger on) when the command steps
    and holds; else a Recorded spline of the recorded command, the simulation starting at the first
    sample (origin: its time) and the samples from the command's first move on fitted.
    """
    command = recording.command_rad
    after = recording.after
    if command is None or np.all(np.abs(command[after] - step_rad)
                                 <= STEP_FLATNESS * abs(step_rad)):
        return Step(step_rad), 0.0, after
    origin = float(recording.time_s[0])
    moved = Recorded(recording.time_s - origin, command, source=recording.source)
    return moved, origin, recording.time_s >= recording.start_s


@dataclasses.dataclass(frozen=True, eq=False)
class Replay:
    """Simulated signals of every parameter set at every recording's samples.

    Attributes
    ----------
    position : list of numpy.ndarray
        Per recording, (n_sets, n_samples) output angle [rad] from the trigger on.
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
        replayed = [recording_command(r, s) for r, s in zip(self.recordings, steps_rad,
                                                             strict=True)]
        self.commands = [command for command, _, _ in replayed]
        #: per recording, the samples fitted (bool mask over the recording's samples)
        self.masks = [mask for _, _, mask in replayed]
        # simulation times of the fitted samples
        self.times = [r.time_s[mask] - origin for r, (_, origin, mask)
                      in zip(self.recordings, replayed, strict=True)]
        self.rates = config.simulation.rates_hz
        one = variant_parameters(config, {})
        periods = [1.0 / rate for rate in self.rates if rate]
        self.dt = loop_time_step(one, periods)
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
