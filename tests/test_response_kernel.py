"""The compiled grid responses against the numpy reference, and the analysis on either.

:func:`cas_freq.analysis.response_kernel.grid_responses` evaluates the ratios of
:func:`cas_freq.model.loops.responses` point by point; only the rounding order differs (real
arithmetic at jw, one real division per complex division). The tolerance, 1e-12 of |value|
per point, is ~500x the largest difference measured over these cases (~2e-15): it allows the
few points where a sum such as D + N cancels by a few digits, and is still far below anything
the figures resolve.
"""

import numpy as np
import pytest

from cas_freq.analysis import FIGURES, batch_analyze, response_kernel
from cas_freq.analysis.frequency import (
    DEFAULT_POINTS_PER_DECADE,
    DEFAULT_RANGE_RAD_S,
    frequency_grid,
)
from cas_freq.analysis.response_kernel import grid_responses
from cas_freq.config import load_variant
from cas_freq.core.jit import COMPILED_FROM
from cas_freq.core.parameters import LoopParameters, variant_parameters
from cas_freq.model.delay import EXACT, DelayModel
from cas_freq.model.loops import Selector, responses

RUNS = 24
RELATIVE = 1e-12
OMEGA = frequency_grid(*DEFAULT_RANGE_RAD_S, DEFAULT_POINTS_PER_DECADE, 0.0005)
#: Keys varied in the analysis comparison -> their LoopParameters fields.
_FIELD = {"position_loop.Kp": "cp_Kp", "position_loop.Kd": "cp_Kd",
          "current_loop.Kp": "ci_Kp", "motor.J": "J"}


def _params(config="configs/qt_cas.yaml", variant="base"):
    return LoopParameters.from_config(load_variant(config, variant).params)


def _spread(rng, value, n=RUNS, low=0.7, high=1.4):
    return value * rng.uniform(low, high, n)


def _batch(base, rng, **changes):
    """RUNS copies of ``base`` with ``changes`` (arrays of RUNS values, or scalars)."""
    params = base.take(np.zeros(RUNS, dtype=int))
    return params.replace(**{name: np.broadcast_to(np.asarray(value, dtype=float), (RUNS,))
                             .copy() for name, value in changes.items()})


def _cases():
    rng = np.random.default_rng(12)
    qt = _params()
    fitted = _params(variant="fitted")
    servo = _params("configs/dc_servo.yaml")
    loaded = _params(variant="loaded")
    mixed = rng.uniform(size=RUNS) < 0.5
    return {
        # every loop parameter and the current-loop delay vary
        "qt_cas, six keys and delay": _batch(
            qt, rng, cp_Kp=_spread(rng, qt.cp_Kp[0]), cp_Kd=_spread(rng, qt.cp_Kd[0]),
            cp_Ki=_spread(rng, qt.cp_Ki[0]), ci_Kp=_spread(rng, qt.ci_Kp[0]),
            Km=_spread(rng, qt.Km[0]), J=_spread(rng, qt.J[0]),
            tau_c=_spread(rng, qt.tau_c[0])),
        # only the position gains vary: one current loop for all (L_i of shape (m,))
        "fitted, position gains only": _batch(
            fitted, rng, cp_Kp=_spread(rng, fitted.cp_Kp[0]), Tf=_spread(rng, fitted.Tf[0])),
        "dc_servo, motor and delays": _batch(
            servo, rng, R=_spread(rng, servo.R[0]), L=_spread(rng, servo.L[0]),
            tau_p=_spread(rng, servo.tau_p[0]), mu_v=_spread(rng, servo.mu_v[0])),
        # a rigid load with a hinge spring (D of degree 2, not divisible by s)
        "rigid load": _batch(fitted, rng, J_L=5e-5, b_L=_spread(rng, 2e-3), K_h=2.0,
                             eta=_spread(rng, 0.7, low=0.9, high=1.2)),
        # a compliant gear with mesh damping, some runs with an aiding hinge moment
        "two-mass drivetrain": _batch(
            fitted, rng, J_L=_spread(rng, 5e-5), K_g=_spread(rng, 3000.0), c_g=0.04,
            b_L=1e-3, K_h=np.where(mixed, -5.0, 2.0), eta=0.7),
        # the shipped loaded variant: compliant gear, load and hinge spring, gains varied
        "qt_cas loaded variant": _batch(
            loaded, rng, cp_Kp=_spread(rng, loaded.cp_Kp[0]), K_h=_spread(rng, loaded.K_h[0])),
        # compliant and rigid runs side by side, no hinge spring (D/s factored out)
        "some runs compliant": _batch(fitted, rng, J_L=5e-5, K_g=np.where(mixed, 3000.0, 0.0)),
    }


