"""Own forms reach every capability: each test builds a problem in plain UFL on a scene's mesh
(its facet tags for the measures), with no scene, and checks that the core gives what the
YAML scene of the same physics gives — the estimators of both kinds, the adaptive loop, grid
sequencing, a rigid obstacle with a tilted normal, a mortar pair, Tresca and Coulomb friction,
a load path — to solver tolerance.  The scene path builds its problem with its own models
(contact.setup.*) from the same core objects, so the agreement checks that one
implementation serves both; the file runs serially and on 2 ranks (test_on_two_ranks)."""

from __future__ import annotations

from dataclasses import replace

import contact
from contact import (
    BoundaryData,
    ComplementarityProblem,
    Coulomb,
    Diffusion,
    Domain,
    Elasticity,
    MortarPair,
    Plane,
    RigidObstacle,
    Tresca,
    Unilateral,
)
from contact.models.physics import lame

import numpy as np
import pytest
import ufl
from clirun import ROOT, pytest_on_ranks
from dolfinx import fem, mesh
from mpi4py import MPI

comm = MPI.COMM_WORLD
TIGHT = {"rtol": 1e-12, "atol": 1e-14}


def largest(a: np.ndarray) -> float:
    return comm.allreduce(float(np.max(np.abs(a), initial=0.0)), op=MPI.MAX)


def close(a: np.ndarray, b: np.ndarray, rtol: float) -> bool:
    """max |a − b| ≤ rtol max(|b|) over all ranks."""
    return largest(a - b) <= rtol * max(largest(b), 1e-300)


# ------------------------------------------------------------------ the scalar Signorini scene
SIGNORINI = ["mesh.cells=[12,12]", "output.verbose=false", "solver.sequence=off"]


def signorini(
    domain: Domain | mesh.Mesh, ids: dict[str, int], loads: bool = True
) -> ComplementarityProblem:
    """configs/signorini_square.yaml in UFL: −Δu = 1, u = 0 on the top, k∂u/∂n = 0 on the
    sides, u ≤ g = 0.1 + 2(x − 0.5)² on the bottom; ``loads``: the physics declares the zero
    loads of the sides and the bottom (else it leaves them out: zero by default)."""
    msh = domain.mesh if isinstance(domain, Domain) else domain
    tags = domain.facets if isinstance(domain, Domain) else None
    V = fem.functionspace(msh, ("Lagrange", 1))
    u, v, w = fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
    x = ufl.SpatialCoordinate(msh)
    one, zero = fem.Constant(msh, 1.0), fem.Constant(msh, 0.0)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)
    top = fem.locate_dofs_topological(V, 1, tags.find(ids["top"]))
    g = 0.1 + 2 * (x[0] - 0.5) ** 2
    physics = Diffusion(
        one,
        one,
        BoundaryData(
            tags,
            dirichlet=(ids["top"],),
            neumann={ids["sides"]: zero, ids["bottom"]: zero} if loads else {},
        ),
        dirichlet_value=lambda space: fem.Function(space),
    )
    return ComplementarityProblem.from_forms(
        ufl.inner(ufl.grad(w), ufl.grad(v)) * ufl.dx,
        one * v * ufl.dx + zero * v * ds(ids["sides"]) + zero * v * ds(ids["bottom"]),
        u,
        Unilateral(g, side="upper", measure=ds(ids["bottom"])),
        [fem.dirichletbc(0.0, top, V)],
        physics=physics,
    )


@pytest.fixture(scope="module")
def square():
    scene = contact.load_scene(ROOT / "configs" / "signorini_square.yaml", SIGNORINI)
    return scene, contact.solve(scene, **TIGHT)


KINDS = ["residual", "equilibrated", "equilibrated_rt0"]


