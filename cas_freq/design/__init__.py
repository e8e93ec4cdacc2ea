"""``cas-freq design``: a local interactive design page (:mod:`cas_freq.design.server`) over
the existing engine (:mod:`cas_freq.design.compute`)."""
