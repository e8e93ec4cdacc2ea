"""The shipped config's figures are those of the previous release, to 1e-6 relative.

Reference: ``cas-freq analyze --all-variants --json`` of cas_freq before the engine merge
(commit 6f7f9ed), where two independent implementations (a scalar path refined with Brent's
method and the vectorised batch path) gave these figures and agreed with each other to 1e-6
and with python-control's margins of the Padé-10 model to 1e-7. The merged engine must keep
them: 1e-6 relative is the merge's requirement; the refinement tolerances (1e-12 for roots,
~1e-9 in frequency for maxima) leave a wide margin.
"""

import pytest

from cas_freq.analysis import analyze
from cas_freq.config import load_variant

PREVIOUS = {
    "base": {
        "current_loop.crossover_rad_s": 8716.881917,
        "current_loop.phase_margin_deg": 63.41077909,
        "current_loop.delay_margin_s": 0.0001269636192,
        "current_loop.gain_margin_db": 9.684527152,
        "current_loop.phase_crossover_rad_s": 26487.0074,
        "current_loop.sensitivity_peak_db": 4.125486801,
        "current_loop.disk_margin_alpha": 0.8723004815,
        "position_loop.crossover_rad_s": 698.5669105,
        "position_loop.phase_margin_deg": 34.71552027,
        "position_loop.delay_margin_s": 0.0008673473093,
        "position_loop.gain_margin_db": 8.349250908,
        "position_loop.phase_crossover_rad_s": 1466.463001,
        "position_loop.gain_margin_low_db": -36.9528603,
        "position_loop.sensitivity_peak_db": 6.71659796,
        "position_loop.disk_margin_alpha": 0.551174459,
        "closed_loop.bandwidth_rad_s": 1385.340866,
        "closed_loop.peak_db": 4.564073254,
        "closed_loop.peak_rad_s": 755.1165273,
        "closed_loop.phase_90_rad_s": 792.2614804,
    },
    "fitted": {
        "current_loop.crossover_rad_s": 8606.735998,
        "current_loop.phase_margin_deg": 63.39031609,
        "current_loop.delay_margin_s": 0.0001285469579,
        "current_loop.gain_margin_db": 9.697813027,
        "current_loop.phase_crossover_rad_s": 26481.48898,
        "current_loop.sensitivity_peak_db": 4.114236091,
        "current_loop.disk_margin_alpha": 0.8741494446,
        "position_loop.crossover_rad_s": 428.9857006,
        "position_loop.phase_margin_deg": 43.34620836,
        "position_loop.delay_margin_s": 0.001763541426,
        "position_loop.gain_margin_db": 13.18371714,
        "position_loop.phase_crossover_rad_s": 1452.209206,
        "position_loop.gain_margin_low_db": -31.3941506,
        "position_loop.sensitivity_peak_db": 4.143807693,
        "position_loop.disk_margin_alpha": 0.7794301071,
        "closed_loop.bandwidth_rad_s": 843.5104535,
        "closed_loop.peak_db": 3.15264342,
        "closed_loop.peak_rad_s": 308.6274737,
        "closed_loop.phase_90_rad_s": 542.121366,
    },
    "relaxed": {
        "current_loop.crossover_rad_s": 8716.881917,
        "current_loop.phase_margin_deg": 63.41077909,
        "current_loop.delay_margin_s": 0.0001269636192,
        "current_loop.gain_margin_db": 9.684527152,
        "current_loop.phase_crossover_rad_s": 26487.0074,
        "current_loop.sensitivity_peak_db": 4.125486801,
        "current_loop.disk_margin_alpha": 0.8723004815,
        "position_loop.crossover_rad_s": 450.5134748,
        "position_loop.phase_margin_deg": 43.18557183,
        "position_loop.delay_margin_s": 0.001673047445,
        "position_loop.gain_margin_db": 12.7862259,
        "position_loop.phase_crossover_rad_s": 1466.463002,
        "position_loop.gain_margin_low_db": -32.51589561,
        "position_loop.sensitivity_peak_db": 4.279839834,
        "position_loop.disk_margin_alpha": 0.76933795,
        "closed_loop.bandwidth_rad_s": 891.0528661,
        "closed_loop.peak_db": 3.092661869,
        "closed_loop.peak_rad_s": 330.7914407,
        "closed_loop.phase_90_rad_s": 565.9022729,
    },
}


def _figure(data, dotted):
    loop, name = dotted.split(".", 1)
    return data[loop][name]


@pytest.mark.parametrize("variant", sorted(PREVIOUS))
def test_figures_unchanged_by_the_engine_merge(variant):
    data = analyze(load_variant(None, variant)).to_dict()
    for dotted, expected in PREVIOUS[variant].items():
        assert _figure(data, dotted) == pytest.approx(expected, rel=1e-6), dotted
    assert data["stable"] is True
