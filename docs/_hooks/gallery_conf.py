"""mkdocs-gallery's configuration script (``conf_script`` in mkdocs.yml): the gallery shows the
figures the examples' ``.plot()`` return as well as pyplot's.

cas_freq draws its figures without pyplot (a ``matplotlib.figure.Figure`` that a notebook
shows as a cell's value), so mkdocs-gallery's matplotlib scraper, which saves pyplot's open
figures, does not see them: :func:`returned_figures` saves each other figure an example holds
in a variable, once.
"""

import weakref

_SAVED = weakref.WeakSet()


def returned_figures(block, script, **kwargs):
    """Save the figures held in the example's variables that were not saved yet; their
    Markdown for the gallery page."""
    from matplotlib._pylab_helpers import Gcf
    from matplotlib.figure import Figure
    from mkdocs_gallery.scrapers import figure_md_or_html

    pyplots = {manager.canvas.figure for manager in Gcf.get_all_fig_managers()}
    paths = []
    for value in list(script.run_vars.example_globals.values()):
        if isinstance(value, Figure) and value not in _SAVED and value not in pyplots:
            _SAVED.add(value)
            path = next(script.run_vars.image_path_iterator)
            value.savefig(path)
            paths.append(path)
    return figure_md_or_html(paths, script) if paths else ""


#: Before matplotlib's scraper, which saves and closes pyplot's figures (saved by it alone).
conf = {"image_scrapers": (returned_figures, "matplotlib")}
