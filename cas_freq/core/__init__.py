"""The lowest layer: the parameter and figure tables, the output's units, the
closed-form formulas, safe file input and atomic output, number formatting, numba's
cached ``njit``; nothing here imports the rest of cas_freq."""
