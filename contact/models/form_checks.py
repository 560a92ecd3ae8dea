"""The checks of the own-forms API's arguments (:mod:`contact.models.forms`): the forms'
ranks, spaces and meshes against the unknown u's, the Dirichlet conditions' spaces, and
the constraint — its measure (one that selects nothing is an error, as a scene's predicate
that selects nothing is), DoFs (owned integer indices), weights (finite, > 0) and bound
(finite, one value per point).

Each error is one line starting with the argument's name (``a: expected a bilinear form
…``, ``Unilateral.dofs: …``): a ``TypeError`` for an argument of the wrong kind, a
``ValueError`` for a wrong value.  A mistake that would otherwise crash the interpreter
(a bilinear form as the load, Dirichlet DoFs outside the space), give a raw PETSc error
or drop the constraint silently is caught before anything is assembled.

**Collective.**  Every check raises the same exception on every rank, so an argument that
is wrong on one rank only (DoFs out of range there, a callable bound failing on one
partition) never leaves the others waiting in a collective.  Checks of local data run
inside :func:`agree`, which gathers each rank's first failure and raises the lowest
failing rank's on all (naming that rank when some ranks passed); checks of global counts
(nothing selected, non-finite bound values) reduce the count first.  The checks are
vectorised, O(n) in the DoFs, and run once per problem.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

#: the kinds of error every rank raises alike (anything else: a RuntimeError naming it)
_KINDS: tuple[type[Exception], ...] = (TypeError, ValueError, RuntimeError)
#: what a form of each rank is, for messages
_RANKS = {
    0: "a functional (no test function)",
    1: "a linear form (a test function)",
    2: "a bilinear form (a test and a trial function)",
}
_ARGUMENTS = {0: "test function", 1: "trial function"}


def agree[T](comm: MPI.Comm, check: Callable[[], T], same: bool = False) -> T:
    """``check()`` (local work only: no collective inside) on every rank, then one
    allgather: if it raised on any rank, every rank raises the lowest failing rank's error
    — its type if a TypeError, ValueError or RuntimeError (else a RuntimeError naming the
    type) and its message, with ``(rank r)`` appended when some ranks passed.

    ``same``: ``check()`` returns a mapping {argument: what it is} that must be the same on
    every rank (the kind of each argument, which decides the collectives the ranks enter
    next); a difference is a ValueError naming the argument, on every rank.  Returns
    ``check()``'s value."""
    failure: tuple[type[Exception], str] | None = None
    origin: Exception | None = None
    value: Any = None
    try:
        value = check()
    except Exception as err:  # any: one rank's failure must reach every rank
        origin = err
        kind = next((k for k in _KINDS if isinstance(err, k)), None)
        text = str(err) if kind is not None else f"{type(err).__name__}: {err}"
        failure = (kind or RuntimeError, " ".join(text.split()))
    mine = (failure, value if same else None)
    found: list[tuple[Any, Any]] = comm.allgather(mine) if comm.size > 1 else [mine]
    failed = [(rank, f) for rank, (f, _) in enumerate(found) if f is not None]
    if failed:
        rank, (kind, message) = failed[0]
        if len(failed) < comm.size:
            message = f"{message} (rank {rank})"
        raise kind(message) from origin
    if same:
        reference = found[0][1]
        for key, first in reference.items():
            other = next((r for r, (_, v) in enumerate(found) if v[key] != first), None)
            if other is not None:
                raise ValueError(
                    f"{key}: not the same on every rank (rank 0: {first}, rank {other}: "
                    f"{found[other][1][key]}); build the same problem on every rank"
                )
    return value


def check_unknown(u: Any) -> fem.Function:
    """``u`` is a ``dolfinx.fem.Function`` (local: without it there is no communicator to
    agree on; the same on every rank for the same call)."""
    if not isinstance(u, fem.Function):
        raise TypeError(
            f"u: expected a dolfinx.fem.Function (the unknown, on the forms' space), "
            f"got {type(u).__name__}"
        )
    return u


def bcs_list(bcs: Any) -> list | None:
    """``bcs`` as a list, or None if it is no sequence (:func:`check_bcs` reports it)."""
    if isinstance(bcs, (str, bytes)) or not isinstance(bcs, Iterable):
        return None
    return list(bcs)


