"""The problem a model builds: the solver's :class:`~contact.solvers.problem.DiscreteProblem`
with the continuous problem it discretises — its equations (:mod:`.physics`) and the contact
conditions its constraint set comes from (:mod:`.constraints`) — which the estimators and
reports read."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from dolfinx import fem

from ..solvers.problem import DiscreteProblem
from .constraints import Condition
from .physics import Physics


@dataclass
class Problem(DiscreteProblem):
    """A discrete problem with the continuous problem it discretises: the equations
    (``physics``, what the estimators check) and the contact conditions its constraint set
    comes from (``contacts``, in the order of the constraint's nodes).  Every model and
    :class:`ComplementarityProblem` builds one; the solvers see its
    :class:`~contact.solvers.problem.DiscreteProblem` part only."""

    physics: Physics | None = None
    contacts: tuple[Condition, ...] = ()
    #: the previous load step's displacement, from which friction's slips are measured
    u_prev: fem.Function | None = None


def discrete(problem: Any) -> DiscreteProblem:
    """The solver's problem of ``problem``: itself, or what a
    :class:`~contact.models.forms.ComplementarityProblem` holds; anything else is a
    ValueError naming the argument."""
    inner = getattr(problem, "problem", problem)
    if not isinstance(inner, DiscreteProblem):
        raise ValueError(
            "problem: expected a contact.ComplementarityProblem or the problem of a model, "
            f"got {type(problem).__name__}"
        )
    return inner