@pytest.mark.parametrize("kind", KINDS)
def test_estimates(square, kind):
    """η and η_T of both estimators from the own forms' physics equal the scene's."""
    scene, reference = square
    with signorini(Domain(scene.mesh, scene.boundary.tags), scene.boundary.ids) as problem:
        result = contact.solve(problem, **TIGHT)
        assert close(result.u_h.x.array, reference.u_h.x.array, 1e-9)
        mine = contact.estimate(problem, result, kind=kind)
        theirs = contact.estimate(scene, reference, kind=kind)
        assert abs(mine.eta - theirs.eta) <= 1e-8 * theirs.eta and theirs.eta > 0
        assert close(mine.eta_T.x.array, theirs.eta_T.x.array, 1e-7)


def test_adapt(square):
    """Three Dörfler levels of a user's builder on a Domain (facet tags carried through
    refinement): the same meshes and η as the scene's loop."""
    scene, _ = square
    ids = scene.boundary.ids
    run = contact.adapt(
        lambda domain: signorini(domain, ids),
        Domain(scene.mesh, scene.boundary.tags),
        kind=scene.config.estimator,
        max_levels=3,
        theta=0.5,
        newton_rtol=1e-12,
    )
    ref = contact.adapt(scene, max_levels=3, theta=0.5, newton_rtol=1e-12, verbose=False)
    assert [lv.result.dofs for lv in run.levels] == [lv.result.dofs for lv in ref.levels]
    for mine, theirs in zip(run.levels, ref.levels):
        assert abs(mine.estimate.eta - theirs.estimate.eta) <= 1e-8 * theirs.estimate.eta
    assert run.stop == ref.stop == "reached max_levels = 3"


def test_adapt_on_a_level_budget_ends_with_the_last_solution(square):
    """``estimate_last=False``: the builder's loop solves the same levels as with its last
    estimate (the same meshes and solutions) and ends with the last level's solution: that
    level has no η, η_T or effectivity, and its time to accuracy is its time to the
    solution (no estimate in it); the levels before keep their η."""
    scene, _ = square
    ids = scene.boundary.ids

    def run(estimate_last: bool):
        return contact.adapt(
            lambda domain: signorini(domain, ids),
            Domain(scene.mesh, scene.boundary.tags),
            kind=scene.config.estimator,
            max_levels=3,
            newton_rtol=1e-12,
            estimate_last=estimate_last,
        )

    full, budget = run(True), run(False)
    assert budget.stop == full.stop == "reached max_levels = 3"
    assert [lv.result.dofs for lv in budget.levels] == [lv.result.dofs for lv in full.levels]
    for mine, theirs in zip(budget.levels, full.levels):
        assert close(mine.result.u_h.x.array, theirs.result.u_h.x.array, 1e-12)
    for mine, theirs in zip(budget.levels[:-1], full.levels[:-1]):
        assert mine.eta == pytest.approx(theirs.eta, rel=1e-10) and mine.estimate.computed
    last = budget.levels[-1]
    assert not last.estimate.computed and last.estimate.eta_T is None and last.eta is None
    assert full.levels[-1].eta > 0 and full.levels[-1].estimate.eta_T is not None
    row = last.row()
    assert row["eta"] == row["effectivity"] == row["eta_disc"] == ""
    assert last.seconds["estimate"] == 0.0 < full.levels[-1].seconds["estimate"]
    assert last.elapsed - last.solved_elapsed < 0.5 * full.levels[-1].seconds["estimate"]


def test_sequencing():
    """contact.sequence of the builder on 8², 16², 32² meshes: the solution of the scene
    sequenced over the same meshes (solver.sequence: 2), its coarse levels and the fine mesh's
    Newton iterations."""
    scene = contact.load_scene(
        ROOT / "configs" / "signorini_square.yaml",
        ["mesh.cells=[32,32]", "output.verbose=false", "solver.sequence=2"],
    )
    ref = contact.solve(scene, **TIGHT)
    meshes = [mesh.create_unit_square(comm, n, n) for n in (8, 16)]

    def build(msh):
        tags = _square_tags(msh)
        return signorini(Domain(msh, tags), {"top": 1, "sides": 2, "bottom": 3})

    problem, result = contact.sequence(build, [*meshes, scene.mesh], **TIGHT)
    with problem:
        assert result.converged and len(result.sequence) == len(ref.sequence) == 2
        assert [lv.dofs for lv in result.sequence] == [lv.dofs for lv in ref.sequence]
        assert result.iterations == ref.iterations
        assert close(result.u_h.x.array, ref.u_h.x.array, 1e-9)