CASES = _cases()


def _reference(params, delay, closed=True, feedforward=False):
    return responses(Selector(params)(column=True), 1j * OMEGA, closed=closed, delay=delay,
                     feedforward=feedforward)


def _assert_close(compiled, reference):
    assert compiled.shape == reference.shape
    difference = np.abs(compiled - reference)
    assert np.all(np.isfinite(compiled))
    assert np.all(difference <= RELATIVE * np.abs(reference)), float(
        np.max(difference / np.abs(reference)))


@pytest.mark.parametrize("delay", [EXACT, DelayModel(3)], ids=["exact", "pade3"])
@pytest.mark.parametrize("name", list(CASES))
def test_compiled_responses_equal_the_numpy_reference(name, delay):
    params = CASES[name]
    compiled = grid_responses(Selector(params)(column=True), OMEGA, params.n_runs, delay)
    reference = _reference(params, delay)
    for loop in ("current_loop", "position_loop", "closed_loop"):
        expected = getattr(reference, loop)
        if loop != "current_loop":
            expected = np.broadcast_to(expected, (params.n_runs, OMEGA.size))
        _assert_close(getattr(compiled, loop), expected)


def test_shared_current_loop_comes_back_once():
    params = CASES["fitted, position gains only"]
    compiled = grid_responses(Selector(params)(column=True), OMEGA, params.n_runs, EXACT)
    assert compiled.current_loop.shape == OMEGA.shape
    assert compiled.position_loop.shape == (params.n_runs, OMEGA.size)


def test_derivative_on_measurement_and_feedforward_per_run():
    rng = np.random.default_rng(3)
    base = CASES["qt_cas, six keys and delay"]
    params = base.replace(
        derivative_on_measurement=rng.uniform(size=RUNS) < 0.5,
        ff_v=np.where(rng.uniform(size=RUNS) < 0.5, 0.0, _spread(rng, 0.05)),
        ff_a=_spread(rng, 1e-5))
    for feedforward in (False, True):
        compiled = grid_responses(Selector(params)(column=True), OMEGA, RUNS, EXACT,
                                  feedforward=feedforward)
        reference = _reference(params, EXACT, feedforward=feedforward)
        _assert_close(compiled.closed_loop, reference.closed_loop)
    # feed-forward changes T (so the test above compares something)
    without = grid_responses(Selector(params)(column=True), OMEGA, RUNS, EXACT)
    assert np.max(np.abs(without.closed_loop - compiled.closed_loop)) > 1e-3


def test_open_loops_only():
    params = CASES["two-mass drivetrain"]
    compiled = grid_responses(Selector(params)(column=True), OMEGA, RUNS, EXACT, closed=False)
    assert compiled.closed_loop is None
    _assert_close(compiled.position_loop, _reference(params, EXACT, closed=False).position_loop)


def _figures(monkeypatch, engine, params):
    monkeypatch.setenv("CAS_FREQ_ENGINE", engine)
    return batch_analyze(params, workers=1)


@pytest.mark.parametrize("config, variant", [("configs/qt_cas.yaml", "base"),
                                             ("configs/dc_servo.yaml", "base")])
