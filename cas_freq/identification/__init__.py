"""Identification from bench recordings (``cas-freq fit``): read step recordings
(:mod:`~cas_freq.identification.recordings`, column names and units in
:mod:`~cas_freq.identification.columns`) and fit the report's second-order-plus-delay model to
one or several of them (:mod:`~cas_freq.identification.step_fit`); read sweep recordings
(:mod:`~cas_freq.identification.sweep`) and estimate their frequency responses with coherence
(:mod:`~cas_freq.identification.frf`).
"""

from cas_freq.identification.recordings import Recording, read_recording
from cas_freq.identification.step_fit import RecordingFits, RunFit, fit_recordings

__all__ = ["Recording", "RecordingFits", "RunFit", "fit_recordings", "read_recording"]
