"""A worm gear's efficiencies from its geometry (``gear.worm``) and an inertia simulant from its
(``load.simulant``): issue 41, item 1; docs/model.md §5.

Independent derivations:

* the worm, as an inclined plane with friction: with the friction angle phi' = atan(f / cos
  phi_n), driving the wheel gives eta = tan(lambda) / tan(lambda + phi') and being driven
  eta_b = tan(lambda - phi') / tan(lambda), 0 where lambda <= phi' (self-locking); cas_freq
  writes the same thing as ratios of cosines and tangents (Shigley), so agreement to 1e-12 is
  arithmetic, any slip in a sign or an angle moves it by percent;
* the disc: its mass rho pi t (R^2 - r^2) times (R^2 + r^2) / 2;
* the reflected inertia: behind a rigid gear the loops see J + J_L / (eta N^2)
  (docs/model.md §5), so the QT-CAS with a simulant and a worm has the closed loop T of the
  QT-CAS whose rotor inertia is that sum and which has no load at all (to 1e-12 relative).
"""

import math

import numpy as np
import pytest
from clirun import run_cli

import cas_freq as cf
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.formulas import disc_inertia, worm_efficiencies

QT = "configs/qt_cas.yaml"
SIMULANT = {"load.simulant.diameter": "74 mm", "load.simulant.thickness": "10 mm",
            "load.simulant.name": "steel disc"}
WORM = {"gear.worm.lead_angle": "5 deg", "gear.worm.friction_coefficient": 0.05}


@pytest.mark.parametrize("lead_deg, friction, pressure_deg", [
    (5.0, 0.05, 20.0), (3.6, 0.08, 20.0), (15.0, 0.1, 14.5), (30.0, 0.02, 20.0),
    (2.0, 0.1, 20.0),  # self-locking
])
def test_worm_efficiencies_match_the_inclined_plane(lead_deg, friction, pressure_deg):
    lead, pressure = math.radians(lead_deg), math.radians(pressure_deg)
    phi = math.atan(friction / math.cos(pressure))
    forward = math.tan(lead) / math.tan(lead + phi)
    back = max(math.tan(lead - phi) / math.tan(lead), 0.0)
    ours = worm_efficiencies(lead, friction, pressure)
    assert ours[0] == pytest.approx(forward, rel=1e-12)
    assert ours[1] == pytest.approx(back, rel=1e-12, abs=1e-15)
    if lead < phi:
        assert ours[1] == 0.0


def test_disc_inertia_is_half_m_r_squared():
    diameter, thickness, density, bore = 0.074, 0.01, 7850.0, 0.008
    mass = density * math.pi * thickness * ((diameter / 2) ** 2 - (bore / 2) ** 2)
    expected = 0.5 * mass * ((diameter / 2) ** 2 + (bore / 2) ** 2)
    assert disc_inertia(diameter, thickness, density, bore) == pytest.approx(expected,
                                                                             rel=1e-12)


def test_the_loops_see_the_simulant_reflected_by_eta_n_squared():
    loaded = cf.load(QT, set={**SIMULANT, **WORM})
    params = loaded.params
    eta, ratio = params.gear.efficiency, params.gear.ratio
    simulant = params.load.inertia
    assert simulant == pytest.approx(disc_inertia(0.074, 0.01, 7850.0), rel=1e-12)
    lumped = cf.load(QT, set={"motor.J": params.motor.J + simulant / (eta * ratio**2)})
    omega = np.geomspace(1.0, 1e5, 400)
    ours = loaded.frequency_response(omega).closed_loop
    theirs = lumped.frequency_response(omega).closed_loop
    np.testing.assert_allclose(ours, theirs, rtol=1e-12)
    # and the efficiency matters: with eta = 1 the same simulant gives another loop
    rigid = cf.load(QT, set={"motor.J": params.motor.J + simulant / ratio**2})
    assert np.max(np.abs(rigid.frequency_response(omega).closed_loop - ours)) > 1e-3


def test_analyze_names_the_simulant_and_the_worm():
    code, out, err = run_cli(["analyze", QT, *(f"--set={k}={v}" for k, v in
                                                {**SIMULANT, **WORM}.items())])
    assert code == 0, err
    assert "the steel disc, a disc of 74 mm diameter and 10 mm thickness" in out
    assert "forward 0.6189, backdrive 0.39" in out


@pytest.mark.parametrize("changes, message", [
    ({**WORM, "gear.efficiency": 0.5}, "remove gear.efficiency"),
    ({**SIMULANT, "load.inertia": 1e-5}, "remove load.inertia"),
    ({"load.simulant.diameter": "74 mm"}, "load.simulant.thickness"),
    ({**SIMULANT, "load.simulant.bore": "80 mm"}, "must be below the diameter"),
    ({"gear.worm.lead_angle": "5 deg"}, "gear.worm.friction_coefficient"),
    ({"gear.worm.lead_angle": "60 deg", "gear.worm.friction_coefficient": 0.9},
     "cannot drive the wheel"),
    ({"gear.worm.lead_angle": "95 deg", "gear.worm.friction_coefficient": 0.1},
     "gear.worm.lead_angle"),
])
def test_bad_descriptions_are_refused_naming_the_key(changes, message):
    with pytest.raises(ConfigError, match=message):
        cf.load(QT, set=changes)
