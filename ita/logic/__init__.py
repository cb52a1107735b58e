"""The symbolic side of ITA: the Prolog knowledge bases and the bridge to them.

Import the values from here; the bridge itself (``ita.logic.bridge``, which starts
SWI-Prolog) is imported only by code that queries the knowledge bases.
"""

from ita.logic.model import Diagnostic, PredicateDoc, ProofNode, QueryResult, Severity
from ita.logic.terms import Str, Term, Var

__all__ = [
    "Diagnostic",
    "PredicateDoc",
    "ProofNode",
    "QueryResult",
    "Severity",
    "Str",
    "Term",
    "Var",
]
