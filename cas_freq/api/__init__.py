"""The Python API: one actuator variant, or many, in a notebook.

Nothing is computed here: each method calls the engine the CLI uses (:mod:`cas_freq.config`,
:mod:`cas_freq.analysis`, :mod:`cas_freq.simulation`, :mod:`cas_freq.model`), so every figure
is the one the matching command prints. The figures are defined in docs/model.md. matplotlib
and python-control are imported only by :meth:`FrequencyResponse.plot`,
:meth:`StepResponse.plot`, :meth:`ProfileResponse.plot`, :meth:`Analysis.plot` and
:meth:`Actuator.to_control`.

In a notebook every result shows a table of its headline figures (``_repr_html_``, from
:mod:`cas_freq.core.summary`) and every ``plot()`` figure displays itself (a PNG, no
``%matplotlib``); ``repr()`` is a few lines of the same figures.

Examples
--------
>>> import cas_freq as cf
>>> act = cf.load("configs/qt_cas.yaml", variant="fitted", set={"position_loop.Kp": "5 A/rad"})
>>> act.analyze().closed_loop.bandwidth_rad_s        # every figure of ``analyze --json``
>>> act.analyze().plot()                             # Bode of L_i, L_p and T, margins marked
>>> act.frequency_response(omega).plot()             # Bode of L_i, L_p and T
>>> act.simulate(step="10 deg").plot()               # nonlinear step: output angle and current
>>> act.simulate_profile("10 deg", "2000 deg/s", "1e5 deg/s^2").profile  # a profile move
>>> act.vary({"position_loop.Kp": np.linspace(2, 12, 200)}).analyze().closed_loop.bandwidth_rad_s
"""

import dataclasses
import functools
import types

import numpy as np

import cas_freq.analysis as analysis
from cas_freq.analysis.frequency import DEFAULT_RANGE_RAD_S
from cas_freq.analysis.systems import (
    POLYNOMIAL_LOG10_LIMIT,
    largest_polynomial,
    linear_model,
    margin_safe_model,
)
from cas_freq.api.results import (
    _LOOPS,
    Analysis,
    FrequencyResponse,
    ProfileResponse,
    StepResponse,
)
from cas_freq.api.studies import CandidateRanking, WorstCase
from cas_freq.config.loader import load_variant, read_config_file, variant_names
from cas_freq.config.wording import OutputWords
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.output import angle, output_step, output_unit, read_output
from cas_freq.core.parameters import LoopParameters, unit_of, variant_parameters
from cas_freq.core.summary import Summary, spread
from cas_freq.core.threads import one_blas_thread
from cas_freq.core.tolerances import parse_tolerance
from cas_freq.core.units import to_si
from cas_freq.model import ActuatorLoops, DelayModel
from cas_freq.model.delay import MAX_PADE_ORDER
from cas_freq.report.data import described_loops
from cas_freq.studies import exported_model
from cas_freq.studies.candidates import rank_candidates
from cas_freq.studies.distributed import session
from cas_freq.studies.envelope import load_envelope
from cas_freq.studies.profile_run import make_profile, profile_run
from cas_freq.studies.run import linear_verdict, step_batch
from cas_freq.studies.worstcase import worst_case
from cas_freq.tuning import options
from cas_freq.tuning.run import tune_variant

#: Highest default Padé order of :meth:`Actuator.to_control`. python-control's
#: ``stability_margins`` works on the loop's polynomials, whose coefficients grow with the
#: order (and the states): past ~1e76 its stability-margin test overflows and it raises
#: LinAlgError (:data:`cas_freq.analysis.systems.POLYNOMIAL_LOG10_LIMIT`): at 6 on the loaded
#: QT-CAS variant, at 4 on the cascade axis (25 states). The default is the highest order up
#: to this one below that limit (4 on the QT-CAS variants, 3 on the cascade axis), PM and
#: crossover within 1e-6 of the exact-delay analysis. tests/test_notebook.py checks every
#: shipped architecture.
TO_CONTROL_PADE_ORDER = 4


def _delay(delay):
    """A :class:`DelayModel` from ``"exact"``/``"pade:N"`` (as ``--delay``) or a DelayModel."""
    return delay if isinstance(delay, DelayModel) else DelayModel.parse(delay)


