"""``cas-freq tune`` (issue 15): a known optimum, infeasibility, reproducibility, the written
config, robust and load-case scenario sets, bad input, the Pareto front, another actuator.

Every search here is small (16 global Sobol points, 1-2 refinement rounds of 32, or fewer) so
the file runs in well under 90 s on 2 cores; each expected value says where it comes from and
why its tolerance is what it is.
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from clirun import run_cli
from scipy import optimize, stats

import cas_freq as cf
from cas_freq.tuning.evaluate import TRADE_OFF, Evaluation
from cas_freq.tuning.search import ROUND_COUNT, pareto_front

ROOT = Path(__file__).resolve().parents[1]
QT_CAS = ROOT / "configs" / "qt_cas.yaml"
DC_SERVO = ROOT / "configs" / "dc_servo.yaml"

#: The small search every CLI run here uses (issue brief: 16 candidates, 2 rounds).
SMALL = ["--candidates", "16", "--rounds", "2"]


def _json(argv):
    """(exit status, parsed JSON, stderr) of ``cas-freq tune argv --json``."""
    code, out, err = run_cli(["tune", *argv, "--json"])
    return code, (json.loads(out) if out.strip() else None), err


def _requirement(data, rid, which="tuned"):
    return next(r for r in data[which]["requirements"] if r["id"] == rid)


# ---- 1. a known optimum ------------------------------------------------------------------------

#: The phase-margin bound of the one-requirement config [deg].
PM_MIN = 50.0


@pytest.fixture(scope="module")
def pd_config(tmp_path_factory):
    """dc_servo as a PD position loop (Ki = 0, Tf fixed at 0.1 ms so the derivative filter does
    not move with Kp), one requirement: position_loop.phase_margin_deg >= 50 deg (required).

    With a current-controlled double integrator Km/(J s^2) behind a PD, raising Kp raises the
    zero Kp/Kd above the crossover's neighbourhood: the phase lead at crossover falls and the
    crossover (hence the closed-loop bandwidth) rises. Checked on a grid in
    :func:`test_known_optimum_pd_phase_margin` (both monotonic over the whole search range), so
    the max-bandwidth optimum is the Kp where PM = 50 deg exactly.
    """
    raw = yaml.safe_load(DC_SERVO.read_text(encoding="utf-8"))
    raw["position_loop"]["Ki"] = 0
    raw["position_loop"]["Tf"] = "0.1 ms"
    raw["requirements"] = [{"id": "PM-X", "metric": "position_loop.phase_margin_deg",
                            "min": f"{PM_MIN} deg", "severity": "required",
                            "source": "test_tune: known optimum"}]
    path = tmp_path_factory.mktemp("pd") / "pd.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False), encoding="utf-8")
    return path


def test_known_optimum_pd_phase_margin(pd_config):
    actuator = cf.load(pd_config)
    kp0 = 6.0  # configs/dc_servo.yaml position_loop.Kp: 6 A/rad
    # Default range without --bounds: the variant's value /4 .. x4 (space.DEFAULT_FACTOR).
    lower, upper = kp0 / 4.0, kp0 * 4.0

    # Monotonicity over the search range (the premise of the known optimum), batch engine.
    grid = np.geomspace(lower, upper, 41)
    batch = actuator.vary({"position_loop.Kp": grid}).analyze()
    pm, bw = batch.position_loop.phase_margin_deg, batch.closed_loop.bandwidth_rad_s
    assert np.all(np.isfinite(pm)) and np.all(np.isfinite(bw))
    assert np.all(np.diff(pm) < 0) and np.all(np.diff(bw) > 0)
    assert pm[0] > PM_MIN > pm[-1]  # the optimum is inside the range, not at a bound

    # The optimum, independently of the tuner: root of PM(Kp) - 50 deg with the single-variant
    # analysis (cf.load(...).analyze(), not the batch code the tuner uses), to 1e-10 in Kp.
    def margin(kp):
        return cf.load(pd_config, set={"position_loop.Kp": kp}).analyze() \
            .position_loop.phase_margin_deg - PM_MIN

    kp_star = optimize.brentq(margin, lower, upper, xtol=1e-10, rtol=1e-12)

    rounds = 2
    code, data, _ = _json([str(pd_config), "--free", "position_loop.Kp", "--margin", "0",
                           "--objective", "max-bandwidth", "--candidates", "16",
                           "--rounds", str(rounds)])
    assert code == 0 and data["feasible"] is True
    assert data["free"][0]["lower"] == pytest.approx(lower, rel=1e-12)
    assert data["free"][0]["upper"] == pytest.approx(upper, rel=1e-12)
    kp = data["tuned"]["values"]["position_loop.Kp"]
    # Feasible side: PM(kp) >= 50 deg, i.e. kp <= kp_star (PM falls with Kp); the tuner's own
    # figure and an independent analysis agree.
    assert _requirement(data, "PM-X")["nominal"] >= PM_MIN
    assert margin(kp) >= -1e-9
    assert kp <= kp_star * (1 + 1e-9)
    # Resolution. The search works in u = ln(Kp/lower)/ln(upper/lower) in [0, 1]. A scrambled
    # base-2 Sobol set of 2^m points puts exactly one point in each of the 2^m equal strata, so:
    # the 16 global points leave the incumbent within 2/16 of u*; round r (half-width
    # h_r = 0.25 * 0.5^r, 32 points) has one point per stratum of 2 h_r / 32, and u* stays in its
    # box (h_0 = 1/4 >= 2/16, h_1 = 1/8 >= 2 * 2 h_0/32), so after the last round the best
    # feasible point is within two strata of u*: 2 * 2 h_last / 32 in u.
    h_last = 0.25 * 0.5 ** (rounds - 1)
    du = 2 * 2 * h_last / ROUND_COUNT
    log_range = math.log(upper / lower)
    assert math.log(kp_star / kp) <= du * log_range + 1e-12, (kp, kp_star)
    # ... and the bandwidth it reports is the objective's, the largest seen among feasible ones.
    assert data["tuned"]["objective"] == pytest.approx(
        actuator.vary({"position_loop.Kp": [kp]}).analyze().closed_loop.bandwidth_rad_s[0],
        rel=1e-9)


# ---- 2. infeasible -----------------------------------------------------------------------------

def test_infeasible_bounds_exit_1_names_bw1(tmp_path):
    # Kp 0.01..0.02 A/rad (the shipped 6.34 / ~300) and tiny Ki, Kd: the loop gain is ~300x
    # below the shipped one, whose bandwidth is ~1385 rad/s; nothing reaches 300 rad/s.
    argv = [str(QT_CAS), "--bounds", "position_loop.Kp=0.01:0.02",
            "--bounds", "position_loop.Ki=0.01:0.02", "--bounds", "position_loop.Kd=1e-5:2e-5",
            "--candidates", "8", "--rounds", "1"]
    code, out, _ = run_cli(["tune", *argv])
    assert code == 1
    assert "INFEASIBLE" in out
    assert "the closest candidate misses" in out and "BW-1" in out.split(
        "the closest candidate misses", 1)[1].splitlines()[0]
    code, data, _ = _json(argv)
    assert code == 1 and data["feasible"] is False and data["feasible_candidates"] == 0
    bw1 = _requirement(data, "BW-1")
    assert bw1["shortfall"] > 0
    # Shortfall is relative to the tightened bound (300 * 1.02 = 306 rad/s, --margin 2 default).
    if bw1["nominal"] is not None:
        assert bw1["shortfall"] == pytest.approx((306.0 - bw1["nominal"]) / 306.0, rel=1e-9)
    assert data["best_reachable"]["BW-1"] is None or data["best_reachable"]["BW-1"] < 306.0
    # Without -o an infeasible tune writes no config and prints no drive settings.
    assert data["drive"] is None and "written" not in data


# ---- 3. reproducibility ------------------------------------------------------------------------

REPRO = ["--variant", "fitted", "--required-only", *SMALL]


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_same_seed_same_values_other_seed_still_feasible(tmp_path):
    code_a, a, _ = _json([*REPRO, "--seed", "3"])
    code_b, b, _ = _json([*REPRO, "--seed", "3"])
    assert code_a == code_b == 0
    assert a["tuned"]["values"] == b["tuned"]["values"]  # exactly: every draw is from the seed
    assert a["pareto"] == b["pareto"]
    code_c, c, _ = _json([*REPRO, "--seed", "4", "-o", str(tmp_path / "c.yaml")])
    assert code_c == 0 and c["feasible"] is True
    assert all(r["shortfall"] == 0 for r in c["tuned"]["requirements"])
    code, out, _ = run_cli(["verify", str(tmp_path / "c.yaml"), "--variant", "tuned", "--json"])
    assert code == 0 and json.loads(out)["passed"] is True


# ---- 4. the tuned config verifies; the input is never changed ----------------------------------

@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_tuned_config_verifies_and_input_unchanged(tmp_path):
    config = tmp_path / "in.yaml"
    config.write_bytes(QT_CAS.read_bytes())
    before = config.read_bytes()
    out_path = tmp_path / "tuned.yaml"
    # --required-only: with the advisory requirements held too, 16 + 2 x 32 candidates find no
    # feasible one for 'fitted' (the default 128 + 6 x 32 do); the test is about the written file.
    code, data, _ = _json([str(config), "--variant", "fitted", "--required-only", *SMALL,
                           "-o", str(out_path)])
    assert code == 0 and data["feasible"] is True and data["written"] == str(out_path)
    assert config.read_bytes() == before
    code, out, _ = run_cli(["verify", str(out_path), "--variant", "tuned", "--json"])
    assert code == 0
    verdicts = {v["id"]: v for v in json.loads(out)["verdicts"]}
    assert verdicts["BW-1"]["status"] == "PASS" and verdicts["OS-1"]["status"] == "PASS"
    # verify measures what the tune reported (values written to 1e-5 relative, so 1e-3 here).
    for rid in ("BW-1", "OS-1"):
        assert verdicts[rid]["value"] == pytest.approx(_requirement(data, rid)["nominal"],
                                                       rel=1e-3)
    # The other variants of the written config are the input's.
    written = yaml.safe_load(out_path.read_text(encoding="utf-8"))
    original = yaml.safe_load(before)
    assert written["variants"]["fitted"] == original["variants"]["fitted"]
    for key, value in data["tuned"]["values"].items():
        load = cf.load(out_path, variant="tuned").params
        section, name = key.split(".")
        assert float(np.ravel(getattr(getattr(load, section), name))[0]) == pytest.approx(
            value, rel=1e-5)

    # -o equal to the input config: exit 2, the input untouched.
    code, out, err = run_cli(["tune", str(config), "--variant", "fitted", "--candidates", "1",
                              "--rounds", "0", "-o", str(config)])
    assert code == 2 and "-o" in err and "input" in err
    assert config.read_bytes() == before


# ---- 5. robust ----------------------------------------------------------------------------------

@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_robust_montecarlo_yield_holds_on_fresh_samples(tmp_path):
    out_path = tmp_path / "robust.yaml"
    samples, target = 20, 90.0
    code, data, _ = _json(["--variant", "fitted", "--required-only", *SMALL,
                           "--robust", f"montecarlo:{samples}", "--tolerance", "motor.Km=10%",
                           "--yield", str(target), "-o", str(out_path)])
    assert code == 0 and data["feasible"] is True
    assert data["scenarios"]["count"] == 1 + samples  # nominal + the samples
    assert data["scenarios"]["target_yield_pct"] == pytest.approx(target)
    stated = data["tuned"]["yield_pct"]
    assert stated >= target

    # Check on 200 fresh draws (seed 7, not the tune's seed 0) with every figure per sample.
    folder = tmp_path / "mc"
    code, _, _ = run_cli(["montecarlo", str(out_path), "--variant", "tuned", "--tolerance",
                          "motor.Km=10%", "--samples", "200", "--seed", "7", "--json", "-q",
                          "-o", str(folder)])
    assert code in (0, 1)
    report = json.loads((folder / "montecarlo.json").read_text(encoding="utf-8"))
    rows = {r["id"]: r for r in report["requirements"]}
    # The joint yield of the held (required) requirements over the 200 samples, from the
    # per-requirement counts: joint >= 1 - sum of per-requirement failure rates (union bound).
    held = [h["id"] for h in data["held"]]
    assert set(held) == {"BW-1", "OS-1"}
    joint = 100.0 - sum(100.0 - rows[rid]["yield_pct"] for rid in held)
    # Allowance. The tune's 20 samples only show that >= 18 of 20 passed (90 %). The one-sided
    # 99 % Clopper-Pearson lower bound of a pass rate with 18/20 passes is
    # beta.ppf(0.01, 18, 3) ~= 0.64: a true yield that low still passes 18 of 20 draws 1 % of
    # the time (and the search picks among many candidates, which favours lucky ones). The 200
    # fresh samples add their own noise, 3 sigma of a binomial at that rate. The tune's 2 %
    # margin only helps (verify's bounds are looser).
    passes = math.ceil(target / 100.0 * samples)
    lower = stats.beta.ppf(0.01, passes, samples - passes + 1)
    noise = 3.0 * math.sqrt(lower * (1.0 - lower) / 200)
    allowance = 100.0 * (target / 100.0 - (lower - noise))
    assert joint >= target - allowance, (joint, target, allowance)
    # Both run the same model on the same draws kind: the tune's own stated yield of the chosen
    # candidate is no worse than its per-requirement yields.
    for rid in held:
        assert _requirement(data, rid)["yield_pct"] >= stated - 1e-9


def test_robust_corners_two_tolerances_count():
    code, data, _ = _json(["--variant", "fitted", "--required-only", "--candidates", "2",
                           "--rounds", "0", "--robust", "corners", "--tolerance", "motor.Km=10%",
                           "--tolerance", "motor.J=10%"])
    assert code in (0, 1)
    # The nominal plus the 2^2 corners of the tolerance box; every corner counted (100 %).
    assert data["scenarios"]["count"] == 1 + 4
    assert data["scenarios"]["target_yield_pct"] == pytest.approx(100.0)


# ---- 6. load cases ------------------------------------------------------------------------------

@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_load_cases_multiply_scenarios():
    grid = cf.load(QT_CAS, variant="fitted").params.load_envelope.hinge_stiffness
    size = len(grid)
    assert size == 17  # configs/qt_cas.yaml: hinge_stiffness "-20:60:17"
    code, data, _ = _json(["--variant", "fitted", "--required-only", "--candidates", "1",
                           "--rounds", "0", "--load-cases"])
    assert code in (0, 1)
    assert data["scenarios"]["count"] == size
    code, data, _ = _json(["--variant", "fitted", "--required-only", "--candidates", "1",
                           "--rounds", "0", "--load-cases", "--robust", "corners",
                           "--tolerance", "motor.Km=10%"])
    assert code in (0, 1)
    assert data["scenarios"]["count"] == (1 + 2) * size


def test_load_cases_without_envelope_exit_2():
    code, _, err = run_cli(["tune", str(DC_SERVO), "--candidates", "1", "--rounds", "0",
                            "--load-cases"])
    assert code == 2 and "load_envelope" in err and "--load-cases" in err


# ---- 7. bad input -------------------------------------------------------------------------------

@pytest.mark.parametrize("extra, names", [
    (["--free", "position_loop.Kq"], "position_loop.Kq"),
    (["--free", "position_loop.Kp", "--bounds", "position_loop.Ki=1:2"], "position_loop.Ki"),
    (["--bounds", "position_loop.Kp=5:1"], "position_loop.Kp"),
    (["--robust", "montecarlo:x", "--tolerance", "motor.Km=10%"], "--robust"),
    (["--robust", "corners"], "--robust"),
    (["--tolerance", "motor.Km=10%"], "--tolerance"),
    (["--compare", "somewhere"], "--compare"),
    (["--free", "position_loop.ff_v", "--set", "position_loop.ff_v=0"], "position_loop.ff_v"),
    (["--candidates", "0"], "--candidates"),
    (["--margin", "-1"], "--margin"),
])
def test_bad_input_exit_2(extra, names, tmp_path):
    code, out, err = run_cli(["tune", "--candidates", "1", "--rounds", "0", *extra])
    assert code == 2, (out, err)
    assert names in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


# ---- 8. the Pareto front ------------------------------------------------------------------------

def _dominates(a, b):
    """a beats b: no worse in every trade-off figure (signed), better in one."""
    return bool(np.all(a >= b) and np.any(a > b))


def _signed(evaluation, i):
    return np.array([sense * evaluation.nominal[name][i] for name, sense in TRADE_OFF])


def _check_front(evaluation, front):
    feasible = [i for i in np.flatnonzero(evaluation.feasible)
                if np.all(np.isfinite(_signed(evaluation, i)))]
    assert set(front) <= set(feasible)
    for i in front:
        assert not any(_dominates(_signed(evaluation, j), _signed(evaluation, i))
                       for j in feasible), i
    for i in set(feasible) - set(front):
        assert any(_dominates(_signed(evaluation, j), _signed(evaluation, i))
                   or np.array_equal(_signed(evaluation, j), _signed(evaluation, i))
                   for j in front), i
    bandwidth = evaluation.nominal[TRADE_OFF[0][0]][front]
    assert np.all(np.diff(bandwidth) >= 0)  # ordered by bandwidth


def test_pareto_front_hand_made():
    # (bandwidth up, phase margin up, overshoot down); feasibility in the last column.
    rows = [
        (100.0, 60.0, 5.0, True),    # 0 front: best PM and OS
        (200.0, 50.0, 8.0, True),    # 1 front
        (150.0, 50.0, 9.0, True),    # 2 dominated by 1
        (300.0, 40.0, 10.0, True),   # 3 front: best bandwidth
        (400.0, 70.0, 1.0, False),   # 4 infeasible: dominates all, must not be on the front
        (200.0, 50.0, 8.0, True),    # 5 duplicate of 1: kept once
        (250.0, np.nan, 3.0, True),  # 6 a figure missing: not on the front
        (90.0, 60.0, 5.0, True),     # 7 dominated by 0 (less bandwidth)
    ]
    data = np.array([r[:3] for r in rows])
    n = len(rows)
    evaluation = Evaluation(
        values={"position_loop.Kp": np.arange(n, dtype=float)},
        objective=data[:, 0].copy(), passed=np.ones((n, 1)), yield_all=np.ones(n),
        feasible=np.array([r[3] for r in rows]), violation=np.zeros((n, 1)),
        nominal={"closed_loop.bandwidth_rad_s": data[:, 0],
                 "position_loop.phase_margin_deg": data[:, 1],
                 "step.overshoot_pct": data[:, 2]}, stable=np.ones(n, dtype=bool))
    front = list(pareto_front(evaluation))
    assert front == [0, 1, 3]
    _check_front(evaluation, front)


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_pareto_front_of_a_tune():
    from cas_freq.config import load_variant
    from cas_freq.tuning import tune
    from cas_freq.tuning.evaluate import constraints
    from cas_freq.tuning.options import DEFAULT_FREE
    from cas_freq.tuning.scenarios import scenarios
    from cas_freq.tuning.space import tune_keys

    loaded = load_variant(QT_CAS, "fitted")
    keys = tune_keys(loaded.params, DEFAULT_FREE, {})
    held, skipped = constraints(loaded.params.requirements, 0.02, advisory=False)
    result = tune(loaded.params, keys, scenarios(loaded.params), held, skipped,
                  global_count=16, rounds=1, seed=0)
    assert result.evaluation.feasible.sum() >= 3
    _check_front(result.evaluation, list(result.pareto))
    assert list(result.pareto) == list(pareto_front(result.evaluation))


# ---- 9. another actuator -------------------------------------------------------------------------

def test_dc_servo_tune_consistent_with_verify(tmp_path):
    out_path = tmp_path / "dc.yaml"
    code, data, _ = _json([str(DC_SERVO), *SMALL, "-o", str(out_path)])
    assert code in (0, 1)
    assert (code == 0) == data["feasible"]
    vcode, out, _ = run_cli(["verify", str(out_path), "--variant", "tuned", "--json"])
    verdicts = {v["id"]: v for v in json.loads(out)["verdicts"]}
    margin = 0.02  # --margin 2 (default): the tune's bounds are 2 % tighter than verify's
    for row in data["tuned"]["requirements"]:
        v = verdicts[row["id"]]
        if row["nominal"] is not None:
            assert v["value"] == pytest.approx(row["nominal"], rel=1e-3), row["id"]
        if row["shortfall"] == 0:
            assert v["status"].startswith("PASS"), (row, v)
        elif row["shortfall"] > margin + 1e-3:
            assert not v["status"].startswith("PASS"), (row, v)
    if code == 0:
        assert vcode == 0  # every held requirement (required ones included) passes verify


# ---- bugs the first version of this file found (fixed) --------------------------------------

def test_bad_yield_without_montecarlo_exit_2():
    code, _, err = run_cli(["tune", "--candidates", "1", "--rounds", "0", "--yield", "150"])
    assert code == 2 and "--yield" in err


def test_an_unstable_candidate_is_not_assessed_not_short_by_1000_percent():
    # An aiding hinge spring of -1e9 N*m/rad (an accepted value) makes every candidate's
    # closed loop unstable. Each requirement then fails with shortfall MISSING_VIOLATION
    # (10, a rank); the text printed it as "short by 1e+03 %", also on GM-I, whose 9.693 dB
    # meets its 6.12 dB bound. It now says why, as verify does ("not assessed: the closed
    # loop is unstable"); the instability is checked independently by analyze at the
    # closest candidate's values.
    argv = ["--variant", "loaded", "--set", "load.hinge_stiffness=-1e9", "--candidates", "4",
            "--rounds", "0"]
    code, out, _ = run_cli(["tune", *argv])
    assert code == 1 and "short by" not in out
    gm_i = next(line for line in out.splitlines() if line.lstrip().startswith("GM-I "))
    assert gm_i.endswith("not assessed: the closed loop is unstable")
    assert "the closest candidate misses: every requirement (its closed loop is unstable)" in out
    code, data, _ = _json(argv)
    assert code == 1 and data["tuned"]["stable"] is False
    assert all(r["not_assessed"] == "the closed loop is unstable"
               for r in data["tuned"]["requirements"])
    sets = [f"--set={key}={value!r}" for key, value in data["tuned"]["values"].items()]
    code, out, _ = run_cli(["analyze", *argv[:4], *sets, "--json"])
    assert code == 0 and json.loads(out)["stability"] == "unstable"


def test_before_is_the_variant_even_outside_the_bounds():
    code, data, _ = _json(["--bounds", "position_loop.Kp=0.01:0.02", "--candidates", "1",
                           "--rounds", "0"])
    assert code in (0, 1)
    start = data["free"][0]["start"]
    assert start == pytest.approx(6.3435, rel=1e-12)  # configs/qt_cas.yaml, base variant
    assert data["before"]["values"]["position_loop.Kp"] == pytest.approx(start, rel=1e-12)
    # The base variant's BW-1 as verify measures it (exact delays, same engine).
    code, out, _ = run_cli(["verify", "--json"])
    measured = next(v["value"] for v in json.loads(out)["verdicts"] if v["id"] == "BW-1")
    assert _requirement(data, "BW-1", "before")["nominal"] == pytest.approx(measured, rel=1e-6)


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_a_tune_on_a_local_cluster_is_the_local_tune():
    """--scheduler local:2 evaluates the batches on dask workers; the result is the local one
    to the last digit of the JSON (the chunks are evaluated by the same code, in order). Two
    batches of one config in one session also guard the scatter key (a second scatter of the
    same config reused the first's key, which its release then dropped: "lost
    dependencies")."""
    pytest.importorskip("distributed", reason="the 'distributed' extra is not installed")
    argv = ["--variant", "fitted", "--candidates", "32", "--rounds", "1"]
    runs = []
    for extra in ([], ["--scheduler", "local:2"]):
        code, data, err = _json(argv + extra)
        assert code in (0, 1), err
        data.pop("seconds")
        runs.append(data)
    assert runs[0] == runs[1]
