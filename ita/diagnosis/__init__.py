"""The Exception Handler (the seed's thirteenth component): diagnosis of a failed
measurement by tests made in the cell, the world model put right, recovery by plan
repair or replanning.

Knowledge in kb/faults.pl, engine in prolog/diagnosis.pl; here: :mod:`~ita.diagnosis
.classify` (a failure as an exception of the knowledge base), :mod:`~ita.diagnosis
.knowledge` (the bridge calls), :mod:`~ita.diagnosis.tests` (the tests, run in the cell),
:mod:`~ita.diagnosis.counts` (frequencies learned across runs), :mod:`~ita.diagnosis
.handler` (the whole of it).
"""

from ita.diagnosis.counts import FaultCounts, counts_path
from ita.diagnosis.handler import Diagnosis, ExceptionHandler, Handled

__all__ = ["Diagnosis", "ExceptionHandler", "FaultCounts", "Handled", "counts_path"]