def _square_tags(msh) -> mesh.MeshTags:
    """The unit square's top (1), sides (2) and bottom (3)."""
    parts = [
        (1, lambda x: x[1] > 1 - 1e-10),
        (2, lambda x: (x[0] < 1e-10) | (x[0] > 1 - 1e-10)),
        (3, lambda x: x[1] < 1e-10),
    ]
    msh.topology.create_connectivity(1, 2)
    facets, values = [], []
    for value, where in parts:
        found = mesh.locate_entities_boundary(msh, 1, where)
        facets.append(found)
        values.append(np.full(len(found), value, dtype=np.int32))
    f, v = np.concatenate(facets), np.concatenate(values)
    order = np.argsort(f)
    return mesh.meshtags(msh, 1, f[order], v[order])


# ----------------------------------------------------------------- elastic bodies, own forms
def elastic(
    scene,
    conditions,
    u_D=(0.0, 0.0),
    mu=None,
    lmbda=None,
    traction=None,
    u_prev=None,
) -> ComplementarityProblem:
    """Linear elasticity (plane strain) on the scene's mesh in UFL: E = 1, ν = 0.3 unless
    ``mu``/``lmbda`` are given, u = ``u_D`` on the parts with role dirichlet, u_k = 0 on
    each symmetry plane x_k = c, the traction ``traction`` on the neumann parts."""
    msh, bnd = scene.mesh, scene.boundary
    V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
    u, v, w = fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
    if mu is None:
        mu, lmbda = lame(1.0, 0.3)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=bnd.tags)
    f = fem.Constant(msh, np.zeros(2))

    def sigma(z):
        e = ufl.sym(ufl.grad(z))
        return 2 * mu * e + lmbda * ufl.tr(e) * ufl.Identity(2)

    L = ufl.inner(f, v) * ufl.dx
    neumann = {}
    for i in bnd.ids_with_role("neumann"):
        neumann[i] = t = fem.Constant(msh, np.asarray(traction, dtype=float))
        L += ufl.inner(t, v) * ds(i)
    bcs, symmetry = [], []
    value = fem.Function(V)
    value.interpolate(lambda x: np.vstack([np.full(x.shape[1], c) for c in u_D]))
    if bnd.ids_with_role("dirichlet"):
        dofs = fem.locate_dofs_topological(V, 1, bnd.facets("dirichlet"))
        bcs.append(fem.dirichletbc(value, dofs))
    for name, role in bnd.roles.items():
        if role == "symmetry":
            facets = bnd.tags.find(bnd.ids[name])
            X = msh.geometry.x[mesh.entities_to_geometry(msh, 1, facets).ravel()]
            k = int(np.argmin(np.ptp(X[:, :2], axis=0))) if len(X) else 0
            k = comm.allreduce(k, op=MPI.MAX)  # every rank: the plane's axis
            S = V.sub(k)
            bcs.append(fem.dirichletbc(0.0, fem.locate_dofs_topological(S, 1, facets), S))
            symmetry.append((bnd.ids[name], k))
    physics = Elasticity(
        mu,
        lmbda,
        f,
        BoundaryData(
            bnd.tags,
            dirichlet=bnd.ids_with_role("dirichlet"),
            neumann=neumann,
            free=bnd.ids_with_role("natural"),
            symmetry=tuple(symmetry),
        ),
    )
    return ComplementarityProblem.from_forms(
        ufl.inner(sigma(w), ufl.sym(ufl.grad(v))) * ufl.dx,
        L,
        u,
        conditions,
        bcs,
        physics=physics,
        u_prev=u_prev,
    )


def contact_ds(scene) -> ufl.Measure:
    ds = ufl.Measure("ds", domain=scene.mesh, subdomain_data=scene.boundary.tags)
    return ds(scene.boundary.ids_with_role("contact"))