def same_space(W: Any, V: fem.FunctionSpace) -> bool:
    """Whether the space ``W`` (Python or C++) is u's space ``V`` itself.  DOLFINx matches
    spaces by object (its assembler applies a Dirichlet condition to a form only if the
    form's space contains the condition's), so a space built like V — same mesh, element
    and DoF numbering — is not V."""
    cpp, V_cpp = getattr(W, "_cpp_object", W), V._cpp_object
    return bool(V_cpp.contains(cpp) and cpp.contains(V_cpp))


def _elsewhere(W: Any, V: fem.FunctionSpace) -> str:
    """Where a space ``W`` that is not u's space ``V`` (nor in it) lives, for messages."""
    cpp, V_cpp = getattr(W, "_cpp_object", W), V._cpp_object
    if cpp.mesh is not V.mesh._cpp_object:
        return "on another mesh than u's"
    if (
        not cpp.component()
        and cpp.element == V_cpp.element
        and cpp.dofmap.index_map.size_local == V.dofmap.index_map.size_local
    ):
        return (
            "on a copy of u's function space (another object: DOLFINx matches spaces by "
            "object and would drop Dirichlet conditions)"
        )
    return "on another function space than u's"


def check_form(name: str, form: Any, rank: int, V: fem.FunctionSpace) -> None:
    """``form`` is a UFL form (or a compiled ``dolfinx.fem.Form``) of ``rank`` (a: 2, L: 1,
    F: 1, J: 2) whose test (and trial) functions live on u's space ``V`` and which is
    integrated over u's mesh, its coefficients on that mesh too."""
    if isinstance(form, fem.Form):
        spaces, meshes, coefficients = list(form.function_spaces), [form.mesh], []
        numbers = list(range(form.rank))
    elif isinstance(form, (ufl.Form, ufl.ZeroBaseForm)):
        arguments = sorted(form.arguments(), key=lambda arg: arg.number())
        spaces = [arg.ufl_function_space() for arg in arguments]
        numbers = [arg.number() for arg in arguments]
        meshes = [d.ufl_cargo() for d in getattr(form, "ufl_domains", tuple)()]
        coefficients = [c for c in form.coefficients() if isinstance(c, fem.Function)]
    else:
        raise TypeError(
            f"{name}: expected a UFL form (ufl.Form) or a dolfinx.fem.Form, "
            f"got {type(form).__name__}"
        )
    if len(numbers) != rank:
        raise ValueError(
            f"{name}: expected {_RANKS[rank]}, got "
            f"{_RANKS.get(len(numbers), f'a form of {len(numbers)} arguments')}"
        )
    if numbers != list(range(rank)):
        raise ValueError(
            f"{name}: {_RANKS[rank]} takes the argument numbers {list(range(rank))} "
            f"(ufl.TestFunction first), got {numbers}"
        )
    for number, W in zip(numbers, spaces):
        if not same_space(W, V):
            raise ValueError(
                f"{name}: its {_ARGUMENTS[number]} lives {_elsewhere(W, V)}; build the "
                "forms on u.function_space"
            )
    if any(mesh is not V.mesh._cpp_object for mesh in meshes):
        raise ValueError(f"{name}: is integrated over another mesh than u's")
    for c in coefficients:
        if c.function_space.mesh is not V.mesh:
            raise ValueError(f"{name}: its coefficient {c.name!r} lives on another mesh than u's")


def check_written_in(F: Any, J: Any, u: fem.Function) -> None:
    """A residual ``F`` is written in ``u`` (the iterate enters R(x) through it); ``J`` is
    needed when F is compiled (``ufl.derivative`` takes UFL)."""
    if isinstance(F, fem.Form):
        if J is None:
            raise TypeError(
                "J: required when F is a compiled dolfinx.fem.Form (ufl.derivative needs "
                "the UFL form)"
            )
        return
    if u not in F.coefficients():
        raise ValueError(
            "F: is not written in u (u is none of its coefficients), so R(u) would not "
            "change with u; write F in the Function u"
        )


