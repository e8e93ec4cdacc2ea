"""Results in a notebook: short reprs and HTML tables of headline figures, figures that display
themselves without ``%matplotlib``, ``Analysis.plot()``, and ``to_control()`` systems that
python-control's own ``stability_margins`` and ``step_info`` handle.

The executed notebook (docs/notebooks/first_steps.ipynb, run by nbclient in a fresh IPython
kernel: ~10 s wall, 4 s CPU with numba's cache warm) is the check of issue 28: an ``image/png``
output from ``.plot()`` with no magic.
"""

import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import cas_freq as cf

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "docs" / "notebooks" / "first_steps.ipynb"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def act():
    return cf.load()


@pytest.fixture(scope="module")
def analysis(act):
    return act.analyze()


def test_analysis_repr_is_a_few_lines_of_headline_figures(analysis):
    # Before: the dataclass repr printed every field (poles, every crossover): ~3,000 chars.
    text = repr(analysis)
    assert len(text.splitlines()) <= 8 and len(text) < 600
    assert text.startswith("Analysis: qt_cas / base (exact delays)")
    pm = analysis.position_loop.phase_margin_deg
    assert f"position loop: phase margin: {pm:.4g} deg" in text


def test_analysis_html_is_a_table_with_units(analysis):
    table = analysis._repr_html_()
    assert table.startswith("<table>") and table.endswith("</table>")
    bandwidth = analysis.closed_loop.bandwidth_rad_s
    # the bandwidth's row: label and unit from cas_freq.core.figures.FIGURES
    assert (f"bandwidth ω_BW (−3.01 dB)</td><td style='text-align:right'>{bandwidth:.4g}</td>"
            "<td style='text-align:left'>rad/s</td>") in table


def test_delay_margin_row_is_shown_in_its_display_unit(analysis):
    # FIGURES gives the delay margin in s with display unit ms (scale 1e3)
    table = analysis._repr_html_()
    assert f"{analysis.position_loop.delay_margin_s * 1e3:.4g}</td>" in table
    assert "delay margin" in table


def test_set_analysis_repr_gives_ranges_not_arrays(act):
    batch = act.vary({"position_loop.Kp": np.linspace(2.0, 12.0, 200)}).analyze()
    text = repr(batch)
    # a SimpleNamespace repr printed all 200 values of each of ~40 arrays
    assert len(text) < 700 and "array" not in text
    assert "stable: 200 of 200" in text
    pm = batch.position_loop.phase_margin_deg
    assert f"position loop: phase margin: {pm.min():.4g} .. {pm.max():.4g} deg" in text


def test_analysis_plot_draws_l_i_l_p_and_t_with_margins(analysis):
    fig = analysis.plot()
    magnitude, phase = fig.axes[:2]
    labels = [line.get_label() for line in magnitude.get_lines()]
    assert any(label.startswith("L_i") for label in labels)
    assert any(label.startswith("L_p") and "PM" in label for label in labels)
    assert any(label.startswith("T = δ/δ_cmd") and "ω_BW" in label for label in labels)
    # the headline phase margin's bar on the phase axes: a vertical segment of PM degrees
    pm = analysis.position_loop.phase_margin_deg
    heights = [abs(seg[1, 1] - seg[0, 1]) for c in phase.collections for seg in c.get_segments()]
    assert min(abs(h - pm) for h in heights) < 1e-9


def test_plot_figures_give_ipython_a_png_themselves(act, analysis):
    # Without %matplotlib no IPython formatter knows matplotlib's Figure: the figure's own
    # _repr_png_ is what shows (before: <Figure size 800x600 with 2 Axes>).
    figures = [analysis.plot(), act.frequency_response(np.geomspace(1.0, 1e4, 50)).plot()]
    for fig in figures:
        assert fig._repr_png_().startswith(PNG_SIGNATURE)


def test_plot_does_not_switch_the_matplotlib_backend():
    # plots/common used to call matplotlib.use("Agg") on import: in a notebook that turned the
    # inline backend off for the user's own pyplot figures. A fresh process (the modules are
    # imported once per process), a backend other than Agg chosen first.
    code = ("import matplotlib; matplotlib.use('svg'); "
            "import cas_freq.api.figures, cas_freq.plots.report; "
            "print(matplotlib.rcParams['backend'])")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    env.pop("MPLBACKEND", None)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, check=True, cwd=ROOT)
    assert out.stdout.strip() == "svg"