def block(**changes) -> dict:
    """An elastic block on a rigid plane (configs/friction_block_2d.yaml at 16 × 4)."""
    scene = {
        "name": "block",
        "constants": {"delta": 0.01, "drag": 0.04},
        "mesh": {"type": "rectangle", "corners": [[-1, 0], [1, 0.5]], "cells": [16, 4]},
        "boundaries": {
            "bottom": {"role": "contact", "where": "y < 1e-10"},
            "top": {"role": "dirichlet", "where": "y > 0.5 - 1e-10"},
        },
        "model": {"type": "elasticity", "E": 1.0, "nu": 0.3},
        "obstacle": {"type": "plane", "point": [0, 0], "normal": [0, 1]},
        "data": {"u_D": ["drag*max(t - 0.2, 0)/0.8", "-delta*min(t/0.2, 1)"]},
        "solver": {"method": "fb", **TIGHT},
        "output": {"verbose": False},
    }
    for key, value in changes.items():
        scene[key] = value
    return scene


def drag(t: float) -> tuple[float, float]:
    """u_D of the block at pseudo-time t."""
    return 0.04 * max(t - 0.2, 0.0) / 0.8, -0.01 * min(t / 0.2, 1.0)


def agree(result, reference, force: bool = True) -> None:
    assert result.converged and reference.converged
    assert result.n_active == reference.n_active > 0
    assert close(result.u_h.x.array, reference.u_h.x.array, 1e-8)
    assert close(result.lmbda_h.x.array, reference.lmbda_h.x.array, 1e-6)
    if force:
        assert abs(result.contact_force - reference.contact_force) <= 1e-7 * abs(
            reference.contact_force
        )


def test_a_tilted_plane():
    """A plane tilted by 0.2 rad: the contact nodes rotated to its normal (u = Q x) from a
    RigidObstacle of own forms as from the scene's obstacle; the residual estimate too."""
    nu = [-np.sin(0.2), np.cos(0.2)]
    scene = contact.load_scene(block(obstacle={"type": "plane", "point": [0, -0.02], "normal": nu}))
    reference = contact.solve(scene)
    obstacle = RigidObstacle(Plane([0.0, -0.02], nu), contact_ds(scene))
    with elastic(scene, obstacle, u_D=drag(1.0)) as problem:
        assert problem.problem.basis is not None  # rotated to the normal
        result = contact.solve(problem, **TIGHT)
        agree(result, reference)
        mine, theirs = contact.estimate(problem, result), contact.estimate(scene, reference)
        assert abs(mine.eta - theirs.eta) <= 1e-7 * theirs.eta
        # the traction-free sides left out of BoundaryData: the residual estimator checks
        # σ(u_h)n = 0 on them all the same
        p = problem.problem
        assert p.physics.boundary.free  # the scene's sides (role natural)
        p.physics = replace(p.physics, boundary=replace(p.physics.boundary, free=()))
        assert contact.estimate(problem, result).eta == pytest.approx(mine.eta, rel=1e-12)


def test_a_mortar_pair():
    """configs/two_body_patch_2d.yaml: two bodies of different materials in one mesh, their
    interface a MortarPair of own forms (DG0 Lamé parameters from the cell tags)."""
    scene = contact.load_scene(
        ROOT / "configs" / "two_body_patch_2d.yaml", ["output.verbose=false", "solver.rtol=1e-12"]
    )
    reference = contact.solve(scene)
    bnd = scene.boundary
    W = fem.functionspace(scene.mesh, ("DG", 0))
    mu, lmbda = fem.Function(W), fem.Function(W)
    for tag, (E, nu) in ((1, (1.0, 0.3)), (2, (3.0, 0.2))):
        cells = scene.bodies.find(tag)
        mu.x.array[cells], lmbda.x.array[cells] = lame(E, nu)
    ds = ufl.Measure("ds", domain=scene.mesh, subdomain_data=bnd.tags)
    pair = MortarPair(ds(bnd.ids["slave"]), ds(bnd.ids["master"]))
    with elastic(scene, [pair], mu=mu, lmbda=lmbda, traction=(0.0, -0.01)) as problem:
        u0 = fem.Function(problem.problem.V)
        u0.interpolate(lambda x: np.vstack([0 * x[0], -1e-4 * (x[1] > 0.5 - 1e-10)]))
        result = contact.solve(problem, u0=u0, **TIGHT)
        agree(result, reference, force=False)
        mine, theirs = contact.estimate(problem, result), contact.estimate(scene, reference)
        assert abs(mine.eta - theirs.eta) <= 1e-6 * theirs.eta