def test_batch_analysis_is_the_same_on_either_path(monkeypatch, config, variant):
    # 64 runs x 1,601+ frequencies: above COMPILED_FROM, so the default engine compiles.
    loaded = load_variant(config, variant)
    rng = np.random.default_rng(5)
    single = LoopParameters.from_config(loaded.params)
    changes = {key: getattr(single, field)[0] * rng.uniform(0.5, 1.6, 64)
               for key, field in _FIELD.items()}
    params = variant_parameters(loaded.params, changes)
    calls = []
    original = response_kernel.grid_responses

    def counted(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(response_kernel, "grid_responses", counted)
    compiled = _figures(monkeypatch, "compiled", params)
    assert calls, "the compiled path was not taken"
    calls.clear()
    reference = _figures(monkeypatch, "reference", params)
    assert not calls
    assert list(compiled.stability) == list(reference.stability)
    for name in FIGURES:
        # where a maximum lies is set only to ~sqrt(eps) of its frequency: |S| and |T| are
        # flat there to second order, so a 1e-16 change of the samples moves the refined
        # maximum by ~1e-8 (up to 3e-8 measured); the other figures (crossings, margins,
        # peak values) agree to ~2e-14 (measured)
        rtol = 1e-6 if name.endswith("peak_rad_s") else 1e-10
        np.testing.assert_allclose(compiled.figures[name], reference.figures[name],
                                   rtol=rtol, atol=1e-12, equal_nan=True, err_msg=name)


def test_a_single_analysis_stays_on_numpy(monkeypatch):
    # a single analysis must not need numba: below COMPILED_FROM the numpy path runs (a batch
    # chooses once for all its chunks, so a run's figures do not depend on its chunk: see
    # tests/test_distributed.py)
    from cas_freq.analysis import analyze
    from cas_freq.config import load_variant

    monkeypatch.setattr(response_kernel, "grid_responses", None)  # would fail if called
    assert _params().n_runs * OMEGA.size < COMPILED_FROM
    assert analyze(load_variant(None, "base")).stable


def test_prepared_responses_equal_the_responses_of_the_chosen_runs():
    # The margin searches evaluate a few points of some runs through PreparedResponses (the
    # structure built once per batch). Reference: responses()/current_loop() of those runs'
    # own parameters (Selector(runs)); the same coefficients, so equal to the bit.
    from cas_freq.model.loops import PreparedResponses, current_loop

    params = load_variant("configs/cascade_axis.yaml").params
    rng = np.random.default_rng(3)
    p = variant_parameters(params, {"position_loop.Kp": 40.0 * rng.uniform(0.8, 1.2, 12),
                                    "velocity_loop.Kp": 1.3 * rng.uniform(0.8, 1.2, 12),
                                    "velocity_loop.feedback_filter": np.r_[np.zeros(6),
                                                                          np.full(6, 2e-4)]})
    selector = Selector(p)
    prepared = PreparedResponses(selector())
    runs = np.array([0, 3, 3, 7, 11, 6])
    s = 1j * np.geomspace(10.0, 1e5, runs.size)
    ours = prepared.responses(runs, s, closed=True, loop_at_a_time=True)
    theirs = responses(selector(runs), s, closed=True, delay=EXACT, loop_at_a_time=True)
    np.testing.assert_array_equal(ours.closed_loop, theirs.closed_loop)
    for name in theirs.loops:
        np.testing.assert_array_equal(ours.loops[name], theirs.loops[name])
        np.testing.assert_array_equal(ours.loop_at_a_time[name], theirs.loop_at_a_time[name])
        inner = prepared.responses(runs, s, closed=False, through=name).loops
        assert list(inner)[-1] == name
        np.testing.assert_array_equal(inner[name], theirs.loops[name])
    np.testing.assert_array_equal(prepared.current_loop(runs, s),
                                  current_loop(selector(runs), s))


def test_one_compilation_serves_every_architecture():
    # The kernel reads the loop table as data (coefficient stacks of fixed rank and dtype,
    # whatever the loops): a PID-on-PI, a velocity cascade with filters, a position loop on an
    # output encoder and a compliant drivetrain all run on the one machine code it has.
    from cas_freq.core import jit

    if not jit.use_compiled():
        pytest.skip("numba is not importable: nothing compiles")
    architectures = [("configs/qt_cas.yaml", "base"), ("configs/qt_cas.yaml", "fin_encoder"),
                     ("configs/qt_cas.yaml", "loaded"), ("configs/cascade_axis.yaml", "base"),
                     ("configs/dc_servo.yaml", "base")]
    for config, variant in architectures:
        params = _params(config, variant)
        for delay, closed, aat in ((EXACT, True, True), (DelayModel(3), False, False)):
            grid_responses(Selector(params)(column=True), OMEGA, 1, delay, closed=closed,
                           loop_at_a_time=aat)
    batch = CASES["qt_cas, six keys and delay"]  # coefficients per run
    grid_responses(Selector(batch)(column=True), OMEGA, batch.n_runs, EXACT)
    assert len(response_kernel._responses.signatures) == 1
    assert len(response_kernel._evaluate_all.signatures) == 1
