"""Monte Carlo (and sweep) progress counts whole samples (issue 24).

A study's figures are computed in stages (the batch analysis, then the nonlinear steps, then
the sine dwell), and its progress is the work done, each stage weighted by its rough cost, in
samples' worth. It used to be passed on as a fraction of a sample, so the display read
"23.2727 of 300 samples"; it is now a whole number of samples, non-decreasing, ending at the
sample count.
"""

import io
import math
import re

from cas_freq.cli.common import _PeriodicProgress, _Progress
from cas_freq.config import load_variant
from cas_freq.core.tolerances import parse_tolerance
from cas_freq.studies.montecarlo import run_montecarlo

SAMPLES = 11  # not a divisor of the stages' weights, so a fraction would show


def _calls():
    """The (done, total) calls of a Monte Carlo of SAMPLES samples with a 10 deg step."""
    calls = []
    run_montecarlo(load_variant(None, "base"), [parse_tolerance("motor.Km=5%")], SAMPLES,
                   seed=1, step_rad=math.radians(10),
                   progress=lambda done, total: calls.append((done, total)))
    return calls


def test_progress_is_whole_samples_up_to_the_count():
    calls = _calls()
    assert len(calls) >= 3  # the analysis and the steps both reported
    for done, total in calls:
        assert isinstance(done, int) and isinstance(total, int), (done, total)
        assert total == SAMPLES and 0 <= done <= SAMPLES
    counts = [done for done, _ in calls]
    assert counts == sorted(counts) and counts[-1] == SAMPLES


def test_the_displays_show_whole_samples():
    """What the bar (on a terminal) and the periodic line (a log) print of those calls."""
    calls = _calls()
    stream = io.StringIO()
    bar = _Progress("montecarlo base", stream, "sample")
    for done, total in calls:
        bar(done, total)
    bar.done()
    counts = re.findall(r"([0-9.]+)/([0-9.]+)", stream.getvalue())
    assert counts and all("." not in a + b for a, b in counts), stream.getvalue()
    stream = io.StringIO()
    line = _PeriodicProgress("montecarlo base", stream, "sample", interval_s=0.0)
    for done, total in calls:
        line(done, total)
    text = stream.getvalue()
    assert re.findall(r": (\S+) of 11 samples", text) == [str(done) for done, _ in calls], text
