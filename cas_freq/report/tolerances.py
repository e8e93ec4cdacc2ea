"""The report's tolerance section (a config with ``tolerances:``): each requirement's nominal
value, its worst case over the tolerance box (:mod:`cas_freq.studies.worstcase`) and its
Monte Carlo yield (:mod:`cas_freq.studies.montecarlo`, uniform on the box) side by side, and
the worst corner's closed loop and step beside the nominal."""

import math

import numpy as np

from cas_freq.core.figures import FIGURES, UNIT_LABELS
from cas_freq.core.numbers import number
from cas_freq.core.output import output_unit
from cas_freq.core.parameters import variant_parameters
from cas_freq.model import ActuatorLoops
from cas_freq.report.document import Figure, Heading, Paragraph, Table
from cas_freq.report.outdir import sanitise_name
from cas_freq.simulation.commands import Step
from cas_freq.simulation.simulator import simulate_batch
from cas_freq.studies.montecarlo import requirement_results, run_montecarlo
from cas_freq.studies.worstcase import point_text, worst_case

#: Monte Carlo samples of the yield column (uniform on the box, seeded).
YIELD_SAMPLES = 200
#: Frequencies of the worst corner's |T| [rad/s].
OMEGA = np.geomspace(1.0, 1e5, 600)


class ToleranceSection:
    """The section's blocks and its results.json entry (empty without ``tolerances:``)."""

    def __init__(self, blocks=(), results=None):
        self.blocks = tuple(blocks)
        self.results = {} if results is None else {"tolerances": results}


def _shown(value, unit=""):
    return "—" if value is None else f"{number(value, 5)}{(' ' + unit) if unit else ''}"


def _worst_point(data):
    """The requirement whose worst case the figure shows: the first that fails there, else
    the first required one, else the first."""
    rows = data["requirements"]
    failing = [r for r in rows if r["worst_fails"] and r["severity"] == "required"]
    required = [r for r in rows if r["severity"] == "required"]
    return (failing or required or rows)[0]


def _draw(loaded, found, row, step_rad, png):
    """(SVG, PNG or None) of the worst point's Bode of T and step beside the nominal."""
    from cas_freq.plots.common import png_bytes, svg_text
    from cas_freq.plots.tolerances import worst_corner_figure

    params = loaded.params
    nominal = {item["key"]: item["nominal"] for item in found["box"]}
    changes = {item["key"]: np.array([nominal[item["key"]], item["value"]])
               for item in row["at"]}
    loops = variant_parameters(params, changes)
    t = [ActuatorLoops(loops.run(k)).closed_loop(1j * OMEGA) for k in range(2)]
    run = simulate_batch(loops, Step(step_rad), signals=("theta",))
    label = f"worst {row['id']}: {point_text(row['at'])}"
    fig = worst_corner_figure(OMEGA, np.ravel(t[0]), np.ravel(t[1]), run.t, run.delta[0],
                              run.delta[1], label, params.output_label, output_unit(params))
    return svg_text(fig), png_bytes(fig) if png else None


def tolerance_section(datas, png=False):
    """Lay out the tolerance section: a generator yielding (path, content) of each variant's
    figure and returning a :class:`ToleranceSection`."""
    params = datas[0].loaded.params
    if not params.tolerances:
        return ToleranceSection()
    tolerances = params.tolerance_list
    keys = ", ".join(f"{t.key} ±{100 * t.relative:g} %" if t.relative is not None
                     else f"{t.key} ±{t.absolute:g}" for t in tolerances)
    blocks = [Heading(2, "Tolerances: nominal, worst case and yield"), Paragraph(
        f"The config's tolerances ({keys}) span a box around each variant. For every "
        "requirement: its nominal value, the worst found over the box (every corner, 256 "
        "uniform samples, then a compass search from the worst corner and sample), the "
        "guaranteed bound over the whole box where one is established (every loop's margins "
        "and sensitivity peak, the bandwidth and the resonance peak of continuous loops, where "
        "stability over the box is proved: interval branch and bound), with the point that "
        "reaches the worst (each key's value and its change from the nominal), and the yield "
        f"of {YIELD_SAMPLES} Monte Carlo samples "
        "uniform on the box (seed 0). `cas-freq worstcase` prints the search.")]
    rows, results = [], []
    for data in datas:
        loaded = data.loaded
        found = worst_case(loaded, tolerances)
        yields = {r["id"]: r for r in requirement_results(
            run_montecarlo(loaded, list(tolerances), YIELD_SAMPLES, distribution="uniform",
                           seed=0))}
        for row in found["requirements"]:
            share = yields.get(row["id"], {})
            rows.append((
                row["id"], loaded.variant, UNIT_LABELS[FIGURES[row["metric"]].unit],
                _shown(row["nominal"]),
                ("not stable" if row["worst_verdict"] != "stable" else _shown(row["worst"]))
                + (" FAILS" if row["worst_fails"] else ""),
                "—" if row.get("bound") is None else
                f"{'≤' if row.get('bound_above') else '≥'} {_shown(row['bound'])}",
                ("a corner: " if row["at_corner"] else "inside: ") + point_text(row["at"]),
                (f"{share['yield_pct']:.1f} %" if share.get("evaluated") else "—"),
            ))
        results.append({"variant": loaded.variant, "worst_case": found,
                        "yield": list(yields.values())})
        shown = _worst_point(found)
        unit = output_unit(params)
        # the search's step (its SI value in degrees, as every typed record keeps it), else
        # the output's example step (10 deg, 5 mm)
        step_rad = (math.radians(found["step_deg"]) if found["step_deg"] is not None
                    else unit.example_step)
        svg, png_data = _draw(loaded, found, shown, step_rad, png)
        stem = f"figures/{sanitise_name(loaded.variant, fallback='variant')}/worst_case"
        yield f"{stem}.svg", svg
        if png:
            yield f"{stem}.png", png_data
        blocks.append(Figure(f"{stem}.svg", f"The worst point of {shown['id']} beside the "
                             f"nominal: T's Bode and the "
                             f"{unit.symbol(math.degrees(step_rad))} step — "
                             f"{params.name} / {loaded.variant}", svg))
    header = ("requirement", "variant", "unit", "nominal", "worst found", "guaranteed", "at",
              "yield")
    blocks.insert(2, Table(header, tuple(rows), "tolerances: nominal, worst case over the box "
                           "and Monte Carlo yield"))
    return ToleranceSection(blocks, results)