def test_to_control_systems_are_named(act):
    systems = act.to_control()
    names = {key: (getattr(systems, key).name, getattr(systems, key).input_labels,
                   getattr(systems, key).output_labels)
             for key in ("current_loop", "position_loop", "closed_loop")}
    assert names == {"current_loop": ("L_i", ["e_i"], ["i"]),
                     "position_loop": ("L_p", ["e"], ["theta"]),
                     "closed_loop": ("T", ["delta_cmd"], ["delta"])}


#: Every shipped variant (config, variant) of every shipped architecture: the PID-on-PI
#: (QT-CAS, DC servo), the ball screw's linear output and the P-PI-PI cascade with filters.
SHIPPED = [("configs/qt_cas.yaml", v) for v in ("base", "fitted", "relaxed", "loaded",
                                                 "fin_encoder", "sampled")] + [
    ("configs/dc_servo.yaml", "base"), ("configs/ball_screw.yaml", "base"),
    ("configs/cascade_axis.yaml", "base")]


@pytest.mark.parametrize(("config", "variant"), SHIPPED)
def test_to_control_default_works_with_python_controls_margins_and_step_info(config, variant):
    # Before: the default Padé order 6 made stability_margins raise LinAlgError on the loaded
    # variant (its polynomials of degree ~20 overflow), and order 4 on the cascade axis (25
    # states, coefficients to 1e90): the default order is now the highest <= 4 that stays below
    # the overflow, 3 on the cascade axis.
    import control

    from cas_freq.report.data import linear_steps
    from cas_freq.simulation.step_figures import step_figures

    act = cf.load(ROOT / config, variant=variant)
    analysis = act.analyze()
    systems = act.to_control()
    with warnings.catch_warnings():
        # python-control's root test of the polynomials may still overflow on the way
        # (numpy RuntimeWarning, fitted and loaded variants); the margins it returns are right
        warnings.simplefilter("ignore", RuntimeWarning)
        for loop in ("current_loop", "velocity_loop", "position_loop"):
            exact = getattr(analysis, loop, None)
            system = getattr(systems, loop)
            if system is None:
                continue
            if system.isdtime(strict=True):
                # sampled: the systems are exact (no Padé); python-control's margins of a
                # discrete system interpolate its frequency response (0.24 deg off here), so
                # its response is read at cas_freq's crossover instead: |L| = 1 and the phase
                # -180 deg + PM, to 1e-9
                value = system(np.exp(1j * exact.crossover_rad_s * system.dt))
                assert abs(value) == pytest.approx(1.0, abs=1e-9)
                assert np.degrees(np.angle(-value)) == pytest.approx(exact.phase_margin_deg,
                                                                     abs=1e-7)
                continue
            _, pm, _, _, wgc, _ = control.stability_margins(system)
            # Padé-4 against the exact delays: the delays' phase at crossover (< 0.2 rad) is
            # matched by the (4,4) Padé to ~1e-10 rad, so PM and ωc agree to 1e-6 relative
            assert pm == pytest.approx(exact.phase_margin_deg, rel=1e-6)
            assert wgc == pytest.approx(exact.crossover_rad_s, rel=1e-6)
        info = control.step_info(systems.closed_loop)
        if not systems.closed_loop.isdtime(strict=True):
            # python-control's bandwidth at cas_freq's -3.0103 dB: T's Padé model against the
            # exact delays, whose phase error does not move |T| at ω_BW beyond ~1e-9 (1e-6)
            bandwidth = control.bandwidth(systems.closed_loop, dbdrop=-20 * np.log10(np.sqrt(2)))
            assert bandwidth == pytest.approx(analysis.closed_loop.bandwidth_rad_s, rel=1e-6)
    # step_info measures from T's DC gain (0.99933 with the loaded variant's hinge spring):
    # the same as cas_freq's |T(0)| (taken 1000x below the grid, so to ~1e-4 dB)
    final = info["SteadyStateValue"]
    assert 20.0 * np.log10(final) == pytest.approx(analysis.closed_loop.dc_gain_db, abs=1e-4)
    if systems.closed_loop.isdtime(strict=True):
        # sampled: the report's linear step is T's output samples (each held until the next):
        # at the sample instants it is python-control's step response of the same discrete T
        period = systems.closed_loop.dt
        response = control.step_response(systems.closed_loop, T=np.arange(400) * period)
        t = np.arange(0.0, 400 * period - 1e-12, 1e-5)
        ours = linear_steps(act.params, [t], [1.0], 4)[0]
        held = response.outputs[np.floor(t / period + 1e-9).astype(int)]
        np.testing.assert_allclose(ours, held, rtol=1e-10, atol=1e-12)
        return
    # cas_freq's linear step of the same Padé model (the report's), on a 10 µs grid, measured
    # from that final value: the overshoot is a value of y, the same to the grid's resolution
    # of the peak (1e-4 relative); the rise time is two interpolated crossings, to a grid step
    # (10 µs of ~1-5 ms: 2 %)
    t = np.arange(0.0, 0.3, 1e-5)
    figures = step_figures(t, linear_steps(act.params, [t], [1.0], 4)[0], 1.0,
                           final_value=final)
    assert info["Overshoot"] == pytest.approx(figures.overshoot_pct, rel=1e-4)
    assert info["RiseTime"] == pytest.approx(figures.rise_time_s, rel=2e-2)


