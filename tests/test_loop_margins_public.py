"""cf.loop_margins and cf.closed_loop_figures: margins of any loop, checked against
python-control's own test systems and MATLAB's allmargin documentation."""

import contextlib
import io
import json
import math
import re

import control
import numpy as np
import pytest
from docs_pages import doc_section

import cas_freq as cf

s = control.tf("s")

# The systems of python-control's control/tests/margin_test.py (fixture ``tsys``, v0.10.2),
# each with the headline stability_margins it publishes: (gm [ratio], pm [deg], sm, wpc
# [rad/s], wgc [rad/s], wms [rad/s]); inf/nan where none.
MARGIN_TEST_SYSTEMS = [
    (control.tf([1, 2], [1, 2, 3]), (math.inf, math.inf, math.inf, math.nan, math.nan, math.nan)),
    (control.tf([1], [1, 2, 3, 4]), (2.0, math.inf, 0.4170, 1.7321, math.nan, 1.6620)),
    (control.ss([[1.0, 4.0], [3.0, 2.0]], [[1.0], [-4.0]], [[1.0, 0.0]], [[0.0]]),
     (math.inf, 147.0743, math.inf, math.nan, 2.5483, math.nan)),
    ((8.75 * (4 * s**2 + 0.4 * s + 1)) / ((100 * s + 1) * (s**2 + 0.22 * s + 1))
     / (s**2 / 10.0**2 + 2 * 0.04 * s / 10.0 + 1),
     (2.2716, 97.5941, 0.5591, 10.0053, 0.0850, 9.9918)),
    (1 / (1 + s), (math.inf, math.inf, math.inf, math.nan, math.nan, math.nan)),
    (3 * (10 + s) / (2 + s), (math.inf, math.inf, math.inf, math.nan, math.nan, math.nan)),
    (0.01 * (10 - s) / (2 + s) / (1 + s), (300.0, math.inf, 0.9917, 5.6569, math.nan, 2.3171)),
]

# python-control's "example21" (margin_test.py, fixture tsys_zmoresystems, from "A note on the
# Gain and Phase Margin Concepts", Journal of Control and Systems Engineering, 2015).
EXAMPLE21 = 0.002 * (s + 0.02) * (s + 0.05) * (s + 5) * (s + 10) / (
    (s - 0.0005) * (s + 0.0001) * (s + 0.01) * (s + 0.2) * (s + 1) * (s + 100) ** 2)

# MATLAB's allmargin documentation, first example
# (https://www.mathworks.com/help/control/ref/dynamicsystem.allmargin.html):
# L = tf(25, [1 10 10 10]) gives GainMargin 3.6000 at GMFrequency 3.1623, PhaseMargin 29.1104
# at PMFrequency 1.7844, DelayMargin 0.2847 at DMFrequency 1.7844, Stable 1.
MATLAB_L = control.tf(25, [1, 10, 10, 10])


def _db(ratio):
    return 20.0 * math.log10(ratio)


def _same_crossings_as_python_control(result, system):
    """Every crossing against python-control's polynomial method (stability_margins with
    returnall, which solves |L| = 1 and Im L = 0 as polynomial roots): an independent method;
    both refine to machine precision, so 1e-7 relative is ample (1e-6 deg / dB absolute)."""
    gm, pm, _, wpc, wgc, _ = control.stability_margins(system, returnall=True)
    # python-control also lists w = 0 when L(0) < 0, as we do, and when L(0) = 0 (a zero at
    # s = 0, gm inf): that is L starting at the origin, not a crossing of the negative axis
    touch = (np.asarray(wpc) == 0) & np.isinf(gm)
    gm, wpc = np.asarray(gm)[~touch], np.asarray(wpc)[~touch]
    order = np.argsort(wpc)
    np.testing.assert_allclose([c.frequency_rad_s for c in result.phase_crossovers],
                               np.asarray(wpc)[order], rtol=1e-7)
    np.testing.assert_allclose([c.gain_margin_db for c in result.phase_crossovers],
                               20 * np.log10(np.asarray(gm)[order]), atol=1e-6)
    order = np.argsort(wgc)
    np.testing.assert_allclose([c.frequency_rad_s for c in result.gain_crossovers],
                               np.asarray(wgc)[order], rtol=1e-7)
    np.testing.assert_allclose([c.phase_margin_deg for c in result.gain_crossovers],
                               np.asarray(pm)[order], atol=1e-6)