def check_bcs(bcs: list | None, V: fem.FunctionSpace) -> None:
    """Each Dirichlet condition is a ``dolfinx.fem.DirichletBC`` on u's space or a
    subspace of it (the space objects: :func:`same_space`), its DoF indices in that
    space's local range."""
    if bcs is None:
        raise TypeError("bcs: expected a sequence of dolfinx.fem.DirichletBC")
    imap, bs = V.dofmap.index_map, V.dofmap.index_map_bs
    n_local = (imap.size_local + imap.num_ghosts) * bs
    for i, bc in enumerate(bcs):
        if not isinstance(bc, fem.DirichletBC):
            raise TypeError(
                f"bcs[{i}]: expected a dolfinx.fem.DirichletBC, got {type(bc).__name__}"
            )
        W = bc.function_space
        if not V._cpp_object.contains(W):
            raise ValueError(
                f"bcs[{i}]: built {_elsewhere(W, V)}; build it on u.function_space or a "
                "subspace V.sub(k)"
            )
        dofs = bc.dof_indices()[0]
        if len(dofs) and (dofs.min() < 0 or dofs.max() >= n_local):
            raise ValueError(
                f"bcs[{i}]: DoF indices outside u's space (0 … {n_local - 1}), e.g. "
                f"{int(dofs.max())}: located on another space?"
            )


def _index_problem(what: str, bad: np.ndarray, values: np.ndarray, limit: str) -> str:
    return f"{what}: {int(bad.sum())} index(es) {limit}, e.g. {values[bad][0]}"


def check_constraint(c: Any, V: fem.FunctionSpace) -> dict[str, object]:
    """A :class:`~contact.models.forms.Unilateral` ``c`` on its own and against u's space
    ``V`` (local data): its side, which of measure / dofs / weights / component it takes,
    the measure's kind, mesh and tags, the component, the DoFs (1D owned integer indices,
    each once), the weights (one finite number > 0 per DoF) and the kind of bound (its
    values are checked once evaluated: :func:`shaped`, :func:`check_finite_bound`).
    Returns its :func:`shape_of`."""
    if c.side not in ("upper", "lower"):
        raise ValueError(
            f"Unilateral.side: expected 'upper' (u <= g) or 'lower' (u >= g), got {c.side!r}"
        )
    if c.dofs is not None and c.measure is not None:
        raise ValueError("Unilateral: give either a measure or dofs, not both")
    if c.weights is not None and c.dofs is None:
        raise ValueError("Unilateral: weights go with dofs (a measure makes its own)")
    if c.component is not None and c.dofs is not None:
        raise ValueError("Unilateral: a component goes with a measure (dofs name their own)")
    if c.dofs is None:
        check_measure(c.measure, V)
        _check_component(c.component, V)
    else:
        _check_dofs(c.dofs, c.weights, V)
    _check_bound_kind(c.bound, target_space(V, c.component))
    return shape_of(c)


def shape_of(c: Any) -> dict[str, object]:
    """What decides the collectives a constraint's nodes and bound enter: which of measure
    or dofs, the measure's kind and tags, the component and the kind of bound (for
    :func:`agree` with ``same``: the same on every rank)."""
    m = c.measure
    bound = c.bound
    return {
        "Unilateral.side": c.side,
        "Unilateral.dofs": "given" if c.dofs is not None else None,
        "Unilateral.measure": None if m is None else f"{m.integral_type()}({m.subdomain_id()})",
        "Unilateral.component": c.component,
        "Unilateral.bound": (
            "a Function"
            if isinstance(bound, fem.Function)
            else "a UFL expression"
            if isinstance(bound, ufl.core.expr.Expr)
            else "a callable"
            if callable(bound)
            else "a number"
            if np.ndim(bound) == 0
            else "values"
        ),
    }


