"""Figures drawn with matplotlib for interactive use (each module imports matplotlib itself).

Importing this package imports nothing; :mod:`cas_freq.plots.api` draws the figures of the
Python API's ``plot()`` methods.
"""
