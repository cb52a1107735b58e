"""The Sequence Planner: partition measurements into groups and order each group.

Modules: ``tour`` (ordering: :func:`ita.sequence.tour.solve_tour`), ``construct`` and
``localsearch`` (its building blocks), ``tsplib`` (TSPLIB files, to check the ordering
against published optima).
"""