@pytest.mark.parametrize("number", range(len(MARGIN_TEST_SYSTEMS)))
def test_python_control_margin_test_systems(number):
    system, published = MARGIN_TEST_SYSTEMS[number]
    result = cf.loop_margins(system)
    # 1. Every crossing against python-control's polynomial method (stability_margins with
    # returnall, which solves |L| = 1 and Im L = 0 as polynomial roots): an independent
    # method; both refine to machine precision, so 1e-7 relative is ample.
    _same_crossings_as_python_control(result, system)
    # 2. The headline figures against the values margin_test.py publishes, with the
    # tolerance it checks python-control's own stability_margins against them (atol 1.5e-2:
    # they are 4-decimal values, some from an older computation, e.g. PM 97.5941 where
    # python-control 0.10.2 and we both give 97.59398).
    gm_ratio, pm_deg, sm, w_pc, w_gc, w_ms = published
    if math.isinf(gm_ratio):
        assert result.gain_margin_db is None and result.gain_margin_low_db is None
    else:  # python-control's gm is the crossing nearest the critical point: here upper
        assert 10 ** (result.gain_margin_db / 20) == pytest.approx(gm_ratio, abs=1.5e-2)
        assert result.phase_crossover_rad_s == pytest.approx(w_pc, abs=1.5e-2)
    if math.isinf(pm_deg):
        assert result.phase_margin_deg is None and result.gain_crossovers == ()
    else:
        assert result.phase_margin_deg == pytest.approx(pm_deg, abs=1.5e-2)
        assert result.crossover_rad_s == pytest.approx(w_gc, abs=1.5e-2)
    # 3. Ms = 1 / sm (sm: python-control's least distance to -1), only for a stable closed
    # loop, decided from the poles of feedback(L, 1) (system 3 is unstable closed-loop:
    # python-control still prints its sm, which is then no robustness figure).
    stable = bool(np.all(control.feedback(system, 1).poles().real < 0))
    assert result.closed_loop_stable is stable
    if stable and math.isfinite(sm):
        assert 1 / 10 ** (result.sensitivity_peak_db / 20) == pytest.approx(sm, abs=1.5e-2)
        assert result.sensitivity_peak_rad_s == pytest.approx(w_ms, abs=1.5e-2)
    if not stable:
        assert result.sensitivity_peak_db is None and result.disk_margin_alpha is None


# The "cornucopia of tricky systems" of margin_test.py (fixture tsys_zmoresystems), and the
# margin() results its test_zmore_margin publishes: (sysname, K, (gm, pm [deg], wpc, wgc), atol).
ZMORE = {
    "typem1": s / (s + 1),
    "type0": 1 / (s + 1) ** 3,
    "type1": (s + 0.1) / s / (s + 1),
    "type2": (s + 0.1) / s**2 / (s + 1),
    "type3": (s + 0.1) * (s + 0.1) / s**3 / (s + 1),
    "example21": EXAMPLE21,
    "example23": ((s + 0.1) ** 2 + 1) * (s - 0.1) / (((s + 0.1) ** 2 + 4) * (s + 1)),
    "example25a": s / (s**2 + 2 * s + 2) ** 4,
    "example26a": ((s - 0.1) ** 2 + 1) / ((s + 0.1) * ((s - 0.2) ** 2 + 4)),
    "example26b": ((s - 0.1) ** 2 + 1) / ((s - 0.3) * ((s - 0.2) ** 2 + 4)),
}
ZMORE["example24"] = EXAMPLE21 * 20000
ZMORE["example25b"] = ZMORE["example25a"] * 100
ZMORE["example22"] = EXAMPLE21 * (s**2 - 2 * s + 401)
ZMORE_MARGIN = [
    ("typem1", 2.0, (math.inf, -120.0007, math.nan, 0.5774), 1.5e-3),
    ("type0", 0.8, (10.0014, math.inf, 1.7322, math.nan), 1.5e-3),
    ("type0", 2.0, (4.000, 67.6058, 1.7322, 0.7663), 1e-2),
    ("type1", 1.0, (math.inf, 144.9032, math.nan, 0.3162), 1e-4),
    ("type2", 1.0, (math.inf, 44.4594, math.nan, 0.7907), 1e-4),
    ("type3", 1.0, (0.0626, 37.1748, 0.1119, 0.7951), 1.5e-3),
    ("example21", 1.0, (0.0100, -14.5640, 0, 0.0022), 1e-2),
    ("example21", 1000.0, (0.1793, 22.5215, 0.0243, 0.0630), 1e-2),
    ("example21", 5000.0, (4.5596, 21.2101, 0.4385, 0.1868), 1.5e-3),
]


