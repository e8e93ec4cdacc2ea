"""
# The QT-CAS loops

Analyze the shipped QT-CAS actuator and draw the Bode of its loops.
"""

import cas_freq as cf

act = cf.load()
res = act.analyze()
print(res)
fig = res.plot()
