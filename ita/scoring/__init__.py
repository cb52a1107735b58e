"""Scoring a simulated run against the as-built part the simulator made.

:mod:`~ita.scoring.truth` (the true values, from the as-built truth or the mesh the
simulator held; the faults injected), :mod:`~ita.scoring.compare` (results against true
values), :mod:`~ita.scoring.diagnoses` (diagnoses against the injected faults).  Only
this package (and the simulator) may read the as-built truth; the report receives true
values from here as a plain mapping and never reads them itself.
"""