@pytest.mark.parametrize("name", sorted(ZMORE))
def test_python_control_tricky_systems_every_crossing(name):
    # every one of the tricky systems, at three gains, crossing by crossing
    for gain in (0.8, 1.0, 2.0):
        _same_crossings_as_python_control(cf.loop_margins(ZMORE[name] * gain),
                                          ZMORE[name] * gain)


@pytest.mark.parametrize(("name", "gain", "published", "atol"), ZMORE_MARGIN)
def test_python_control_tricky_systems_headline(name, gain, published, atol):
    # margin()'s headline with margin_test.py's own tolerance. Its gm is the phase crossover
    # nearest the critical point, > 1 an upper margin (our gain_margin_db), < 1 a lower one
    # (gain_margin_low_db); its pm the gain crossover with the smallest |PM|, as ours.
    result = cf.loop_margins(ZMORE[name] * gain)
    gm, pm, wpc, wgc = published
    if math.isinf(gm):
        assert result.gain_margin_db is None and result.gain_margin_low_db is None
    elif gm > 1:
        assert 10 ** (result.gain_margin_db / 20) == pytest.approx(gm, abs=atol)
        assert result.phase_crossover_rad_s == pytest.approx(wpc, abs=atol)
    else:
        assert 10 ** (result.gain_margin_low_db / 20) == pytest.approx(gm, abs=atol)
        assert result.phase_crossover_low_rad_s == pytest.approx(wpc, abs=atol)
    if math.isinf(pm):
        assert result.phase_margin_deg is None
    else:
        assert result.phase_margin_deg == pytest.approx(pm, abs=atol)
        assert result.crossover_rad_s == pytest.approx(wgc, abs=atol)


def test_example21_times_1000():
    # python-control's margin_test.py test_zmore_margin publishes for example21 x 1000:
    # margin() = (gm 0.1793, pm 22.5215°, wpc 0.0243, wgc 0.0630). Its gm < 1 is a LOWER
    # margin (the gain may fall by 14.93 dB), so it is our gain_margin_low_db. The loop is
    # open-loop unstable (a pole at +0.0005) with a negative DC gain: its phase starts on the
    # -180° side, where the internal path once answered PM 382.5° and a 106 s delay margin.
    loop = EXAMPLE21 * 1000
    result = cf.loop_margins(loop)
    assert result.phase_margin_deg == pytest.approx(22.5215, abs=1e-4)  # published, 4 dec.
    assert result.crossover_rad_s == pytest.approx(0.0630, abs=1e-4)
    # gm to margin_test.py's tolerance there (atol 1e-2 on the ratio: 0.1793 is an older
    # value), and to python-control 0.10.2's margin() to rounding
    assert 10 ** (result.gain_margin_low_db / 20) == pytest.approx(0.1793, abs=1e-2)
    gm, pm, wpc, wgc = control.margin(loop)
    assert result.gain_margin_low_db == pytest.approx(_db(gm), abs=1e-7)
    assert result.phase_crossover_low_rad_s == pytest.approx(wpc, rel=1e-8)
    assert result.phase_margin_deg == pytest.approx(pm, abs=1e-7)
    assert result.crossover_rad_s == pytest.approx(wgc, rel=1e-8)
    # delay margin PM [rad] / wc = 6.24 s (to the 2 decimals the issue quotes); checked by a
    # second method: the closed loop with a Padé-8 delay is stable at 6.0 s, unstable at 6.5 s
    assert result.delay_margin_s == pytest.approx(6.24, abs=0.005)

    def stable_with_delay(tau):
        pade = control.tf(*control.pade(tau, 8))
        return bool(np.all(control.feedback(loop * pade, 1).poles().real < 0))

    assert stable_with_delay(6.0) and not stable_with_delay(6.5)
    assert result.closed_loop_stable is True