def _executed(monkeypatch, tmp_path):
    """The notebook executed in a fresh kernel of this Python (jupyter_client runs a kernel
    spec's ``python`` as ``sys.executable``), from the repository root; the kernel's connection
    files, IPython's profile and history and matplotlib's cache go to ``tmp_path``, not the
    user's home (tests change nothing on the machine)."""
    import nbclient  # the test extra installs nbclient, nbformat and ipykernel
    import nbformat
    # the kernel imports this worktree's cas_freq (CI installs it editable as well)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    for name, folder in (("JUPYTER_RUNTIME_DIR", "runtime"), ("JUPYTER_DATA_DIR", "data"),
                         ("IPYTHONDIR", "ipython"), ("MPLCONFIGDIR", "matplotlib")):
        monkeypatch.setenv(name, str(tmp_path / folder))
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(notebook, timeout=600, kernel_name="python3",
                                     resources={"metadata": {"path": str(ROOT)}})
    client.execute()
    return notebook


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_first_steps_notebook_shows_the_table_and_the_plot_without_magics(monkeypatch,
                                                                         tmp_path):
    notebook = _executed(monkeypatch, tmp_path)
    code = "\n".join(cell.source for cell in notebook.cells if cell.cell_type == "code")
    assert "%matplotlib" not in code and "matplotlib" not in code
    cells = {cell.source.strip().splitlines()[-1]: cell for cell in notebook.cells
             if cell.cell_type == "code"}
    shown = {line: [kind for output in cell.outputs for kind in output.get("data", {})]
             for line, cell in cells.items()}
    assert "text/html" in shown["result"]
    assert "image/png" in shown["result.plot()"]
    png = cells["result.plot()"].outputs[0]["data"]["image/png"]
    assert len(png) > 10_000  # base64 of a drawn figure, not an empty canvas
    printed = "".join(output.get("text", "") for output in cells[
        'print(systems.position_loop.name, f"PM {pm:.2f} deg at {wgc:.1f} rad/s")'].outputs)
    assert printed.startswith("L_p PM ")


def test_to_control_default_order_stays_in_python_controls_reach():
    # The cascade axis at Padé 4: L_p's characteristic polynomial reaches 1e90 (25 states),
    # past the ~1e76 at which python-control's stability_margins overflows (tested above for
    # the default); the default order is 3 there, 4 on the QT-CAS. An order asked for is built
    # as asked, with a warning saying why python-control's margins would fail on it.
    from cas_freq.core.exceptions import CasFreqError

    cascade = cf.load(ROOT / "configs/cascade_axis.yaml")
    assert cascade.to_control().pade_order == 3
    assert cf.load(ROOT / "configs/qt_cas.yaml", variant="loaded").to_control().pade_order == 4
    with pytest.warns(UserWarning, match="pade: at order 4 the position loop's characteristic "
                                         "polynomial reaches 1e90"):
        assert cascade.to_control(pade=4).position_loop.nstates == 25
    with pytest.raises(CasFreqError, match=r"pade: 0 is not accepted; accepted: an integer"):
        cascade.to_control(pade=0)
