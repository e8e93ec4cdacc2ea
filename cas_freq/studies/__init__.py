"""Studies over many variants: parameter sweeps, tolerance Monte Carlo and batched steps.

- :mod:`~cas_freq.studies.sweep`: every figure on a grid of dotted config keys;
- :mod:`~cas_freq.studies.montecarlo`: figures and requirement yields over drawn tolerances;
- :mod:`~cas_freq.studies.steps`: nonlinear steps of many variants with their figures.

They compute data only: the figures are drawn by :mod:`cas_freq.plots.studies` and the
folders written by :mod:`cas_freq.report.studies`. Nothing here imports python-control or
matplotlib.
"""
