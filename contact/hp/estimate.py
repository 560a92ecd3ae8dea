"""ESTIMATE for an hp solution: the residual estimator with h/p weights, or the guaranteed
equilibrated bound (docs/theory.md §9, §11)."""

from __future__ import annotations

from ..adaptivity.estimate import Estimate, residual_estimate
from ..models.discrete import Problem
from ..setup.scene import Scene
from ..solvers import Result
from .space import HPSpace

ESTIMATORS = ("equilibrated", "residual")


def hp_estimate(
    scene: Scene, result: Result, space: HPSpace, kind: str = "equilibrated"
) -> Estimate:
    """η_T and η of an hp solve: ``residual`` (docs/theory.md §5 with the weights h_T/p_T,
    h_E/p_E) or ``equilibrated`` (the guaranteed bound, :mod:`.bound`).  Collective."""
    if kind not in ESTIMATORS:
        raise ValueError(f"estimator: expected one of {ESTIMATORS}, got {kind!r}")
    if kind == "residual":
        problem = result.problem
        assert isinstance(problem, Problem)  # hp_problem's, with its physics and condition
        return residual_estimate(problem, result, space.degree_function())
    from .bound import hp_bound

    bound = hp_bound(scene, result, space)
    return Estimate(bound.eta_T, bound.eta, bound.terms)