def test_matlab_allmargin_example():
    # MATLAB's printed values (see MATLAB_L), and analytically: L(jw) is real where
    # Im(den) = 10 w - w^3 = 0, w = sqrt(10), with den = 10 - 10 w^2 = -90: GM = 90/25 = 3.6.
    result = cf.loop_margins(MATLAB_L)
    assert result.phase_crossover_rad_s == pytest.approx(math.sqrt(10.0), rel=1e-9)
    assert result.gain_margin_db == pytest.approx(_db(3.6), rel=1e-9)
    assert result.phase_margin_deg == pytest.approx(29.1104, abs=1e-4)  # 4 decimals printed
    assert result.crossover_rad_s == pytest.approx(1.7844, abs=1e-4)
    assert result.delay_margin_s == pytest.approx(0.2847, abs=1e-4)
    assert result.delay_margin_crossover_rad_s == result.crossover_rad_s
    assert result.closed_loop_stable is True
    json.dumps(result.to_dict())  # JSON-ready


def test_delay_against_pade_of_high_order():
    # L e^(-0.1 s) against python-control on L times a Padé-10 delay: at the crossings
    # (w tau < 0.32) the Padé phase error is below 1e-12 rad, so the two agree to rounding.
    # Analytic too: a delay leaves |L| alone, so the crossover stays at MATLAB's 1.7844 and
    # PM falls by w_c tau [rad]; the delay margin falls by tau.
    tau = 0.1
    exact = cf.loop_margins(control.ss(MATLAB_L), delay=tau)
    plain = cf.loop_margins(MATLAB_L)
    gm, pm, _, wpc, wgc, _ = control.stability_margins(
        MATLAB_L * control.tf(*control.pade(tau, 10)))
    assert exact.phase_margin_deg == pytest.approx(pm, abs=1e-7)
    assert exact.crossover_rad_s == pytest.approx(wgc, rel=1e-9)
    assert exact.gain_margin_db == pytest.approx(_db(gm), abs=1e-7)
    assert exact.phase_crossover_rad_s == pytest.approx(wpc, rel=1e-8)
    assert exact.crossover_rad_s == pytest.approx(plain.crossover_rad_s, rel=1e-12)
    assert exact.phase_margin_deg == pytest.approx(
        plain.phase_margin_deg - math.degrees(plain.crossover_rad_s * tau), abs=1e-9)
    assert exact.delay_margin_s == pytest.approx(plain.delay_margin_s - tau, abs=1e-12)
    assert exact.closed_loop_stable is True and "Padé-10" in exact.stability_basis
    # a delay past the margin: the Padé-10 closed loop is unstable, Ms and disk margin None
    late = cf.loop_margins(MATLAB_L, delay=0.3)
    assert late.closed_loop_stable is False and late.sensitivity_peak_db is None


def test_callable_and_frequency_data():
    exact = cf.loop_margins(MATLAB_L)
    # a callable of s: the same crossings; closed-loop stability unknown unless given
    loop = lambda s: 25.0 / (s**3 + 10 * s**2 + 10 * s + 10)  # noqa: E731
    called = cf.loop_margins(loop, omega_range=(1e-2, 1e3))
    assert called.phase_margin_deg == pytest.approx(exact.phase_margin_deg, rel=1e-12)
    assert called.sensitivity_peak_db is None and called.closed_loop_stable is None
    assert "stable=" in called.stability_basis
    told = cf.loop_margins(loop, omega_range=(1e-2, 1e3), stable=True)
    assert told.sensitivity_peak_db == pytest.approx(exact.sensitivity_peak_db, rel=1e-9)
    # frequency data, 2000 points over 4 decades as margin_test.py's FRD test: interpolated
    # only, so close but not exact. ln|L| and phase linear in ln w between samples of spacing
    # h = ln(10) 4/1999 = 4.6e-3: the error is ~ h^2/8 times the curvature, ~1e-5 relative
    omega = np.logspace(-2, 2, 2000)
    frd = control.FrequencyResponseData(MATLAB_L, omega)
    from_frd = cf.loop_margins(frd, stable=True)
    from_arrays = cf.loop_margins((omega, MATLAB_L(1j * omega)), stable=True)
    for data in (from_frd, from_arrays):
        assert data.crossover_rad_s == pytest.approx(exact.crossover_rad_s, rel=1e-4)
        assert data.phase_margin_deg == pytest.approx(exact.phase_margin_deg, abs=1e-3)
        assert data.gain_margin_db == pytest.approx(exact.gain_margin_db, abs=1e-3)
        assert data.sensitivity_peak_db == pytest.approx(exact.sensitivity_peak_db, abs=1e-3)
        assert data.omega_range_rad_s == (0.01, 100.0)
    # python-control's own interpolation of the same data agrees to its tolerance (1.5e-3)
    gm, pm, _, _, _, _ = control.stability_margins(frd)
    assert from_frd.phase_margin_deg == pytest.approx(pm, abs=1.5e-3)