def _quantities(values, unit, field, output=None):
    """Numbers [``unit``] from a number, a string with its unit (``"1 deg"``, ``"2 rev/s"``) or a
    sequence of either: a number is taken as ``unit``; a string is converted
    (:func:`cas_freq.core.units.to_si`), or at the output (``output``, an
    :class:`~cas_freq.core.output.OutputUnit`) read as an angle or a length
    (:func:`cas_freq.core.output.read_output`). A scalar gives a float, a sequence an array.

    Raises
    ------
    cas_freq.core.exceptions.CasFreqError
        One line naming ``field``, the value and what is accepted.
    """
    single = isinstance(values, str) or np.ndim(values) == 0
    items = [values] if single else list(np.asarray(values, dtype=object).reshape(-1))
    out = []
    for value in items:
        value = value.item() if isinstance(value, np.generic) else value
        if isinstance(value, str) and output is not None:
            try:  # its message names the field, the value and what to give
                out.append(read_output(value, output, field))
            except ValueError as exc:
                raise CasFreqError(str(exc)) from None
            continue
        try:
            out.append(to_si(value, unit))
        except (TypeError, ValueError) as exc:
            accepted = f"a number [{unit}] or a string with its unit ({exc})"
            raise CasFreqError(f"{field}: {value!r} is not accepted; accepted: "
                               f"{accepted}") from None
    return out[0] if single else np.array(out, dtype=float).reshape(np.shape(values))


def _range(frequency_range):
    """An analysed range (w_min, w_max) [rad/s] from numbers or strings with their unit; the
    default when None."""
    if frequency_range is None:
        return DEFAULT_RANGE_RAD_S
    return tuple(float(w) for w in _quantities(frequency_range, "rad/s", "frequency_range"))


def load(path=None, variant="base", set=None):  # ``set=`` mirrors ``--set``
    """Load one variant of a config file, as ``cas-freq ... --variant NAME --set K=V`` does.

    Parameters
    ----------
    path : str or Path, optional
        The YAML config; default the shipped QT-CAS config
        (:func:`cas_freq.config.loader.default_config_path`).
    variant : str
        ``"base"`` or one of the file's ``variants`` (see :attr:`Actuator.variants`).
    set : dict of str to object, optional
        Dotted key -> value applied after the variant, numbers in SI or strings with units
        (``{"position_loop.Kp": "5 A/rad", "current_loop.delay": "0.1 ms"}``).

    Returns
    -------
    Actuator

    Raises
    ------
    cas_freq.core.exceptions.ConfigError
        Naming the key and the value, for an unknown variant or key or a bad value.
    """
    return Actuator(load_variant(path, variant, tuple((set or {}).items()), overrides_name="set="))