@pytest.mark.parametrize(
    "law, section",
    [
        (Tresca(0.002), {"law": "tresca", "threshold": "0.002"}),
        (Coulomb(0.3), {"law": "coulomb", "coefficient": 0.3}),
    ],
)
def test_friction(law, section):
    """The block dragged over the plane, one step at t = 1: the friction law a part of the
    own forms' RigidObstacle, as in the scene's friction section."""
    scene = contact.load_scene(block(friction=section))
    reference = contact.run_load_path(scene).steps[-1].result
    obstacle = RigidObstacle(Plane([0.0, 0.0], [0.0, 1.0]), contact_ds(scene), friction=law)
    with elastic(scene, obstacle, u_D=drag(1.0)) as problem:
        result = contact.solve(problem, **TIGHT)
        agree(result, reference)
        assert result.friction is not None and reference.friction is not None
        slipping = result.friction["status"] == 2
        assert comm.allreduce(int(slipping.sum())) > 0  # the drag makes nodes slip
        assert np.array_equal(slipping, reference.friction["status"] == 2)
        assert close(result.friction["lambda_t"], reference.friction["lambda_t"], 1e-6)


def test_load_path():
    """Coulomb friction over four load steps: a builder of the problem at t (its Dirichlet
    data at t, the previous step's solution for the slips) through contact.run_load_path."""
    times = [0.25, 0.5, 0.75, 1.0]
    scene = contact.load_scene(
        block(friction={"law": "coulomb", "coefficient": 0.3}, load={"times": times})
    )
    reference = contact.run_load_path(scene, keep_all=True)

    def build(t, u_prev):
        obstacle = RigidObstacle(
            Plane([0.0, 0.0], [0.0, 1.0]), contact_ds(scene), friction=Coulomb(0.3)
        )
        return elastic(scene, obstacle, u_D=drag(t), u_prev=u_prev)

    path = contact.run_load_path(build, times, keep_all=True, **TIGHT)
    assert path.converged and len(path.steps) == len(reference.steps) == 4
    for mine, theirs in zip(path.steps, reference.steps):
        assert mine.time == theirs.time
        agree(mine.result, theirs.result)


def test_a_number_as_the_obstacle():
    """The equilibrated bound of an obstacle problem whose obstacle is a number: the same η as
    with that number as a fem.Constant (the bound as written, a constant)."""
    msh = mesh.create_unit_square(comm, 12, 12)
    edge = mesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
    tags = mesh.meshtags(msh, 1, np.sort(edge), 1)

    def eta(bound) -> float:
        V = fem.functionspace(msh, ("Lagrange", 1))
        u, v, w = fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
        bc = fem.dirichletbc(0.0, fem.locate_dofs_topological(V, 1, edge), V)
        one, f = fem.Constant(msh, 1.0), fem.Constant(msh, 10.0)
        physics = Diffusion(one, f, BoundaryData(tags, dirichlet=(1,)))
        a, L = ufl.inner(ufl.grad(w), ufl.grad(v)) * ufl.dx, f * v * ufl.dx
        cap = Unilateral(bound)
        with ComplementarityProblem.from_forms(a, L, u, cap, [bc], physics=physics) as p:
            result = contact.solve(p, **TIGHT)
            assert result.converged and result.n_active > 0
            return contact.estimate(p, result, kind="equilibrated").eta

    number, constant = eta(0.05), eta(fem.Constant(msh, 0.05))
    assert number > 0 and abs(number - constant) <= 1e-12 * constant


