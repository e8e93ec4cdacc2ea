"""Drawing a report's figures: in forked worker processes while the caller computes the next
variant (:class:`FigureRenderer`), or in this process (:func:`render_figures`).

The workers' life (signals, ending with this process) is :mod:`cas_freq.report.workers`'.
"""

import sys

from cas_freq.core.threads import result_of
from cas_freq.report.data import SINEDWELL_FIGURES, not_computed
from cas_freq.report.workers import fork_pool, stop_pool

#: Worker processes that draw a report's figures (while the next variant is computed); 1 draws
#: them in the calling process. Two: matplotlib draws on one core, and the project's machine has
#: two.
FIGURE_WORKERS = 2


def render_figures(data, stems, png=False):
    """Draw figures of one variant.

    Parameters
    ----------
    data : cas_freq.report.data.VariantData
    stems : sequence of str
        Keys of :data:`cas_freq.plots.report.VARIANT_FIGURES`.
    png : bool
        Also write each figure as PNG.

    Returns
    -------
    list of (str, str, bytes or None, str)
        (stem, SVG text, PNG bytes or None, caption) of each stem, in order.
    """
    from cas_freq.plots import report as plots

    skipped = SINEDWELL_FIGURES if "sinedwell" in not_computed(data) else ()
    drawn = []
    for stem in stems:
        if stem in skipped:  # not drawn: its data were not computed (_figure_files says why)
            continue
        draw, caption = plots.VARIANT_FIGURES[stem]
        fig = draw(data)
        drawn.append((stem, plots.svg_text(fig), plots.png_bytes(fig) if png else None,
                      caption(data) if callable(caption) else caption))
    return drawn


def _figure_stems():
    """The stems of a variant's figures, in order (imports matplotlib)."""
    from cas_freq.plots.report import VARIANT_FIGURES

    return list(VARIANT_FIGURES)


#: Which of a variant's figures :meth:`FigureRenderer.submit` draws.
PARTS = ("all", "frequency", "time")


def _render_share(data, share, shares, png, part):
    """Figures ``share``, ``share + shares``, ... of one variant among those of ``part``:
    every figure, those of :data:`~cas_freq.plots.report.FREQUENCY_FIGURES` or the others."""
    from cas_freq.plots.report import FREQUENCY_FIGURES

    stems = [stem for stem in _figure_stems()
             if part == "all" or (stem in FREQUENCY_FIGURES) == (part == "frequency")]
    return render_figures(data, stems[share::shares], png)


class _Later:
    """A drawing done when its result is asked for (:meth:`FigureRenderer.draw` without
    workers)."""

    def __init__(self, function, args):
        self.function, self.args = function, args

    def done(self):
        """True: nothing to wait for (the drawing runs in :meth:`result`, in this thread)."""
        return True

    def result(self):
        return self.function(*self.args)


class FigureRenderer:
    """Draws each variant's figures while the caller computes: in ``workers`` processes, or in
    this process (at :meth:`results`) when ``workers`` is 1 or no process can be forked.

    The workers are forked (on Linux; elsewhere the figures are drawn here) on entry, after
    this process has imported the figure code (once, not once per worker) and before it
    computes anything; they never import python-control, and they end with this process
    (:mod:`cas_freq.report.workers`): killed at once when the block ends with an exception
    (an interrupt included), and by the kernel when this process dies. A variant can be sent
    twice: after :func:`~cas_freq.report.data.gather_frequency` for the figures of the
    frequency responses (``part="frequency"``), then complete for the others (``"time"``); or
    once (``"all"``). Each submission is split into ``workers`` shares (alternate stems), one
    task each, and the data are pickled to the task (the complete data ~10 MB, ~20 ms).
    :meth:`results` gathers the figures in the order of
    :data:`~cas_freq.plots.report.VARIANT_FIGURES`, so the output does not depend on which
    process drew what (the SVG text of a figure is the same in any process). Use as a context
    manager.
    """

    def __init__(self, workers=FIGURE_WORKERS, png=False):
        self.png = png
        self.workers = max(1, int(workers))
        self._pool = None
        self._stems = None  # future of the stems' order, from a worker
        self._variants = []  # per variant: [latest data, futures]

    def __enter__(self):
        # fork only on Linux: macOS's system libraries are not fork-safe (Python spawns there)
        if self.workers > 1 and sys.platform.startswith("linux"):
            # the figure code is imported once, before the fork, not by each worker (~0.6 s);
            # python-control (~0.7 s) only here, after the fork, while the workers draw: it
            # is needed for the linear steps and the zeros of T, which are computed here
            import cas_freq.plots.report  # noqa: F401

            try:
                # start the workers now: they import the figure code while the caller computes
                self._pool, stems = fork_pool(self.workers, _figure_stems)
                self._stems = stems[0]
            except OSError:
                self._pool = None
        return self

    def __exit__(self, exc_type, *exc):
        if self._pool is not None:
            # interrupted (Ctrl-C, SIGTERM) or failed: the workers are killed, not waited for
            stop_pool(self._pool, kill=exc_type is not None)
        return False

    def submit(self, index, data, part="all"):
        """Start drawing the figures of ``part`` (one of :data:`PARTS`) of variant ``index``
        (0, 1, ... in the report's order) from ``data``."""
        if part not in PARTS:
            raise ValueError(f"part: one of {PARTS}, got {part!r}")
        if index == len(self._variants):
            self._variants.append([data, []])
        self._variants[index][0] = data
        if self._pool is not None:
            self._variants[index][1] += [
                self._pool.submit(_render_share, data, share, self.workers, self.png, part)
                for share in range(self.workers)]

    @property
    def parallel(self):
        """True when worker processes draw (else everything is done in this process)."""
        return self._pool is not None

    def draw(self, function, *args):
        """Start ``function(*args)`` (a module-level drawing function) in a worker; returns an
        object whose ``result()`` is its value (computed then, in this process, without
        workers)."""
        if self._pool is not None:
            return self._pool.submit(function, *args)
        return _Later(function, args)

    def results(self):
        """Per variant, {stem: (SVG text, PNG bytes or None, caption)} in figure order."""
        stems = _figure_stems() if self._pool is None else result_of(self._stems)
        rendered = []
        for data, futures in self._variants:
            if self._pool is None:
                drawn = render_figures(data, stems, self.png)
            else:
                drawn = [item for future in futures for item in result_of(future)]
            by_stem = {stem: rest for stem, *rest in drawn}
            rendered.append({stem: tuple(by_stem[stem]) for stem in stems if stem in by_stem})
        return rendered
