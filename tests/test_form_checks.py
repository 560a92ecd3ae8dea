"""The own-forms API (``contact.ComplementarityProblem``) refuses bad arguments as a scene
refuses bad input: each case is one TypeError/ValueError line naming the argument, raised
on every rank — also when only one rank's data are wrong — and never an abort of the
interpreter, a rank left waiting or a silent answer.

Before these checks: a bilinear form as L aborted the interpreter (``free(): invalid next
size``), ``from_forms(L, L, …)`` and ``J=F`` were a C++ ``IndexError``, DoFs out of range on
one rank left the other waiting forever, a Dirichlet condition of another mesh's space and
``ds(99)`` with no facet tagged 99 "converged" without the constraint, and NaN bounds or
weights, zero weights, a callable bound of the wrong shape (which read past its array)
ended in ``diverged_function_nanorinf`` at iteration 0.

Every case runs in-process on one rank and, in one subprocess under ``mpirun -n 2`` with a
timeout (:func:`test_every_case_on_two_ranks`), on two: there the "one rank" cases put the
bad data on rank 1 only."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import contact  # noqa: F401  (before dolfinx)
from contact import ComplementarityProblem, Unilateral

import numpy as np
import pytest
import ufl
from clirun import pytest_on_ranks
from dolfinx import fem, mesh
from mpi4py import MPI

comm = MPI.COMM_WORLD
LAST = comm.size - 1  # the rank whose data are wrong in the "one rank only" cases
BOUNDARY = (lambda x: np.full(x.shape[1], True),)


def _boundary_bc(msh, V, value=0.0):
    msh.topology.create_connectivity(1, 2)
    facets = mesh.locate_entities_boundary(msh, 1, BOUNDARY[0])
    return fem.dirichletbc(value, fem.locate_dofs_topological(V, 1, facets), V)


def _tagged(msh, value=3):
    """Facet tags: the top side tagged ``value``."""
    top = mesh.locate_entities_boundary(msh, 1, lambda x: np.isclose(x[1], 1.0))
    return mesh.meshtags(msh, 1, top, np.full(len(top), value, dtype=np.int32))


@pytest.fixture
def s() -> SimpleNamespace:
    """A membrane on the unit square (6 × 6), clamped on its boundary; another mesh (12 ×
    12) to build wrong things on; the owned free DoFs."""
    msh = mesh.create_unit_square(comm, 6, 6)
    other = mesh.create_unit_square(comm, 12, 12)
    V = fem.functionspace(msh, ("Lagrange", 1))
    V_other = fem.functionspace(other, ("Lagrange", 1))
    u, v, w = fem.Function(V, name="u"), ufl.TestFunction(V), ufl.TrialFunction(V)
    bc = _boundary_bc(msh, V)
    n_owned = V.dofmap.index_map.size_local
    tags = _tagged(msh)
    return SimpleNamespace(
        msh=msh,
        V=V,
        u=u,
        a=ufl.inner(ufl.grad(w), ufl.grad(v)) * ufl.dx,
        L=-2.0 * v * ufl.dx,
        F=ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx + 2.0 * v * ufl.dx,
        bc=bc,
        tags=tags,
        ds=ufl.Measure("ds", domain=msh, subdomain_data=tags),
        other=other,
        V_other=V_other,
        bc_other=_boundary_bc(other, V_other),
        free=np.setdiff1d(np.arange(n_owned), bc.dof_indices()[0]).astype(np.int32),
        lower=Unilateral(-0.1, side="lower"),
    )


def _forms(s, constraint, bcs=None):
    return ComplementarityProblem.from_forms(
        s.a, s.L, s.u, constraint, [s.bc] if bcs is None else bcs
    )


def _on_last(bad: Any, good: Any) -> Any:
    return bad if comm.rank == LAST else good


def _closed(s):
    problem = _forms(s, s.lower)
    problem.close()
    return problem.solve("fb")


def _nan_guess(s):
    with _forms(s, s.lower) as problem:
        if comm.rank == LAST:
            s.u.x.array[0] = np.nan
        return problem.solve("fb")


def _nan_function(s):
    g = fem.Function(s.V)
    g.x.array[:] = -0.1
    g.x.array[s.free[0]] = _on_last(np.nan, -0.1)  # an owned constrained DoF
    return _forms(s, Unilateral(g, side="lower"))


def _ghost_dofs(s):
    imap = s.V.dofmap.index_map
    return np.arange(imap.size_local, imap.size_local + imap.num_ghosts)


@dataclass(frozen=True)
class Case:
    """A misuse: ``call(s)``, the exception it must raise and its message's start;
    ``last_only``: the data are wrong on the last rank only (on 2 ranks the message then
    names that rank)."""

    id: str
    call: Callable[[SimpleNamespace], Any]
    kind: type[Exception]
    match: str
    last_only: bool = False


BOUND_NOT_FINITE = (
    r"^Unilateral\.bound: [1-9]\d* of \d+ values at the constrained DoFs are not finite"
)
WEIGHTS = r"^Unilateral\.weights: [1-9]\d* of \d+ are not finite numbers > 0"
CASES = [
    # the forms: ranks, spaces, meshes
    Case(
        "bilinear form as L",
        lambda s: ComplementarityProblem.from_forms(s.a, s.a, s.u, s.lower, [s.bc]),
        ValueError,
        r"^L: expected a linear form \(a test function\), got a bilinear form",
    ),
    Case(
        "linear form as a",
        lambda s: ComplementarityProblem.from_forms(s.L, s.L, s.u, s.lower, [s.bc]),
        ValueError,
        r"^a: expected a bilinear form \(a test and a trial function\), got a linear form",
    ),
    Case(
        "residual as J",
        lambda s: ComplementarityProblem.from_residual(s.F, s.u, s.lower, [s.bc], J=s.F),
        ValueError,
        r"^J: expected a bilinear form",
    ),
    Case(
        "bilinear form as F",
        lambda s: ComplementarityProblem.from_residual(s.a, s.u, s.lower, [s.bc]),
        ValueError,
        r"^F: expected a linear form",
    ),
    Case(
        "a trial function as L's argument",
        lambda s: ComplementarityProblem.from_forms(
            s.a, ufl.TrialFunction(s.V) * ufl.dx, s.u, s.lower, [s.bc]
        ),
        ValueError,
        r"^L: a linear form \(a test function\) takes the argument numbers \[0\]",
    ),
    Case(
        "forms on another mesh",
        lambda s: ComplementarityProblem.from_forms(
            ufl.inner(ufl.grad(ufl.TrialFunction(s.V_other)), ufl.grad(ufl.TestFunction(s.V_other)))
            * ufl.dx,
            ufl.TestFunction(s.V_other) * ufl.dx,
            s.u,
            s.lower,
            [],
        ),
        ValueError,
        r"^a: its test function lives on another mesh than u's; build the forms on "
        r"u\.function_space$",
    ),
    Case(
        "a trial function on another space",
        lambda s: ComplementarityProblem.from_forms(
            ufl.TrialFunction(fem.functionspace(s.msh, ("Lagrange", 2)))
            * ufl.TestFunction(s.V)
            * ufl.dx,
            s.L,
            s.u,
            s.lower,
            [s.bc],
        ),
        ValueError,
        r"^a: its trial function lives on another function space than u's",
    ),
    Case(
        "a coefficient on another mesh",
        lambda s: ComplementarityProblem.from_forms(
            s.a,
            fem.Function(s.V_other, name="f") * ufl.TestFunction(s.V) * ufl.dx(domain=s.msh),
            s.u,
            s.lower,
            [s.bc],
        ),
        ValueError,
        r"^L: its coefficient 'f' lives on another mesh than u's",
    ),
    Case(
        "not a form",
        lambda s: ComplementarityProblem.from_forms("a(u, v)", s.L, s.u, s.lower, [s.bc]),
        TypeError,
        r"^a: expected a UFL form \(ufl\.Form\) or a dolfinx\.fem\.Form, got str",
    ),
    Case(
        "F not written in u",
        lambda s: ComplementarityProblem.from_residual(
            ufl.inner(ufl.grad(fem.Function(s.V)), ufl.grad(ufl.TestFunction(s.V))) * ufl.dx,
            s.u,
            s.lower,
            [s.bc],
        ),
        ValueError,
        r"^F: is not written in u",
    ),
    Case(
        "u not a Function",
        lambda s: ComplementarityProblem.from_forms(s.a, s.L, s.V, s.lower, [s.bc]),
        TypeError,
        r"^u: expected a dolfinx\.fem\.Function",
    ),
    # the Dirichlet conditions
    Case(
        "a Dirichlet condition on another mesh's space",
        lambda s: _forms(s, s.lower, [s.bc_other]),
        ValueError,
        r"^bcs\[0\]: built on another mesh than u's; build it on u\.function_space or a "
        r"subspace V\.sub\(k\)$",
    ),
    Case(
        "another space's DoFs given to u's space",
        lambda s: _forms(s, s.lower, [fem.dirichletbc(0.0, s.bc_other.dof_indices()[0], s.V)]),
        ValueError,
        r"^bcs\[0\]: DoF indices outside u's space",
    ),
    Case(
        "a Dirichlet condition on another space of the mesh",
        lambda s: _forms(
            s, s.lower, [_boundary_bc(s.msh, fem.functionspace(s.msh, ("Lagrange", 2)))]
        ),
        ValueError,
        r"^bcs\[0\]: built on another function space than u's",
    ),
    Case(
        "a Dirichlet condition on a copy of u's space",  # DOLFINx would drop it
        lambda s: _forms(
            s, s.lower, [_boundary_bc(s.msh, fem.functionspace(s.msh, ("Lagrange", 1)))]
        ),
        ValueError,
        r"^bcs\[0\]: built on a copy of u's function space \(another object: DOLFINx matches "
        r"spaces by object and would drop Dirichlet conditions\)",
    ),
    Case(
        "forms on a copy of u's space",
        lambda s: ComplementarityProblem.from_residual(
            ufl.inner(
                ufl.grad(s.u), ufl.grad(ufl.TestFunction(fem.functionspace(s.msh, ("Lagrange", 1))))
            )
            * ufl.dx,
            s.u,
            s.lower,
            [s.bc],
        ),
        ValueError,
        r"^F: its test function lives on a copy of u's function space",
    ),
    Case(
        "not a Dirichlet condition",
        lambda s: _forms(s, s.lower, [s.bc, 0.0]),
        TypeError,
        r"^bcs\[1\]: expected a dolfinx\.fem\.DirichletBC, got float",
    ),
    Case(
        "bcs not a sequence",
        lambda s: ComplementarityProblem.from_forms(s.a, s.L, s.u, s.lower, s.bc),
        TypeError,
        r"^bcs: expected a sequence of dolfinx\.fem\.DirichletBC",
    ),
    # the constraint: its kind, side and measure
    Case(
        "not a Unilateral",
        lambda s: _forms(s, -0.1),
        TypeError,
        r"^constraint: expected a contact\.Unilateral, got float",
    ),
    Case(
        "a side on one rank only",
        lambda s: _forms(s, Unilateral(-0.1, side=_on_last("below", "lower"))),
        ValueError,
        r"^Unilateral\.side: expected 'upper' \(u <= g\) or 'lower' \(u >= g\), got 'below'",
        last_only=True,
    ),
    Case(
        "a measure that selects nothing",
        lambda s: _forms(s, Unilateral(-0.1, side="lower", measure=s.ds(99))),
        ValueError,
        r"^Unilateral\.measure: ds\(99\) selects no facet of its tags \(they hold 3\)$",
    ),
    Case(
        "a measure on Dirichlet DoFs only",
        lambda s: _forms(s, Unilateral(-0.1, side="lower", measure=s.ds(3))),
        ValueError,
        r"^Unilateral\.measure: no DoF to constrain on any rank",
    ),
    Case(
        "tags of another mesh",
        lambda s: _forms(
            s,
            Unilateral(
                0.1, measure=ufl.Measure("ds", domain=s.msh, subdomain_data=_tagged(s.other))(3)
            ),
        ),
        ValueError,
        r"^Unilateral\.measure: its mesh tags belong to another mesh than u's",
    ),
    Case(
        "cell tags with ds",
        lambda s: _forms(
            s,
            Unilateral(
                0.1,
                measure=ufl.Measure(
                    "ds",
                    domain=s.msh,
                    subdomain_data=mesh.meshtags(
                        s.msh, 2, np.arange(3, dtype=np.int32), np.full(3, 3, dtype=np.int32)
                    ),
                )(3),
            ),
        ),
        ValueError,
        r"^Unilateral\.measure: ds needs tags of dimension 1, got tags of dimension 2",
    ),
    Case(
        "an interior-facet measure",
        lambda s: _forms(s, Unilateral(0.1, measure=ufl.dS(domain=s.msh))),
        ValueError,
        r"^Unilateral\.measure: expected dx or ds, got interior_facet",
    ),
    # the constraint's DoFs and weights
    Case(
        "DoFs out of range on one rank only",
        lambda s: _forms(s, Unilateral(0.1, dofs=_on_last(np.array([10**6]), s.free[:1]))),
        ValueError,
        r"^Unilateral\.dofs: 1 index\(es\) outside the owned DoFs 0 … \d+, e\.g\. 1000000",
        last_only=True,
    ),
    Case(
        "ghost DoFs",  # serially none: then an empty constraint, refused as well
        lambda s: _forms(s, Unilateral(0.1, dofs=_ghost_dofs(s)), []),
        ValueError,
        r"^Unilateral\.dofs: (\d+ index\(es\) outside the owned DoFs|no DoF to constrain)",
    ),
    Case(
        "negative DoFs",
        lambda s: _forms(s, Unilateral(0.1, dofs=np.array([-1, 3]))),
        ValueError,
        r"^Unilateral\.dofs: 1 index\(es\) outside the owned DoFs 0 … \d+, e\.g\. -1",
    ),
    Case(
        "float DoFs",
        lambda s: _forms(s, Unilateral(0.1, dofs=np.array([0.5, 1.7]))),
        ValueError,
        r"^Unilateral\.dofs: expected a 1D array of integer DoF indices, got float64$",
    ),
    Case(
        "DoFs as a 2D array",
        lambda s: _forms(s, Unilateral(0.1, dofs=s.free[:2].reshape(1, 2))),
        ValueError,
        r"^Unilateral\.dofs: expected a 1D array of integer DoF indices, got int32 "
        r"with shape \(1, 2\)",
    ),
    Case(
        "a DoF given twice",
        lambda s: _forms(s, Unilateral(0.1, dofs=s.free[[0, 1, 0]])),
        ValueError,
        r"^Unilateral\.dofs: 1 index\(es\) given twice, e\.g\. \d+",
    ),
    Case(
        "NaN weights",
        lambda s: _forms(s, Unilateral(0.1, dofs=s.free[:3], weights=np.array([1, np.nan, 1]))),
        ValueError,
        WEIGHTS + r" \(NaN, inf, zero or negative\), e\.g\. nan",
    ),
    Case(
        "zero weights",
        lambda s: _forms(s, Unilateral(0.1, dofs=s.free[:3], weights=np.zeros(3))),
        ValueError,
        WEIGHTS + r".*e\.g\. 0\.0",
    ),
    Case(
        "negative weights",
        lambda s: _forms(s, Unilateral(0.1, dofs=s.free[:3], weights=-np.ones(3))),
        ValueError,
        WEIGHTS + r".*e\.g\. -1\.0",
    ),
    Case(
        "infinite weights on one rank only",
        lambda s: _forms(
            s, Unilateral(0.1, dofs=s.free[:2], weights=np.array([1.0, _on_last(np.inf, 1.0)]))
        ),
        ValueError,
        WEIGHTS + r".*e\.g\. inf",
        last_only=True,
    ),
    Case(
        "weights of the wrong length",
        lambda s: _forms(s, Unilateral(0.1, dofs=s.free[:3], weights=np.ones(2))),
        ValueError,
        r"^Unilateral\.weights: expected 3 values, got \(2,\)",
    ),
    Case(
        "weights without DoFs on one rank only",
        lambda s: _forms(
            s,
            Unilateral(0.1, dofs=_on_last(None, s.free[:2]), weights=np.ones(2), side="lower"),
        ),
        ValueError,
        r"^Unilateral: weights go with dofs",
        last_only=True,
    ),
    # the bound
    Case(
        "a NaN bound",
        lambda s: _forms(s, Unilateral(np.nan, side="lower")),
        ValueError,
        BOUND_NOT_FINITE,
    ),
    Case(
        "an infinite bound",
        lambda s: _forms(s, Unilateral(np.inf, side="upper")),
        ValueError,
        BOUND_NOT_FINITE,
    ),
    Case(
        "a -inf bound",
        lambda s: _forms(s, Unilateral(-np.inf, side="lower")),
        ValueError,
        BOUND_NOT_FINITE,
    ),
    Case(
        "a NaN bound value on one rank only",
        lambda s: _forms(
            s,
            Unilateral(
                np.where(np.arange(len(s.free)) == 0, _on_last(np.nan, 0.1), 0.1),
                dofs=s.free,
            ),
        ),
        ValueError,
        r"^Unilateral\.bound: 1 of \d+ values at the constrained DoFs are not finite",
    ),
    Case(
        "a bound Function with a NaN on one rank only",
        _nan_function,
        ValueError,
        BOUND_NOT_FINITE,
    ),
    Case(
        "a callable bound of the wrong shape",
        lambda s: _forms(s, Unilateral(lambda x: np.zeros(3), side="lower")),
        ValueError,
        r"^Unilateral\.bound: f\(x\) must return one value per point, shape \(n,\) for x of "
        r"shape \(3, n\); got \(3,\)",
    ),
    Case(
        "a callable bound returning a number",
        lambda s: _forms(s, Unilateral(lambda x: -0.1, side="lower")),
        ValueError,
        r"^Unilateral\.bound: f\(x\) must return one value per point.*got \(\)",
    ),
    Case(
        "a callable bound failing on one rank only",
        lambda s: _forms(
            s,
            Unilateral(
                lambda x: (1 / 0) if comm.rank == LAST else 0.0 * x[0],
                side="lower",
            ),
        ),
        ValueError,
        r"^Unilateral\.bound: f\(x\) failed: ZeroDivisionError",
        last_only=True,
    ),
    Case(
        "a bound Function on another mesh",
        lambda s: _forms(s, Unilateral(fem.Function(s.V_other), side="lower")),
        ValueError,
        r"^Unilateral\.bound: a Function on another mesh than u's",
    ),
    Case(
        "a bound of the wrong kind",
        lambda s: _forms(s, Unilateral("-0.1", side="lower")),
        TypeError,
        r"^Unilateral\.bound: expected a number, a Function, values at the DoFs or "
        r"f\(x\) -> values, got str",
    ),
    Case(
        "bound values of the wrong length",
        lambda s: _forms(s, Unilateral(np.zeros(3), side="lower")),
        ValueError,
        r"^Unilateral\.bound: expected one value per constrained DoF",
    ),
    # solving
    Case(
        "solve after close",
        _closed,
        RuntimeError,
        r"^ComplementarityProblem\.solve: the problem is closed \(close\(\), or the end of its "
        r"with-block, destroyed K and b\); build a new one$",
    ),
    Case(
        "a NaN initial guess on one rank only",
        _nan_guess,
        ValueError,
        r"^u: 1 of its \d+ values \(the initial guess\) are not finite",
        last_only=True,
    ),
]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_misuse_is_one_line_naming_the_argument(s, case: Case) -> None:
    """Every rank raises the same exception, of the case's type, one line starting with the
    argument's name; when only the last rank's data are wrong, the message names it."""
    with pytest.raises(case.kind, match=case.match) as err:
        case.call(s)
    text = str(err.value)
    assert type(err.value) is case.kind and "\n" not in text and len(text) <= 300, text
    assert comm.allgather(text) == [text] * comm.size  # the same line on every rank
    assert text.endswith(f" (rank {LAST})") == (case.last_only and comm.size > 1), text


def _reference(s) -> np.ndarray:
    with _forms(s, s.lower) as problem:
        assert problem.solve("fb", rtol=1e-12).converged
    return s.u.x.array.copy()


def test_valid_variants_are_accepted(s) -> None:
    """What the checks must let through, with the answer of the plain call: compiled
    forms, the same constraint as explicit DoFs, the bound as a Function and as a callable
    returning shape (1, n); and DoFs on rank 0 only (an empty float array elsewhere)."""
    reference = _reference(s)
    n_active = comm.allreduce(int(np.sum(np.isclose(reference[s.free], -0.1))), op=MPI.SUM)
    assert n_active > 0
    g = fem.Function(s.V)
    g.x.array[:] = -0.1
    variants = {
        "compiled forms": lambda u: ComplementarityProblem.from_forms(
            fem.form(s.a), fem.form(s.L), u, s.lower, [s.bc]
        ),
        "dofs": lambda u: ComplementarityProblem.from_forms(
            s.a,
            s.L,
            u,
            Unilateral(
                np.full(len(s.free), -0.1),
                side="lower",
                dofs=s.free,
                weights=np.ones(len(s.free)),
            ),
            [s.bc],
        ),
        "Function bound": lambda u: ComplementarityProblem.from_forms(
            s.a, s.L, u, Unilateral(g, side="lower"), [s.bc]
        ),
        "callable (1, n)": lambda u: ComplementarityProblem.from_forms(
            s.a, s.L, u, Unilateral(lambda x: np.full((1, x.shape[1]), -0.1), side="lower"), [s.bc]
        ),
    }
    for name, build in variants.items():
        u = fem.Function(s.V)
        with build(u) as problem:
            result = problem.solve("fb", rtol=1e-12)
        assert result.converged, name
        diff = comm.allreduce(float(np.max(np.abs(u.x.array - reference))), op=MPI.MAX)
        assert diff < 1e-10, (name, diff)
    # DoFs on rank 0 only: the other ranks give an empty (float) array
    u = fem.Function(s.V)
    dofs = s.free if comm.rank == 0 else np.array([])
    with ComplementarityProblem.from_forms(
        s.a, s.L, u, Unilateral(-0.1, side="lower", dofs=dofs), [s.bc]
    ) as problem:
        assert problem.solve("fb", rtol=1e-12).converged
    low = comm.allreduce(float(np.min(u.x.array[dofs.astype(int)], initial=np.inf)), op=MPI.MIN)
    assert abs(low + 0.1) < 1e-12  # on the bound where it holds
    if comm.size == 1:
        assert np.max(np.abs(u.x.array - reference)) < 1e-10


def test_a_subspace_dirichlet_condition_is_accepted() -> None:
    """A Dirichlet condition on one component (``V.sub(1)``) of a vector space, and the
    constraint on the other one (``component=0`` on tagged facets): checked and solved."""
    msh = mesh.create_unit_square(comm, 6, 6)
    V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
    msh.topology.create_connectivity(1, 2)
    bottom = mesh.locate_entities_boundary(msh, 1, lambda x: np.isclose(x[1], 0.0))
    clamp = [
        fem.dirichletbc(0.0, fem.locate_dofs_topological(V.sub(k), 1, bottom), V.sub(k))
        for k in (0, 1)
    ]
    u, v = fem.Function(V), ufl.TestFunction(V)
    w = ufl.TrialFunction(V)
    a = ufl.inner(ufl.grad(w), ufl.grad(v)) * ufl.dx
    L = ufl.inner(ufl.as_vector([1.0, 0.0]), v) * ufl.dx
    ds = ufl.Measure("ds", domain=msh, subdomain_data=_tagged(msh))
    wall = Unilateral(0.01, side="upper", measure=ds(3), component=0)
    with ComplementarityProblem.from_forms(a, L, u, wall, clamp) as problem:
        result = problem.solve("fb", rtol=1e-12)
        con = problem.problem.constraint
    assert result.converged and result.n_active > 0 and np.all(con.dofs % 2 == 0)
    assert comm.allreduce(float(np.max(u.x.array[con.dofs] - 0.01, initial=-1)), op=MPI.MAX) < 1e-12


def test_ranks_that_build_different_constraints() -> None:
    """DoFs on rank 0 and the default measure (dx) elsewhere: serially a valid problem that
    solves; on more ranks the ranks would enter different collectives (a hang), so every
    rank raises, naming the argument that differs."""
    msh = mesh.create_unit_square(comm, 6, 6)
    V = fem.functionspace(msh, ("Lagrange", 1))
    bc = _boundary_bc(msh, V)
    u, v, w = fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
    free = np.setdiff1d(np.arange(V.dofmap.index_map.size_local), bc.dof_indices()[0])
    constraint = Unilateral(-0.1, side="lower", dofs=free if comm.rank == 0 else None)
    a, L = ufl.inner(ufl.grad(w), ufl.grad(v)) * ufl.dx, -2.0 * v * ufl.dx
    if comm.size == 1:
        with ComplementarityProblem.from_forms(a, L, u, constraint, [bc]) as problem:
            assert problem.solve("fb").converged
        return
    with pytest.raises(
        ValueError,
        match=r"^Unilateral\.dofs: not the same on every rank \(rank 0: given, rank 1: None\); "
        r"build the same problem on every rank$",
    ):
        ComplementarityProblem.from_forms(a, L, u, constraint, [bc])


def test_every_case_on_two_ranks() -> None:
    """The tests above on 2 MPI ranks, in one run under a timeout: every rank raises (no
    rank waits for ever, nothing aborts), the messages agree, and a case whose data are
    wrong on rank 1 only names rank 1."""
    proc = pytest_on_ranks(__file__, "not two_ranks", timeout=420)
    out = proc.stdout[-3000:] + proc.stderr[-3000:]
    assert proc.returncode == 0, out
    passed = [line for line in proc.stdout.splitlines() if " passed" in line]
    expected = f"{len(CASES) + 3} passed"
    assert len(passed) == 2 and all(line.startswith(expected) for line in passed), out
