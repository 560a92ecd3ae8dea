"""Frictional contact rows and their generalized Jacobian (docs/theory.md §1.4): which rows, which
nonsmooth function, which element of its generalized derivative.  How the Newton system is
then solved is :mod:`contact.solvers.linear`'s business.

Per contact node (the data of :class:`contact.solvers.problem.FrictionSet`), with the
normal quantities of :mod:`contact.solvers.newton` (gap a = σ(g − x_n), b = c μ_n,
μ_n = −λ_n = −σ R_n / w, the normal NCP φ ∈ {fb, min, blend}) and

    μ_t = −λ_t = −R_t / w,   s = x_t − x_t^prev,   z = μ_t + c_t s,
    ρ = s(x, t)  (Tresca)   or   ρ = F·max(0, ξ),  ξ = μ_n − a / c = (b − a) / c  (Coulomb)

(ξ = μ_n + c_n (u_n − g) of docs/theory.md §1.4 with c_n = 1/c; ξ = μ_n at a solution in contact,
ξ < 0 where the node separates), the tangential equation is, in one of two forms,

    projection (Alart–Curnier):  C = μ_t − P_B(ρ)(z) = 0,   P_B(ρ)(z) = z min(1, ρ/|z|),
    hsw (Hüeber–Stadler–Wohlmuth): max(ρ, |z|) μ_t − ρ z = 0.

Rows.  The tangential rows of Φ are  Φ_t = −w C  (force units, like the normal rows
Φ_n = −σ (w/c) φ(a, b)); where ρ = 0 this is Φ_t = R_t, the row of a free node (the
projection onto B(0) = {0} gives μ_t = 0).  The hsw row is divided by max(ρ, |z|) at each
Newton point: a row scaling evaluated at the same point for Φ and for its Jacobian, so
the Newton step is HSW's, while ‖Φ‖ is the same quantity as for the projection form
(max(ρ,|z|) μ_t − ρ z = max(ρ,|z|) C).  At ρ = 0 HSW's row degenerates (z = 0 solves it
for any μ_t); both forms then use μ_t = 0.

Generalized Jacobian.  With  dC = J_μ dμ_t + J_s ds + J_ρ dρ  (per node, m×m, m×m, m):

=========  ==============  ==========================  ==================
state      J_μ             J_s                          J_ρ
=========  ==============  ==========================  ==================
stick      0               −c_t I                       0
(|z| < ρ)
slip, AC   I − M           −c_t M                       −ẑ
slip, HSW  (1 − ρ/|z|) I   c_t (μ̃_t ẑᵀ − ρ I)/|z|       −ẑ
           + μ̃_t ẑᵀ/|z|
ρ = 0      I               0                            −ẑ (0 if z = 0)
=========  ==============  ==========================  ==================

with ẑ = z/|z| and M = (ρ/|z|)(I − ẑ ẑᵀ) (the derivative of the projection; 0 in 2D).
The two forms differ only in the slip block: HSW has μ̃_t = ρ μ_t / max(ρ, |μ_t|) (the
current multiplier, projected onto the ball: HSW's own modification of the exact element
of their max form) where the projection has P(z) = ρ ẑ; both are equal at a solution.
Without HSW's modification (μ̃_t = μ_t) Newton cycled on the pulled block of the tests
(50 iterations without convergence, fb and min); with it, hsw converges where the
projection's element 2-cycles: from a frictionless initial guess the projection form flips
every node between sliding left and right (the linear all-slip problem it solves moves the
block the other way), HSW's element turns such a node back to stick (Newton steps from the
frictionless solution of a partial-slip drag, plain Newton: hsw 8, projection no
convergence in 50; the default ``line_search: auto`` catches the cycle and backtracks,
:class:`GuardedFriction`).
A node with |z| ≥ (1 − 10⁻¹¹) ρ, ρ > 0, counts as slipping (``SLIP_TIE``): a node that ended
the previous load step on the friction bound starts the next one (s = 0, z = μ_t^prev)
sliding on in the same direction.  With the exact tie rule round-off in |μ_t^prev| − ρ
decided, and a steadily sliding block took 8 Newton steps per load step instead of 1
(10⁻⁸, 10⁻¹⁰, 10⁻¹¹ and 10⁻¹² all give 1; the tie moves λ_t by at most 10⁻¹¹ ρ).  For Coulomb,
dρ = F·[ξ > 0] (dμ_n + σ dx_n / c) couples the tangential rows to the node's normal row
([ξ > 0]: 0 at ξ = 0, and where |b − a| = c|ξ| is within the tie tolerance τ of
:meth:`~contact.solvers.newton.Complementarity.tie_tolerance`, as the normal element and
the node's status: a cold start on a plane has every a_i ≈ ±10⁻¹⁸, b_i = 0).  With
dμ_t = −dR_t / w and ds = dx_t, every contact node contributes a small block to

    H = B K + D,   B_tt = J_μ,  D_tt = −w J_s,  B_tn = σ F [ξ>0] J_ρ,  D_tn = −w σ F [ξ>0] J_ρ / c,
                   B_nn = ∂_b φ,  D_nn = (w/c) ∂_a φ,

B and D identity / zero on every other node: two node-block matrices, one sparse product
``B.matMult(K)`` (its symbolic phase reused) and one ``axpy`` of D per Newton step; no loop
over nodes.  Components fixed by a symmetry or Dirichlet condition keep their rows
(``free`` masks them out of |z| and of the blocks).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from . import ncp
from .globalize import FRICTION_STALL, Guarded
from .newton import SEPARATED, SLIP, STICK, BlockComplementarity
from .problem import DiscreteProblem, FrictionSet
from .result import Result

FORMS = ("projection", "hsw")
SLIP_TIE = 1e-11  # |z| ≥ (1 − SLIP_TIE) ρ counts as slip (module doc)
STATUS_NAMES = {SEPARATED: "separated", STICK: "stick", SLIP: "slip"}


@dataclass
class TangentialLaw:
    """C and its derivative element (J_μ, J_s, J_ρ) per node, and the node's state."""

    C: np.ndarray  # (n, m)  μ_t − P_B(ρ)(z)
    J_mu: np.ndarray  # (n, m, m)
    J_s: np.ndarray  # (n, m, m)
    J_rho: np.ndarray  # (n, m)
    stick: np.ndarray  # (n,) bool: |z| < (1 − SLIP_TIE) ρ


