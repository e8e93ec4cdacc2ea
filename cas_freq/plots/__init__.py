"""Figures drawn with matplotlib: the only package of cas_freq that imports it.

Each module imports matplotlib itself, so importing this package imports nothing:

- :mod:`cas_freq.api.figures`: the figures of the Python API's ``plot()`` methods;
- :mod:`cas_freq.plots.report`: the design-review report's figures;
- :mod:`cas_freq.plots.loci`: its Nyquist plots and closed-loop pole-zero map;
- :mod:`cas_freq.plots.common`: the fixed style and layout and the deterministic SVG/PNG writer
  they share;
- :mod:`cas_freq.plots.studies`: the sweep and Monte Carlo figures.

Plotting takes computed data and returns a :class:`matplotlib.figure.Figure`; it computes no
figure of merit.
"""
