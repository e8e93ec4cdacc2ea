"""Batch analysis of many actuator variants at once: sweeps and tolerance Monte Carlo.

- :func:`cas_freq.parameters.variant_parameters`: arrays of loop parameters from a base config
  and changed dotted keys;
- :mod:`~cas_freq.batch.responses`: exact-delay responses of many variants;
- :mod:`~cas_freq.batch.roots`: vectorised root and maximum refinement;
- :mod:`~cas_freq.batch.margins`: margins and closed-loop figures of a batch;
- :mod:`~cas_freq.batch.stability`: batched Padé characteristic polynomials and verdicts;
- :mod:`~cas_freq.batch.analyze`: :func:`batch_analyze`, chunked;
- :mod:`~cas_freq.batch.steps`: nonlinear steps of a batch with their figures;
- :mod:`~cas_freq.batch.sweep` and :mod:`~cas_freq.batch.montecarlo`: the commands' data;
- :mod:`~cas_freq.batch.plots` (the only module that imports matplotlib, inside its functions)
  and :mod:`~cas_freq.batch.report`: report directories.

Nothing here imports python-control.
"""