def tangential_law(
    mu_t: np.ndarray,
    s: np.ndarray,
    rho: np.ndarray,
    c_t: np.ndarray,
    free: np.ndarray,
    form: str = "projection",
) -> TangentialLaw:
    """The tangential equation C = μ_t − P_B(ρ)(μ_t + c_t s) = 0 and the generalized-
    derivative element of ``form`` (see the module doc), vectorised over nodes.  Components
    with ``free`` False are absent (zero in z, C and the blocks)."""
    if form not in FORMS:
        raise ValueError(f"unknown tangential form {form!r}; expected one of {', '.join(FORMS)}")
    mask = free.astype(float)
    mu_t, s = mu_t * mask, s * mask
    n, m = mu_t.shape
    z = mu_t + c_t[:, None] * s
    znorm = np.linalg.norm(z, axis=1)
    positive = rho > 0
    stick = positive & (znorm < rho * (1.0 - SLIP_TIE))
    slip = positive & ~stick
    safe = np.where(znorm > 0, znorm, 1.0)
    zhat = z / safe[:, None]
    P = np.where(stick[:, None], z, np.where(slip[:, None], rho[:, None] * zhat, 0.0))
    C = mu_t - P
    eye = np.eye(m)[None, :, :] * np.ones((n, 1, 1))
    pair = mask[:, :, None] * mask[:, None, :]  # free × free entries only
    ratio = np.where(slip, rho / safe, 0.0)[:, None, None]
    if form == "projection":
        M = ratio * (eye - zhat[:, :, None] * zhat[:, None, :])
        J_mu_slip, J_s_slip = eye - M, -c_t[:, None, None] * M
    else:  # HSW's modification: μ_t in the rank-one term projected onto B(ρ)
        mu_b = (
            mu_t
            * (rho / np.maximum(np.maximum(rho, np.linalg.norm(mu_t, axis=1)), 1e-300))[:, None]
        )
        outer = mu_b[:, :, None] * zhat[:, None, :] / safe[:, None, None]
        J_mu_slip = (1.0 - ratio) * eye + outer
        J_s_slip = c_t[:, None, None] * (outer - ratio * eye)
    J_mu = np.where(stick[:, None, None], 0.0, np.where(slip[:, None, None], J_mu_slip, eye)) * pair
    J_s = (
        np.where(
            stick[:, None, None],
            -c_t[:, None, None] * eye,
            np.where(slip[:, None, None], J_s_slip, 0.0),
        )
        * pair
    )
    J_rho = np.where(stick[:, None], 0.0, -zhat) * mask
    return TangentialLaw(C * mask, J_mu, J_s, J_rho, stick)