def square_domain(ghost_mode: mesh.GhostMode) -> Domain:
    """The unit square on 8 × 8 cells with the parts of :func:`signorini` (top 1, sides 2,
    bottom 3), created with ``ghost_mode``."""
    msh = mesh.create_unit_square(comm, 8, 8, ghost_mode=ghost_mode)
    parts = (
        lambda x: np.isclose(x[1], 1.0),
        lambda x: np.isclose(x[0], 0.0) | np.isclose(x[0], 1.0),
        lambda x: np.isclose(x[1], 0.0),
    )
    found = [mesh.locate_entities_boundary(msh, 1, where) for where in parts]
    facets = np.concatenate(found)
    values = np.concatenate([np.full(len(f), i, dtype=np.int32) for i, f in enumerate(found, 1)])
    order = np.argsort(facets)
    return Domain(msh, mesh.meshtags(msh, 1, facets[order], values[order]))


def test_a_mesh_without_ghost_cells():
    """The residual estimator's jump terms need the cell across each facet between two ranks:
    on 2 ranks a mesh created with ghost mode none is one ValueError on every rank naming
    the fix, for contact.estimate and for contact.adapt before its first build; the
    equilibrated bound needs no ghosts and is the same on both meshes, as the residual η
    is serially."""
    ids = {"top": 1, "sides": 2, "bottom": 3}
    none, shared = square_domain(mesh.GhostMode.none), square_domain(mesh.GhostMode.shared_facet)
    etas: dict[str, list[float]] = {"residual": [], "equilibrated": []}
    for domain in (none, shared):
        with signorini(domain, ids) as problem:
            result = contact.solve(problem, **TIGHT)
            assert result.converged and result.n_active > 0
            for kind in etas:
                if kind == "residual" and domain is none and comm.size > 1:
                    with pytest.raises(ValueError) as err:
                        contact.estimate(problem, result, kind=kind)
                    message = str(err.value)
                    assert message.startswith("problem: mesh 'mesh' has ") and "\n" not in message
                    assert "ghost_mode=GhostMode.shared_facet" in message and len(message) <= 300
                    continue
                etas[kind].append(contact.estimate(problem, result, kind=kind).eta)
    assert etas["equilibrated"][0] == pytest.approx(etas["equilibrated"][1], rel=1e-9)
    if comm.size == 1:
        assert etas["residual"][0] == pytest.approx(etas["residual"][1], rel=1e-12)
        return
    built: list[Domain] = []

    def build(domain: Domain) -> ComplementarityProblem:
        built.append(domain)
        return signorini(domain, ids)

    with pytest.raises(ValueError, match=r"^domain: mesh 'mesh' has \d+ facet\(s\) between"):
        contact.adapt(build, none, max_levels=2)
    assert built == []
    run = contact.adapt(build, none, kind="equilibrated", max_levels=2, theta=0.5)
    assert len(run.levels) == 2 and run.levels[1].result.converged  # refined: ghosted


def test_loads_left_out_are_zero():
    """A physics that leaves out the zero loads of the sides and the contact part gives the
    residual estimate and the equilibrated bounds of one that declares them: every
    estimator checks the natural condition on the undeclared sides (a contact part's
    traction defaults to the number 0, which the bound evaluates without compiling)."""
    ids = {"top": 1, "sides": 2, "bottom": 3}
    domain = square_domain(mesh.GhostMode.shared_facet)
    etas = []
    for loads in (True, False):
        with signorini(domain, ids, loads) as problem:
            result = contact.solve(problem, **TIGHT)
            etas.append([contact.estimate(problem, result, kind=k).eta for k in KINDS])
    assert etas[1] == pytest.approx(etas[0], rel=1e-12) and min(etas[0]) > 0


def test_on_two_ranks():
    """The tests above on 2 MPI ranks (one mpirun)."""
    proc = pytest_on_ranks(__file__, "not two_ranks", timeout=900)
    out = proc.stdout[-3000:] + proc.stderr[-3000:]
    assert proc.returncode == 0, out
    passed = [line for line in proc.stdout.splitlines() if " passed" in line]
    assert len(passed) == 2, out