def check_measure(measure: Any, V: fem.FunctionSpace, name: str = "Unilateral.measure") -> None:
    """``measure`` is dx or a tagged ds on u's mesh, its tags of the right dimension (a
    one-line error naming ``name``)."""
    if measure is None:
        return
    if not isinstance(measure, ufl.Measure):
        raise TypeError(f"{name}: expected ufl.dx or ds(tag), got {type(measure).__name__}")
    kind, tag, tags = measure.integral_type(), measure.subdomain_id(), measure.subdomain_data()
    if kind not in ("cell", "exterior_facet"):
        raise ValueError(f"{name}: expected dx or ds, got {kind}")
    domain = measure.ufl_domain()
    if domain is not None and domain.ufl_cargo() is not V.mesh._cpp_object:
        raise ValueError(f"{name}: defined on another mesh than u's")
    if tag == "everywhere":
        return
    ids = tag if isinstance(tag, tuple) else (tag,)
    if not all(isinstance(i, (int, np.integer)) and not isinstance(i, bool) for i in ids):
        raise ValueError(f"{name}: subdomain ids are integer tags, got {tag!r}")
    if tags is None:
        raise ValueError(f"{name}: {kind} with subdomain {tag} needs subdomain_data (mesh tags)")
    topology = getattr(tags, "topology", None)
    if topology is None or not hasattr(tags, "find"):
        raise TypeError(
            f"{name}: its subdomain_data must be dolfinx mesh tags, got {type(tags).__name__}"
        )
    if topology is not V.mesh.topology._cpp_object:
        raise ValueError(f"{name}: its mesh tags belong to another mesh than u's")
    dim = V.mesh.topology.dim - (kind == "exterior_facet")
    if tags.dim != dim:
        raise ValueError(
            f"{name}: {'ds' if dim < V.mesh.topology.dim else 'dx'} needs tags of "
            f"dimension {dim}, got tags of dimension {tags.dim}"
        )


def _check_component(component: Any, V: fem.FunctionSpace) -> None:
    bs = V.dofmap.index_map_bs
    if bs == 1 and component is not None:
        raise ValueError("Unilateral.component: V is scalar: give no component")
    if bs > 1 and (
        isinstance(component, bool)
        or not isinstance(component, (int, np.integer))
        or not 0 <= component < bs
    ):
        raise ValueError(
            f"Unilateral.component: a vector space needs one of 0 … {bs - 1}, got {component}"
        )