def test_closed_loop_figures():
    # T = L/(1+L) of MATLAB's example: T = 25 / (s^3 + 10 s^2 + 10 s + 35). Analytically
    # T(0) = 25/35; the phase is -90° where Re(den) = 35 - 10 w^2 = 0, w = sqrt(3.5). The
    # bandwidth from python-control's bandwidth() (its own root finding), told our line
    # (dbdrop -3.0103 dB, |T(0)|/√2; its default -3 dB gives 2.90218 rad/s, not 2.90322).
    closed = control.feedback(MATLAB_L, 1)
    figures = cf.closed_loop_figures(closed)
    assert figures.dc_gain_db == pytest.approx(_db(25 / 35), abs=1e-9)
    assert figures.phase_90_rad_s == pytest.approx(math.sqrt(3.5), rel=1e-9)
    assert figures.bandwidth_rad_s == pytest.approx(
        control.bandwidth(closed, dbdrop=-_db(math.sqrt(2))), rel=1e-6)
    # the peak by a second method: a dense grid around it (spacing 1e-5 rad/s)
    w = np.linspace(1.5, 2.5, 100_001)
    magnitude = np.abs(closed(1j * w)) / (25 / 35)
    assert figures.peak_db == pytest.approx(_db(magnitude.max()), abs=1e-8)
    assert figures.peak_rad_s == pytest.approx(w[magnitude.argmax()], abs=2e-5)
    assert figures.stable is True
    json.dumps(figures.to_dict())
    # an unstable T: every figure None
    unstable = cf.closed_loop_figures(control.tf(1, [1, -1]))
    assert unstable.stable is False and unstable.bandwidth_rad_s is None


def test_plots_return_figures():
    # figures that a notebook shows without %matplotlib (a PNG of their own, as every API plot)
    fig = cf.loop_margins(MATLAB_L, delay=0.05).plot()
    assert len(fig.axes) == 2 and "PM" in fig.axes[0].get_title()
    assert fig._repr_png_().startswith(b"\x89PNG")
    fig = cf.closed_loop_figures(control.feedback(MATLAB_L, 1)).plot()
    assert len(fig.axes) == 2 and fig._repr_png_().startswith(b"\x89PNG")


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="discrete-time system of dt=True; accepted"):
        cf.loop_margins(control.tf(1, [1, -0.5], True))
    with pytest.raises(ValueError, match="delay"):
        cf.loop_margins(MATLAB_L, delay=-1.0)
    with pytest.raises(ValueError, match="omega_range"):
        cf.loop_margins(MATLAB_L, omega_range=(10.0, 1.0))
    with pytest.raises(ValueError, match="SISO"):
        cf.loop_margins(control.tf([[[1], [1]]], [[[1, 1], [1, 2]]]))
    with pytest.raises(TypeError, match="accepted"):
        cf.loop_margins("25/(s+1)")
    with pytest.raises(ValueError, match="stable: 'yes'"):
        cf.loop_margins(MATLAB_L, stable="yes")
    with pytest.raises(ValueError, match="increasing"):
        cf.loop_margins((np.array([1.0, 3.0, 2.0]), np.ones(3)))


def test_readme_example_runs_as_written():
    # the "Margins of any loop" blocks of the Python API page (docs/api.md, moved there from
    # the README) and their output
    section = doc_section("docs/api.md", "Margins of any loop")
    code, shown = re.findall(r"```(?:python|text)\n(.*?)```", section, flags=re.S)[:2]
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "docs/api.md", "exec"), {})
    assert out.getvalue() == shown
