"""ApexNav's open asymmetric TSP over the high-value frontiers (``exploration_manager.cpp``
``computeATSPCostMatrix``, ``computeATSPTour``), solved by OR-Tools (Apache 2.0) with deterministic limits.

Node 0 is the robot, nodes ``1..n`` the frontiers. ``M(0, i)`` is the path length from the robot to frontier
``i``, ``M(i, 0) = 0`` (the tour need not come back, so the cheapest closed tour is the cheapest open path from the
robot), ``M(i, j) = M(j, i)`` the path length between two frontiers, the diagonal ``tsp_diagonal`` and a pair
without a path ``tsp_unreachable``; costs go to the solver in units of ``1 / tsp_scale`` metres as integers.

ApexNav hands the matrix to LKH-3 (research use only) under a wall-clock budget, so its tours, and so its episodes,
depend on the CPU. Here OR-Tools' routing solver builds a first tour by the cheapest arc from the robot and improves
it by guided local search until it has found ``tsp_solutions`` solutions: a count, never a time. Its neighbourhoods
that are bounded by time (the large-neighbourhood searches, ``lns_time_limit``) are switched off, and the solver is
single-threaded, so one matrix gives one tour on every machine.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from drivenav.errors import InputError

try:
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2, routing_parameters_pb2
    from ortools.util import optional_boolean_pb2
except ImportError:  # the apexnav extra is not installed: one line naming it, before any episode
    raise InputError(  # explorer.name: what --agent apexnav, --set explorer.name=apexnav and --methods all set
        "settings",
        "explorer.name",
        "the apexnav extra for ApexNav's TSP solver (pip install 'drivenav[apexnav]', which brings OR-Tools)",
        "apexnav with ortools not installed",
    ) from None

_TIME_BOUNDED = (
    "use_path_lns",
    "use_full_path_lns",
    "use_tsp_lns",
    "use_inactive_lns",
    "use_global_cheapest_insertion_path_lns",
    "use_local_cheapest_insertion_path_lns",
    "use_global_cheapest_insertion_expensive_chain_lns",
    "use_local_cheapest_insertion_expensive_chain_lns",
    "use_global_cheapest_insertion_close_nodes_lns",
    "use_local_cheapest_insertion_close_nodes_lns",
)
"""The routing solver's neighbourhoods searched under ``lns_time_limit`` (a wall-clock limit): all off."""


def cost_matrix(
    from_robot: NDArray[np.float64],
    between: NDArray[np.float64],
    unreachable: float,
    diagonal: float,
) -> NDArray[np.float64]:
    """ApexNav's ``(n + 1) x (n + 1)`` matrix (module docstring) from the robot-to-frontier lengths ``(n,)`` and the
    frontier-to-frontier lengths ``(n, n)`` (only ``i < j`` read; mirrored); non-finite lengths cost
    ``unreachable``."""
    n = len(from_robot)
    matrix = np.zeros((n + 1, n + 1))
    matrix[0, 1:] = from_robot
    upper = np.triu(np.asarray(between, dtype=np.float64), 1)
    matrix[1:, 1:] = upper + upper.T
    matrix[~np.isfinite(matrix)] = unreachable
    np.fill_diagonal(matrix, diagonal)
    return matrix


def open_tour(matrix: NDArray[np.float64], scale: float, solutions: int) -> list[int]:
    """The nodes ``1..n`` in the order of the cheapest tour from node 0 the solver finds (module docstring). With
    one or two frontiers no solver is needed: the matrix is symmetric between frontiers, so the tour that starts at
    the nearer one is the cheaper (the first of equals)."""
    n = matrix.shape[0]
    if n <= 3:
        return [int(k) + 1 for k in np.argsort(matrix[0, 1:], kind="stable")]
    costs = np.rint(matrix * scale).astype(np.int64)
    manager = pywrapcp.RoutingIndexManager(n, 1, 0)
    routing = pywrapcp.RoutingModel(manager)
    routing.SetArcCostEvaluatorOfAllVehicles(routing.RegisterTransitMatrix(costs.tolist()))
    solution = routing.SolveWithParameters(_parameters(solutions))
    if solution is None:  # cannot happen for a complete graph; the robot's nearest-first order stands in
        return [int(k) + 1 for k in np.argsort(matrix[0, 1:], kind="stable")]
    order, index = [], routing.Start(0)
    while not routing.IsEnd(index):
        index = solution.Value(routing.NextVar(index))
        node = manager.IndexToNode(index)
        if node != 0:
            order.append(int(node))
    return order


def _parameters(solutions: int) -> routing_parameters_pb2.RoutingSearchParameters:
    """Cheapest-arc first tour, guided local search stopped by a solution count, no time-bounded search."""
    parameters = pywrapcp.DefaultRoutingSearchParameters()
    parameters.first_solution_strategy = routing_enums_pb2.FirstSolutionStrategy.PATH_CHEAPEST_ARC
    parameters.local_search_metaheuristic = routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH
    parameters.solution_limit = solutions
    operators = parameters.local_search_operators
    for name in _TIME_BOUNDED:
        setattr(operators, name, optional_boolean_pb2.BOOL_FALSE)
    return parameters
