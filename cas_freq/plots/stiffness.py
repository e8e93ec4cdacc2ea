"""The report's dynamic-stiffness figure (docs/model.md §15, "Dynamic stiffness").

1/|δ/M(jω)| of the output (1/|x/F(jω)| at a linear output) with every loop closed on the
variant's frequency-response grid, the minimum analyze found marked, the config's load spring
(when it has one) drawn as a line for comparison. With sampled controllers the curve is the
continuous loops' (the title says so).
"""

import numpy as np

from cas_freq.config.wording import OutputWords
from cas_freq.core.output import output_unit
from cas_freq.core.parameters import LoopParameters
from cas_freq.model.disturbance import load_response
from cas_freq.model.loops import Selector
from cas_freq.plots.common import EXACT, Margins, plain_log_labels
from cas_freq.plots.common import figure as _figure
from cas_freq.plots.common import rounded as _r


def caption(data):
    """The figure's caption: ``Dynamic stiffness 1/|δ/M_load| of the output ...``."""
    words = OutputWords.of(data.loaded.params)
    return (f"Dynamic stiffness {words.compliance_symbol} of the {words.label} with every loop "
            "closed, its minimum marked")


def stiffness(data):
    """1/|δ/M(jω)| [N·m/rad, N/m at a linear output] against frequency, the minimum marked."""
    params = LoopParameters.from_config(data.loaded.params)
    p = Selector(params)()
    omega = data.curves.omega_rad_s
    values = 1.0 / np.abs(load_response(p, 1j * omega))
    unit = output_unit(data.loaded.params)
    shown = "N/m" if unit.linear else "N·m/rad"
    w = _r(omega)
    fig, axes = _figure(1, 1, (8, 4.2), margins=Margins())
    ax = axes[0, 0]
    ax.plot(w, _r(values), color="C0", label=OutputWords.of(data.loaded.params).compliance_symbol)
    found = data.analysis.stiffness
    if found is not None and found.minimum is not None \
            and omega[0] <= found.min_at_rad_s <= omega[-1]:
        ax.plot(_r([found.min_at_rad_s]), _r([found.minimum]), "v", color="C3",
                label=f"minimum {found.minimum:.4g} {shown} @ {found.min_at_rad_s:.4g} rad/s")
    spring = float(np.asarray(params.K_h).reshape(-1)[0])
    if spring > 0:
        ax.axhline(spring, color="k", ls="--", lw=0.9,
                   label=f"load spring {unit.spring} = {spring:.4g} {shown}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(w[0], w[-1])
    low = float(_r([np.min(values)])[0])
    bottom = min(low, spring) if spring > 0 else low
    ax.set_ylim(bottom / 3.0, min(float(_r([np.max(values)])[0]), low * 1e4))
    plain_log_labels(ax.xaxis)
    ax.set_xlabel("frequency ω [rad/s]")
    ax.set_ylabel(f"dynamic stiffness [{shown}]")
    ax.legend(loc="upper left")
    ax.grid(True, which="both", lw=0.3)
    continuous = (", continuous loops (the controllers are sampled)"
                  if getattr(params, "sample_rates", ()) else "")
    fig.suptitle(f"{data.label}: dynamic stiffness of the output ({EXACT}{continuous})")
    return fig