def _check_dofs(dofs: Any, weights: Any, V: fem.FunctionSpace) -> None:
    n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    d = np.asarray(dofs)
    integer = np.issubdtype(d.dtype, np.integer) or (d.size == 0 and d.dtype.kind in "fiu")
    if d.ndim != 1 or not integer:
        shape = f" with shape {d.shape}" if d.ndim != 1 else ""
        raise ValueError(
            f"Unilateral.dofs: expected a 1D array of integer DoF indices, got {d.dtype}{shape}"
        )
    d = d.astype(np.int64, copy=False)  # (an empty array may come as float)
    bad = (d < 0) | (d >= n_owned)
    if bad.any():
        raise ValueError(
            _index_problem("Unilateral.dofs", bad, d, f"outside the owned DoFs 0 … {n_owned - 1}")
        )
    counts = np.bincount(d, minlength=n_owned)  # O(n): the indices lie in [0, n_owned)
    if (counts > 1).any():
        twice = np.flatnonzero(counts > 1)
        raise ValueError(
            _index_problem("Unilateral.dofs", np.ones(len(twice), bool), twice, "given twice")
        )
    if weights is None:
        return
    try:
        w = np.asarray(weights, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(
            f"Unilateral.weights: expected numbers, got {type(weights).__name__}"
        ) from None
    if w.shape != d.shape:
        raise ValueError(f"Unilateral.weights: expected {len(d)} values, got {w.shape}")
    bad = ~(np.isfinite(w) & (w > 0))
    if bad.any():
        raise ValueError(
            f"Unilateral.weights: {int(bad.sum())} of {len(w)} are not finite numbers > 0 "
            f"(NaN, inf, zero or negative), e.g. {w[bad][0]}"
        )


def target_space(V: fem.FunctionSpace, component: int | None) -> fem.FunctionSpace:
    """The space a bound is given on: ``V``, or its ``component``'s (scalar) subspace."""
    return V if component is None else V.sub(component)


def _check_bound_kind(bound: Any, W: fem.FunctionSpace) -> None:
    if isinstance(bound, fem.Function):
        if bound.function_space.mesh is not W.mesh:
            raise ValueError(
                "Unilateral.bound: a Function on another mesh than u's (interpolate it onto "
                "u's mesh first)"
            )
        if bound.function_space.value_shape != W.value_shape:
            raise ValueError(
                f"Unilateral.bound: a Function of value shape {bound.function_space.value_shape}"
                f", the constraint needs {W.value_shape}"
            )
        return
    if isinstance(bound, ufl.core.expr.Expr):
        if bound.ufl_shape != W.value_shape:
            raise ValueError(
                f"Unilateral.bound: a UFL expression of shape {bound.ufl_shape}, the "
                f"constraint needs {W.value_shape}"
            )
        return
    if callable(bound):
        return
    if isinstance(bound, (bool, np.bool_, str, bytes)):
        raise TypeError(
            "Unilateral.bound: expected a number, a Function, values at the DoFs or "
            f"f(x) -> values, got {type(bound).__name__}"
        )
    values = np.asarray(bound)
    if values.dtype.kind not in "fiu":
        raise TypeError(
            "Unilateral.bound: expected a number, a Function, values at the DoFs or "
            f"f(x) -> values, got {type(bound).__name__} of {values.dtype}"
        )
    if values.ndim > 1:
        raise ValueError(
            f"Unilateral.bound: expected one value per constrained DoF, got shape {values.shape}"
        )


def shaped(f: Callable[[np.ndarray], Any], W: fem.FunctionSpace) -> Callable:
    """``f`` for ``Function.interpolate`` into ``W``, checked: what it returns for points
    x of shape (3, n) must have shape (n,) (scalar W) or (value size, n); its own errors
    and a wrong shape are one ValueError naming the bound."""
    size = int(np.prod(W.value_shape, dtype=int))

    def evaluate(x: np.ndarray) -> np.ndarray:
        try:
            values = np.asarray(f(x), dtype=float)
        except Exception as err:  # the user's function: whatever it raises, named
            text = " ".join(str(err).split())
            raise ValueError(
                f"Unilateral.bound: f(x) failed: {type(err).__name__}: {text}"
            ) from err
        n = x.shape[1]
        allowed = [(size, n), (n,)] if size == 1 else [(size, n)]
        if values.shape not in allowed:
            want = "(n,)" if size == 1 else f"({size}, n)"
            raise ValueError(
                f"Unilateral.bound: f(x) must return one value per point, shape {want} for "
                f"x of shape (3, n); got {values.shape} for n = {n}"
            )
        return values

    return evaluate


def check_selects(
    comm: MPI.Comm, measure: ufl.Measure, tags: Any, ids: tuple, entities: np.ndarray
) -> None:
    """A tagged measure selects some entity on some rank (collective); else a ValueError
    naming the tag values the mesh tags hold."""
    if comm.allreduce(len(entities), op=MPI.SUM):
        return
    held = sorted(set().union(*comm.allgather(set(np.unique(tags.values).tolist()))))
    holds = f"they hold {', '.join(map(str, held[:10]))}" if held else "they are empty"
    what = "facet" if measure.integral_type() == "exterior_facet" else "cell"
    name = "ds" if what == "facet" else "dx"
    tag = ids[0] if len(ids) == 1 else ids
    raise ValueError(f"Unilateral.measure: {name}({tag}) selects no {what} of its tags ({holds})")


def check_constrained(comm: MPI.Comm, dofs: np.ndarray, by_dofs: bool) -> None:
    """The constraint acts on some DoF on some rank (collective): a constraint on Dirichlet
    DoFs only (or on none) would be silently dropped."""
    if comm.allreduce(len(dofs), op=MPI.SUM):
        return
    what = "Unilateral.dofs" if by_dofs else "Unilateral.measure"
    raise ValueError(
        f"{what}: no DoF to constrain on any rank (none given, or all are Dirichlet DoFs): "
        "the constraint would act nowhere"
    )


def check_finite_bound(comm: MPI.Comm, values: np.ndarray) -> None:
    """The bound's values at the constrained DoFs are finite (collective)."""
    bad = int(np.count_nonzero(~np.isfinite(values)))
    bad, total = comm.allreduce(np.array([bad, len(values)]), op=MPI.SUM)
    if bad:
        raise ValueError(
            f"Unilateral.bound: {bad} of {total} values at the constrained DoFs are not "
            "finite (NaN or ±inf)"
        )


def check_initial_guess(u: fem.Function) -> None:
    """u's values (the initial guess of a solve) are finite (local: run it in
    :func:`agree`)."""
    bad = int(np.count_nonzero(~np.isfinite(u.x.array)))
    if bad:
        raise ValueError(
            f"u: {bad} of its {len(u.x.array)} values (the initial guess) are not finite"
        )
