"""The Sequence Planner: partition measurements into groups and order each group.

Modules: ``tour`` (ordering: :func:`ita.sequence.tour.solve_tour`), ``lkh`` (the
default ordering: LKH, bounded by work), ``fasttsp`` (the fast-tsp library), ``construct`` and ``localsearch`` (the classic
ordering's building blocks), ``tsplib`` (TSPLIB files, to check the ordering against
published optima).
"""