class FrictionalComplementarity(BlockComplementarity):
    """The normal NCP of :class:`~contact.solvers.newton.Complementarity` and the
    tangential rows of the friction law, at an iterate x (vectorised over nodes)."""

    def __init__(self, problem: DiscreteProblem):
        super().__init__(problem)
        fs = problem.friction
        assert fs is not None, "a frictional problem"
        self.fs = fs
        self.nodes = self.dofs // self.bs
        self.threshold = fs.threshold  # Tresca's ρ (the fixed point replaces it)
        self.coulomb = fs.law == "coulomb" and self.threshold is None

    def evaluate(self, x: PETSc.Vec) -> dict:
        """Every nodal quantity at x: a, b, μ_n, ξ, ρ, μ_t, s and the tangential law."""
        fs = self.fs
        a, b, r = self.pair(x)
        mu_n = -self.sign * r[self.dofs] / self.w
        xi = (b - a) / self.c
        if self.coulomb:
            assert fs.coefficient is not None  # a Coulomb set has its coefficient F
            rho = fs.coefficient * np.maximum(xi, 0.0)
        else:
            assert self.threshold is not None  # Tresca's threshold s(x)
            rho = self.threshold
        mu_t = -r[fs.tangent] / self.w[:, None]
        s = x.array_r[fs.tangent] - fs.x_prev
        law = tangential_law(mu_t, s, rho, fs.c_t, fs.free, fs.options.form)
        return {
            "a": a,
            "b": b,
            "mu_n": mu_n,
            "xi": xi,
            "rho": rho,
            "mu_t": mu_t * fs.free,
            "s": s * fs.free,
            "law": law,
        }

    def phi(
        self, x: PETSc.Vec, f: PETSc.Vec, method: str, mu: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """f = Φ(x): R on free rows, the normal NCP rows and Φ_t = −w C on tangential rows."""
        return self.phi_of(self.evaluate(x), f, method, mu)

    def phi_of(
        self, st: dict, f: PETSc.Vec, method: str, mu: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """f = Φ at the iterate of ``st``, the :meth:`evaluate` just done (its residual R is
        still this object's); returns (a, b)."""
        a, b = st["a"], st["b"]
        self.R.copy(f)
        out = f.array_w
        out[self.dofs] = -self.sign * (self.w / self.c) * ncp.phi(a, b, method, mu)
        free = self.fs.free
        out[self.fs.tangent[free]] = (-self.w[:, None] * st["law"].C)[free]
        return a, b

    def block_jacobian(
        self, x: PETSc.Vec, H: PETSc.Mat, method: str, mu: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """H = B K + D, the generalized-Jacobian element at x (module doc), K = K_T(x) the
        tangent at x (of a nonlinear residual: a hyperelastic pair); returns the blocks of B
        and D, (local nodes, bs, bs) each."""
        self.p.linearize(x)
        fs, st = self.fs, self.evaluate(x)
        law = st["law"]
        tau = self.tie_tolerance(st["a"], st["b"])  # kinks of φ and of ρ = F·max(0, ξ)
        da, db = ncp.dphi(st["a"], st["b"], method, mu, tau)
        Bv, Dv = self.B.identity(), np.zeros((self.B.local_nodes, self.bs, self.bs))
        nodes, k, t = self.nodes, fs.n_comp, fs.t_comps
        rows = (nodes[:, None, None], t[None, :, None], t[None, None, :])
        Bv[nodes, k, k] = db
        Dv[nodes, k, k] = (self.w / self.c) * da
        eye = np.eye(fs.m)[None] * (~fs.free)[:, :, None]  # fixed components keep R
        Bv[rows] = law.J_mu + eye
        Dv[rows] = -self.w[:, None, None] * law.J_s
        if self.coulomb:
            assert fs.coefficient is not None  # a Coulomb set has its coefficient F
            gate = self.sign * fs.coefficient * ncp.active_min(st["a"], st["b"], tau)  # [ξ > 0]
            Bv[nodes[:, None], t[None, :], k] = gate[:, None] * law.J_rho
            Dv[nodes[:, None], t[None, :], k] = -(self.w * gate / self.c)[:, None] * law.J_rho
        self.B.set(Bv).matMult(self.p.K, result=H)
        H.axpy(1.0, self.D.set(Dv), structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)  # type: ignore[arg-type]
        return Bv, Dv


class GuardedFriction(Guarded):
    """``line_search: auto`` of a frictional solve (any normal φ, either tangential form):
    plain Newton steps until a cycle shows, then backtracking on ½‖Φ‖² (the rules of
    :mod:`contact.solvers.globalize`).  The piece of Φ at x is every contact node's state
    (separated, stick, slip); a state set seen before tells a cycle only if ‖Φ‖ has not
    fallen below FRICTION_STALL times its value at that visit."""

    label, seen = "friction", "its stick/slip set was seen before, |Phi| not halved since"
    stall = FRICTION_STALL

    def piece(self, x: PETSc.Vec) -> np.ndarray:
        cp = self.cp
        assert isinstance(cp, BlockComplementarity)  # friction's or .current's
        st = cp.evaluate(x)  # once: Φ and the states from the same evaluation
        cp.phi_of(st, self.F, self.method, self.mu)
        status = cp.status(x, st)
        return np.concatenate([status == SEPARATED, status == SLIP])


def friction_fields(problem: DiscreteProblem, cp: BlockComplementarity, x: PETSc.Vec) -> dict:
    """Nodal results of a frictional solve (owned contact nodes): λ_n, λ_t (n, m), ρ, the
    slip increment s (n, m), the status, the gap, the weights w, and λ_t, s as vectors in
    global axes (n, gdim); on the current configuration also the nodes' current normals
    (``normals``, n, gdim), along which λ_n acts.  ``cp``: :class:`FrictionalComplementarity`, or
    :class:`contact.solvers.current.CurrentComplementarity` with friction (its tangents
    those of the last evaluation)."""
    fs = problem.friction
    assert fs is not None, "a frictional problem"
    st = cp.evaluate(x)
    status = cp.status(x, st)
    lam_t = -st["mu_t"]
    out = {} if "geo" not in st else {"normals": st["geo"].frames[:, :, 0]}
    return out | {
        "lambda_n": -st["mu_n"],
        "lambda_t": lam_t,
        "rho": np.asarray(st["rho"], dtype=float),
        "slip": st["s"],
        "status": status,
        "gap": st["a"],
        "lambda_t_vec": tangential_vector(fs, lam_t),
        "slip_vec": tangential_vector(fs, st["s"]),
        "w": cp.w,
    }


def status_counts(comm: MPI.Comm, status: np.ndarray) -> dict[str, int]:
    """Global numbers of separated / stick / slip contact nodes."""
    return {
        name: comm.allreduce(int(np.sum(status == code)), op=MPI.SUM)
        for code, name in STATUS_NAMES.items()
    }


def tangential_vector(fs: FrictionSet, values: np.ndarray) -> np.ndarray:
    """Nodal tangential components (n, m) → vectors in global axes (n, gdim): Σ_j v_j t_j."""
    return np.einsum("nij,nj->ni", fs.frames, np.where(fs.free, values, 0.0))


def surface_functions(result: Result) -> list[fem.Function]:
    """Nodal fields for the VTK output: λ_t and the slip increment (vectors in global axes,
    on the displacement space), the status (0 separated, 1 stick, 2 slip; −1 off Γ_C) and the
    friction bound ρ (on the scalar output space)."""
    p, fr = result.problem, result.friction
    if fr is None:
        raise ValueError("friction fields of a frictionless result")
    V, con = p.V, p.constraint
    bs = V.dofmap.index_map_bs
    nodes = con.dofs // bs
    out = []
    for name, values in (("lambda_t", fr["lambda_t_vec"]), ("slip", fr["slip_vec"])):
        fn = fem.Function(V, name=name)
        fn.x.array[(nodes[:, None] * bs + np.arange(values.shape[1])).ravel()] = values.ravel()
        fn.x.scatter_forward()
        out.append(fn)
    for name, values, off in (
        ("status", fr["status"].astype(float), -1.0),
        ("bound", fr["rho"], 0.0),
    ):
        fn = fem.Function(V)
        fn.x.array[:] = off
        fn.x.array[con.dofs] = values
        fn.x.scatter_forward()
        S = p.output.space or V
        scalar = fem.Function(S, name=name)
        scalar.x.array[:] = fn.x.array if p.output.map is None else fn.x.array[p.output.map]
        out.append(scalar)
    return out
