"""Closed-form relations of ARL-TR-9136 (cas_freq.core.formulas)."""

import math

import pytest

from cas_freq.core.formulas import second_order_bandwidth, viscous_friction_from_no_load

# Report Table 3 (catalog motor): Km = 0.0105 N*m/A, n0 = 16,300 rpm (docs/model.md erratum: the
# table says rad/s), I0 = 0.218 A.
KM = 0.0105
N0_RAD_S = 16300 * 2 * math.pi / 60
I0 = 0.218


def test_viscous_friction_matches_report_table_3():
    # Table 3 prints mu_v = 1.341e-6 N*m*s/rad, rounded to 4 significant digits: the rounding
    # error is at most 0.5e-9 / 1.341e-6 = 3.7e-4 relative, so rel 5e-4 accepts the table value
    # and nothing coarser.
    assert viscous_friction_from_no_load(KM, N0_RAD_S, I0) == pytest.approx(1.341e-6, rel=5e-4)


def test_viscous_friction_is_torque_balance():
    # Analytic: at no load Km*I0 = mu_v*w0 (report §6), so mu_v*w0/I0 gives Km back; one
    # multiplication and one division, so rel 1e-14 is a few ulps.
    mu_v = viscous_friction_from_no_load(KM, N0_RAD_S, I0)
    assert mu_v * N0_RAD_S / I0 == pytest.approx(KM, rel=1e-14)
    assert viscous_friction_from_no_load(KM, N0_RAD_S, 0.0) == 0.0


@pytest.mark.parametrize("speed", [0.0, -1706.9])
def test_viscous_friction_rejects_non_positive_speed(speed):
    with pytest.raises(ValueError, match=r"no_load_speed: must be > 0 rad/s"):
        viscous_friction_from_no_load(KM, speed, I0)


def test_viscous_friction_rejects_nan_speed():
    with pytest.raises(ValueError, match="no_load_speed"):
        viscous_friction_from_no_load(KM, math.nan, I0)


def test_second_order_bandwidth_matches_report_section_7():
    # Report §7: wn = 462 rad/s, zeta = 0.54 give "566 rad/s", i.e. rounded to 3 digits, so the
    # exact value lies within +-0.5 rad/s of 566.
    assert second_order_bandwidth(462.0, 0.54) == pytest.approx(566.0, abs=0.5)


def test_second_order_bandwidth_at_zeta_one_over_root_two_is_wn():
    # Analytic: zeta^2 = 1/2 makes 1 - 2 zeta^2 = 0 and 4 zeta^4 - 4 zeta^2 + 2 = 1 - 2 + 2 = 1,
    # so w_BW = wn * sqrt(0 + sqrt(1)) = wn (the Butterworth case). Only rounding of
    # (1/sqrt(2))^2 separates it from wn: rel 1e-12.
    for wn in (1.0, 462.0, 1e4):
        assert second_order_bandwidth(wn, 1 / math.sqrt(2)) == pytest.approx(wn, rel=1e-12)


def test_second_order_bandwidth_undamped():
    # Analytic: zeta = 0 gives wn * sqrt(1 + sqrt(2)).
    assert second_order_bandwidth(100.0, 0.0) == pytest.approx(
        100.0 * math.sqrt(1 + math.sqrt(2)), rel=1e-14
    )


@pytest.mark.parametrize("zeta", [0.1, 0.54, 0.7, 1.0, 2.0])
def test_second_order_bandwidth_is_half_power_point(zeta):
    # Independent check from the definition: |T(jw)|^2 = 1/2 at w_BW for
    # T(s) = wn^2 / (s^2 + 2 zeta wn s + wn^2). Evaluating T in complex arithmetic at a value
    # accurate to ~1e-15 gives |T|^2 to ~1e-13.
    wn = 462.0
    w = second_order_bandwidth(wn, zeta)
    s = 1j * w
    t = wn**2 / (s**2 + 2 * zeta * wn * s + wn**2)
    assert abs(t) ** 2 == pytest.approx(0.5, rel=1e-12)


@pytest.mark.parametrize(
    ("wn", "zeta", "field"),
    [
        (0.0, 0.5, "natural_frequency"),
        (-462.0, 0.5, "natural_frequency"),
        (math.nan, 0.5, "natural_frequency"),
        (462.0, -0.1, "damping_ratio"),
        (462.0, math.nan, "damping_ratio"),
    ],
)
def test_second_order_bandwidth_rejects_bad_input(wn, zeta, field):
    with pytest.raises(ValueError, match=field):
        second_order_bandwidth(wn, zeta)


@pytest.mark.parametrize("zeta", [3.0, 1e3, 1e4, 1e8, 1e100])
def test_second_order_bandwidth_of_a_heavily_damped_fit(zeta):
    """For zeta >> 1 the closed form cancels (1 - 2 zeta^2 + sqrt(...)); written stably it tends
    to wn / (2 zeta): |T|^2 = wn^4 / ((wn^2 - w^2)^2 + 4 zeta^2 wn^2 w^2) = 1/2 there, to
    O(1/zeta^2) relative. A fuzzed config's step fitted zeta ~ 1e4 raised a math domain error."""
    wn = 462.0
    value = second_order_bandwidth(wn, zeta)
    assert value == pytest.approx(wn / (2 * zeta), rel=max(1.0 / zeta**2, 1e-12))
    w = value
    magnitude2 = wn**4 / ((wn**2 - w**2) ** 2 + 4 * (zeta * wn * w) ** 2)
    assert magnitude2 == pytest.approx(0.5, rel=1e-9)


def test_second_order_bandwidth_of_an_absurd_damping_is_zero_not_an_error():
    assert second_order_bandwidth(462.0, 1e200) == 0.0