@dataclasses.dataclass(frozen=True)
class Actuator:
    """One validated actuator variant.

    Attributes
    ----------
    loaded : cas_freq.config.LoadedVariant
        Config path (``loaded.source``), variant name, ``set=`` overrides and parameters.
    """

    loaded: object

    def __repr__(self):
        overrides = ", ".join(f"{key}={value}" for key, value in self.loaded.overrides)
        return (f"Actuator({self.params.name} / {self.variant}"
                + (f", set {overrides}" if overrides else "") + f"; {self.config_path})")

    @property
    def config_path(self):
        """Path of the config file (str)."""
        return self.loaded.source

    @property
    def overrides(self):
        """The ``set=`` overrides, as (dotted key, value) pairs."""
        return self.loaded.overrides

    @property
    def params(self):
        """The validated parameters (:class:`cas_freq.config.ActuatorConfig`, SI)."""
        return self.loaded.params

    @property
    def variant(self):
        """Name of this variant."""
        return self.loaded.variant

    @property
    def variants(self):
        """Names of the config file's variants, ``"base"`` first (list of str)."""
        return variant_names(read_config_file(self.loaded.source))

    @one_blas_thread()
    def analyze(self, delay="exact", frequency_range=None, limit_cycle_check=False):
        """Every frequency-domain figure: margins of both loops, closed loop, stability.

        Parameters
        ----------
        delay : str or DelayModel
            ``"exact"`` or ``"pade:N"`` delays in every frequency response.
        frequency_range : (float or str, float or str), optional
            Analysed range, numbers [rad/s] or strings with their unit (``"1 rev/s"``); default
            0.01..1e6 rad/s.
        limit_cycle_check : bool
            Check each predicted limit cycle (``limit_cycles``, always predicted) by a
            nonlinear simulation (``analyze --limit-cycles``).

        Returns
        -------
        Analysis
            Attributes ``current_loop``, ``position_loop`` (margins), ``closed_loop``
            (bandwidth, peak; None when the loop is not stable), ``stable``, ``stability``;
            a figure that does not exist is None. ``to_dict()`` is ``analyze --json``.
        """
        return Analysis.of(analysis.analyze(self.loaded, _delay(delay), _range(frequency_range),
                                            limit_cycle_check=limit_cycle_check))

    @one_blas_thread()
    def frequency_response(self, omega, delay="exact"):
        """The loops' complex frequency responses.

        Parameters
        ----------
        omega : array_like
            Frequencies, numbers [rad/s] or strings with their unit (``"100 rev/s"``).
        delay : str or DelayModel
            ``"exact"`` or ``"pade:N"``.

        Returns
        -------
        FrequencyResponse
        """
        omega = np.asarray(_quantities(omega, "rad/s", "omega"), dtype=float)
        loops = ActuatorLoops(self.params, _delay(delay))
        s = 1j * omega
        return FrequencyResponse(omega, loops.delay.label,
                                 **{name: getattr(loops, name)(s) for name in _LOOPS},
                                 output_symbol=OutputWords.of(self.loaded.params).symbol,
                                 described=described_loops(self.params))

    @one_blas_thread()
    def simulate(self, step=None):
        """Nonlinear step of the output, as ``cas-freq simulate --step``.

        Parameters
        ----------
        step : str, optional
            Step at the output with a unit (``"10 deg"``, ``"0.1 rad"``), non-zero, within ±90°;
            at a linear output (``gear.screw_lead``) a length (``"5 mm"``) within ±1 m. Default
            10 deg, or 5 mm.

        Returns
        -------
        StepResponse
        """
        step = output_unit(self.loaded.params).example if step is None else step
        amplitude = output_step(str(step), "step", [self.loaded])
        (run,) = step_batch([(self.loaded, amplitude)], {id(self.loaded): self._linear_verdict},
                            parameters={id(self.loaded): self._loop_parameters})
        return StepResponse.of(run)

    @functools.cached_property
    def _loop_parameters(self):
        """The variant's LoopParameters, built once per actuator (its parameters are frozen):
        a sixth of a step's time when built at every call."""
        return LoopParameters.from_config(self.loaded.params)

    @functools.cached_property
    def _linear_verdict(self):
        """The linear closed loop's stability verdict, found once per actuator (its
        parameters are frozen): 40 % of a step's time when found at every call."""
        return linear_verdict(self.loaded.params)

    @one_blas_thread()
    def simulate_profile(self, distance=None, velocity=None, acceleration=None,
                         deceleration=None):
        """A profile move of the output, with and without feed-forward, as ``cas-freq simulate
        --profile``.

        Parameters
        ----------
        distance : str or float
            The move at the output (default ``"10 deg"``; a number is rad), non-zero, within
            ±90°; at a linear output a length (default ``"5 mm"``; a number is m).
        velocity : str or float
            Velocity limit at the output (default ``"2000 deg/s"``, or ``"100 mm/s"``; a number
            is rad/s, or m/s) [> 0].
        acceleration, deceleration : str or float
            Acceleration and deceleration (default: the acceleration) limits at the output
            (default ``"1e5 deg/s^2"``, or ``"2000 mm/s^2"``; a number is rad/s^2, or m/s^2)
            [> 0].

        Returns
        -------
        ProfileResponse
        """
        unit = output_unit(self.loaded.params)
        defaults = (unit.example, *unit.rate_examples)
        distance, velocity, acceleration = (
            default if value is None else value
            for value, default in zip((distance, velocity, acceleration), defaults, strict=True))
        move = make_profile(distance, velocity, acceleration, deceleration,
                            names={"distance": "distance", "velocity": "velocity",
                                   "acceleration": "acceleration",
                                   "deceleration": "deceleration"}, unit=unit)
        return ProfileResponse.of(profile_run(self.loaded, move))

    @one_blas_thread()
    def load_envelope(self, hinge_stiffness, step=None):
        """Every figure and requirement verdict against the load spring K_h (the report's load
        envelope, :mod:`cas_freq.studies.envelope`).

        Parameters
        ----------
        hinge_stiffness : array_like
            Values of ``load.hinge_stiffness`` (the load spring K_h) at the output, numbers
            [N*m/rad] or strings with their unit (> 0 opposes the motion, < 0 aids it).
        step : str, optional
            Output step of the step figures (``"10 deg"``); default the first step
            requirement's.

        Returns
        -------
        cas_freq.studies.envelope.LoadEnvelope
            ``figures`` per grid point, ``stable_range``, and per requirement its verdicts and
            where it is lost (``requirements[k].lost_below`` / ``lost_above``).
        """
        step_rad = None if step is None else angle(str(step), "step")
        stiffness = _quantities(hinge_stiffness, "N*m/rad", "hinge_stiffness")
        return load_envelope(self.loaded, np.asarray(stiffness, dtype=float), step_rad)

    @one_blas_thread()
    def worst_case(self, tolerances=None, samples=256, seed=0, resolution=1e-3,
                   scheduler=None, bound_cells=4_000_000):
        """The worst case of every requirement's figure over the tolerance box, as
        ``cas-freq worstcase`` (:mod:`cas_freq.studies.worstcase`).

        Parameters
        ----------
        tolerances : sequence of str, optional
            ``"KEY=TOL"`` as ``--tolerance`` (``"motor.Km=10%"``, ``"motor.R=±0.036 ohm"``);
            default the config's ``tolerances:``.
        samples : int
            Uniform samples of the box besides its corners.
        seed : int
            Seed of the samples.
        resolution : float
            The local search stops below this share of each key's width.
        scheduler : str, optional
            Run the evaluations on a dask cluster (``local:N`` or an address).
        bound_cells : int
            Most cells of the guaranteed bound's branch and bound (0: no bound).

        Returns
        -------
        WorstCase
        """
        parsed = None if tolerances is None else [
            parse_tolerance(text, self.params) for text in tolerances]
        with session(scheduler):
            return WorstCase(worst_case(self.loaded, parsed, samples=samples, seed=seed,
                                        resolution=resolution, scheduler=scheduler,
                                        bound_cells=bound_cells))

    @one_blas_thread()
    def rank_candidates(self, data, candidates, step=None, channels=None, columns=None):
        """Candidate structures fitted to step recordings and ranked, as ``cas-freq fit --data
        FILE... --candidates FILE`` (:mod:`cas_freq.studies.candidates`).

        Parameters
        ----------
        data : str or Path or sequence of them
            Step recordings (CSV with a header naming columns and units).
        candidates : str or Path
            The candidates file (YAML: each a name, a source, ``set`` overrides and ``free``
            keys with start, bounds and plausible range; docs/identification.md).
        step : str, optional
            The commanded step (``"10 deg"``) for recordings without a command column.
        channels : str, optional
            ``"position"`` or ``"position,current"``.
        columns : dict, optional
            ``role -> header cell`` naming recording columns outright.

        Returns
        -------
        CandidateRanking
        """
        paths = [data] if isinstance(data, (str, bytes)) or hasattr(data, "__fspath__") \
            else list(data)
        step_rad = None if step is None else angle(str(step), "step")
        return CandidateRanking(rank_candidates(self.loaded, candidates, paths, columns,
                                                step_rad, channels))

    @one_blas_thread()
    def tune(self, free=None, objective="max-bandwidth", robust=None, tolerances=(),
             bounds=None, yield_pct=99.0, margin_pct=2.0, required_only=False, seed=0,
             load_cases=False, scheduler=None, candidates=None, rounds=None):
        """Tune keys to this variant's requirements, as ``cas-freq tune`` does.

        Parameters
        ----------
        free : sequence of str, optional
            Keys to tune (default the position loop's Kp, Ki, Kd).
        objective : {"max-bandwidth", "min-settling", "max-margin"}
        robust : {None, "corners", "montecarlo:N"}
            Hold the requirements over the tolerance set too.
        tolerances : sequence of str
            ``"KEY=TOL"`` as ``--tolerance`` (``"motor.Km=10%"``).
        bounds : dict of str to (lo, hi), optional
            Ranges [SI or strings with units]; default the value /4 .. x4.
        yield_pct : float
            Share of the Monte Carlo samples that must pass [%].
        margin_pct : float
            Every bound tightened by this share of its magnitude [%].
        required_only : bool
            Hold only the required requirements.
        seed : int
        load_cases : bool
            Also at every hinge stiffness of the config's load_envelope.
        scheduler : str, optional
            ``local:N`` or a dask.distributed scheduler address.
        candidates, rounds : int, optional
            Global points and refinement rounds (defaults of :mod:`cas_freq.tuning.search`).

        Returns
        -------
        cas_freq.tuning.TuneResult
            ``values()`` the tuned keys [SI], ``feasible``, ``evaluation`` (every candidate),
            ``pareto`` (indices of the trade-off front).
        """
        texts = [f"{key}={low}:{high}" for key, (low, high) in (bounds or {}).items()]
        return tune_variant(
            self.loaded, None if free is None else ",".join(free), texts, objective, robust,
            tolerances, yield_pct, margin_pct, required_only, seed, load_cases,
            scheduler=scheduler, candidates=candidates or options.GLOBAL_COUNT,
            rounds=options.ROUNDS if rounds is None else rounds)

    def vary(self, changes):
        """Many variants at once: this one with some keys changed per sample.

        Parameters
        ----------
        changes : dict of str to array_like
            Dotted key -> values in SI [the key's unit, see the key table of docs/config.md],
            scalars or arrays of one common length n.

        Returns
        -------
        ActuatorSet
        """
        changes = {key: np.asarray(values, dtype=float) for key, values in changes.items()}
        return ActuatorSet(self, changes, variant_parameters(self.params, changes))

    @one_blas_thread()
    def export_model(self, pade=6, amplitudes=None, frequencies=None, feedforward=False):
        """The actuator as the outer loop's designer uses it (``cas-freq export-model``).

        Parameters
        ----------
        pade : int
            Padé order of both delays of the linear T.
        amplitudes : sequence of float or str, optional
            Sine-dwell and step amplitudes at the output, each a number [rad, or m at a
            linear output] or a string with its unit (``"1 deg"``, ``"0.5 mm"``); default
            those of ``cas-freq sinedwell``.
        frequencies : sequence of float or str, optional
            Sine-dwell frequencies, numbers [rad/s] or strings with their unit (``"2 rev/s"``);
            default the ``sinedwell`` grid.
        feedforward : bool
            Let the feed-forward act on the sine-dwell and the sine limits.

        Returns
        -------
        cas_freq.studies.exported_model.ExportedModel
            ``system`` is T as a ``control.StateSpace``; ``to_dict()`` is the command's JSON.
        """
        unit = output_unit(self.loaded.params)
        if amplitudes is not None:
            amplitudes = list(_quantities(amplitudes, unit.si, "amplitudes", unit).reshape(-1))
        if frequencies is not None:
            frequencies = list(_quantities(frequencies, "rad/s", "frequencies").reshape(-1))
        return exported_model.export_model(self.loaded, pade, amplitudes, frequencies, feedforward)

    @one_blas_thread()
    def to_control(self, pade=None):
        """The loops as python-control state-space systems, both delays Padé of order ``pade``.

        Parameters
        ----------
        pade : int, optional
            Padé order of every delay, 1..30. By default the highest order up to
            :data:`TO_CONTROL_PADE_ORDER` at which python-control's polynomial
            ``stability_margins`` stays in floating point on every loop (``step_info`` and
            ``bandwidth`` work at any order); ``model.pade_order`` says which. A higher order
            given here is built as asked, with a warning when ``stability_margins`` would
            overflow on it (``cf.loop_margins`` of the system, or of ``analyze()``'s exact
            delays, works at every order).

        Returns
        -------
        cas_freq.analysis.systems.LinearModel
            ``current_loop`` (L_i), ``current_closed_loop`` (T_i), ``position_loop`` (L_p),
            ``sensitivity`` (S), ``closed_loop`` (T), ``plant``, as :class:`control.StateSpace`
            named so (``sys.name == "L_p"``, signals as
            :data:`cas_freq.analysis.systems.LOOP_NAMES`).
        """
        import warnings

        if pade is None:
            return margin_safe_model(self.params, TO_CONTROL_PADE_ORDER)
        if isinstance(pade, bool) or not isinstance(pade, int | np.integer) or \
                not 1 <= pade <= MAX_PADE_ORDER:
            raise CasFreqError(f"pade: {pade!r} is not accepted; accepted: an integer "
                               f"1..{MAX_PADE_ORDER}, or None (the default order)")
        model = linear_model(self.params, int(pade))
        name, size = largest_polynomial(model)
        if size >= POLYNOMIAL_LOG10_LIMIT:
            warnings.warn(
                f"pade: at order {pade} the {name.replace('_', ' ')}'s characteristic polynomial "
                f"reaches 1e{size:.0f}, past what python-control's polynomial "
                f"stability_margins holds (1e{POLYNOMIAL_LOG10_LIMIT:.0f}): it would raise "
                "LinAlgError; to_control() picks an order that works, and cf.loop_margins "
                "works at any", UserWarning, stacklevel=3)  # past one_blas_thread's wrapper
        return model


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class ActuatorSet(Summary):
    """Many variants of one actuator (from :meth:`Actuator.vary`).

    Attributes
    ----------
    base : Actuator
        The variant the changes apply to.
    changes : dict of str to numpy.ndarray
        The changed keys and their values [SI].
    loop_parameters : cas_freq.core.parameters.LoopParameters
        Parameters of every sample (n runs).
    """

    base: Actuator
    changes: dict
    loop_parameters: object

    def __len__(self):
        return self.loop_parameters.n_runs

    def _summary(self):
        rows = [(key, f"{np.min(values):.4g} .. {np.max(values):.4g}"
                 if np.size(values) else "—", unit_of(key, self.base.params))
                for key, values in self.changes.items()]
        return (f"{len(self)} variants of {self.base.params.name} / {self.base.variant}, "
                "changed:", rows)

    @one_blas_thread()
    def analyze(self, delay="exact", frequency_range=None):
        """The figures of :meth:`Actuator.analyze` for every sample, as numpy arrays.

        Parameters
        ----------
        delay : str or DelayModel
            ``"exact"`` or ``"pade:N"``.
        frequency_range : (float or str, float or str), optional
            Analysed range, numbers [rad/s] or strings with their unit (``"1 rev/s"``); default
            0.01..1e6 rad/s.

        Returns
        -------
        SetAnalysis
            ``current_loop``, ``position_loop``, ``closed_loop`` namespaces of float arrays (n,)
            named as the single analysis' figures (plus ``gain_crossover_count``; each loop's
            ``loop_at_a_time`` a namespace of its own, and ``velocity_loop`` for a drive with
            one), NaN where a
            figure does not exist or the loop is not stable; ``stable`` (bool array);
            ``stability.verdict`` and ``stability.current_loop_verdict`` (str arrays),
            ``stability.pade_order``; ``figures``, the same arrays keyed as
            ``"closed_loop.bandwidth_rad_s"`` (the column names of ``cas-freq sweep``).
        """
        delay = _delay(delay)
        batch = analysis.batch_analyze(
            self.loop_parameters, _range(frequency_range), delay=delay,
            **({"pade_order": delay.order} if delay.order else {}))
        groups = {}
        for name, values in batch.figures.items():
            *path, figure = name.split(".")
            if not path:
                continue
            place = groups
            for part in path:
                place = place.setdefault(part, {})
            place[figure] = values
        return SetAnalysis(
            **{group: _namespace(values) for group, values in groups.items()},
            stable=batch.figures["stable"] == 1.0,
            stability=types.SimpleNamespace(
                verdict=batch.stability, current_loop_verdict=batch.current_loop_stability,
                pade_order=batch.pade_order),
            figures=batch.figures,
        )


def _namespace(values):
    """Nested dicts as nested namespaces (``current_loop.loop_at_a_time.phase_margin_deg``)."""
    return types.SimpleNamespace(**{key: _namespace(value) if isinstance(value, dict) else value
                                    for key, value in values.items()})


class SetAnalysis(Summary, types.SimpleNamespace):
    """The figures of :meth:`ActuatorSet.analyze`: a namespace of arrays (n,) whose repr and
    HTML table give each headline figure's range over the variants, not the arrays."""

    #: The figures its summary spans.
    HEADLINE = ("current_loop.phase_margin_deg", "position_loop.phase_margin_deg",
                "position_loop.gain_margin_db", "position_loop.delay_margin_s",
                "closed_loop.bandwidth_rad_s", "closed_loop.peak_db")

    def _summary(self):
        stable = np.asarray(self.stable)
        rows = [("stable", f"{int(stable.sum())} of {stable.size}", "")]
        rows += [spread(key, self.figures[key]) for key in self.HEADLINE if key in self.figures]
        return f"{stable.size} variants", rows
