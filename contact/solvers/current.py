"""Contact with a rigid obstacle on the current configuration: a gap that is nonlinear in u,
its normal and frame followed at every Newton iterate, and large sliding (issue 31).

Geometry.  The rigid obstacle is its signed distance g(x) (> 0 outside, the body's side),
with the unit normal n(x) = −∇g(x) pointing from x towards the obstacle and its
derivative Dn(x) = −∇∇g(x) (symmetric, n ∈ ker Dn; the curvature of the obstacle's level
set through x):

    plane through p, unit normal ν towards the body:  g = (x − p)·ν,  n = −ν,  Dn = 0;
    circle / sphere, centre c, radius R_o:            g = |x − c| − R_o,
                                                      n = (c − x)/|x − c|,
                                                      Dn = −(I − n nᵀ)/|x − c|.

A contact node i (reference position X_i, displacement u_i) is at x_i = X_i + u_i, so

    a_i(u) = g(X_i + u_i)          (the gap of the deformed point: nonlinear in u),
    ∂a_i/∂u_i = −n_iᵀ,             n_i = n(x_i).

The obstacle's closest point is recomputed from x_i at every evaluation: no pairing of a
node with a place on the obstacle is kept, so a node may slide any distance along it
(large sliding).  Components held by a Dirichlet or symmetry condition stay out of the
normal: ñ_i = P_i n_i / |P_i n_i| (P_i the projector onto the node's free components;
ñ = n when the obstacle is symmetric about the plane), Dñ_i = (I − ñ ñᵀ) P_i Dn_i / |P_i n_i|.

Frame.  F_i = [ñ_i, t_i (, t2_i)] is an orthonormal frame of the *current* normal,
re-computed at every iterate (2D: t = (−ñ_y, ñ_x); 3D: t1 = (ñ × h)/|ñ × h| with the helper
h = e_x, or e_y where |ñ_x| ≥ 0.9, t2 = ñ × t1; a fixed axis e_k is a column of its own,
as in :func:`contact.models.basis.frame`).  Its rate is that of ñ: for a vector v with
frame components ṽ = Fᵀ v,

    d(Fᵀ v) = Fᵀ dv + M(v) dñ,    M(v) rows:  0: vᵀ,
                                              t_k:  −ṽ_0 t_kᵀ + (spin),

the spin term only in 3D with no fixed axis: t2·dt1 = ωᵀ dñ, ω = (h × t2)/|ñ × h|, adding
+ṽ_2 ωᵀ to row t1 and −ṽ_1 ωᵀ to row t2 (exact: the derivative of this frame).

Equations.  The unknowns are the displacements (no change of basis); the change of basis
acts on the *equations*: a contact node's residual block R_i is written in its current
frame, R̃_i = F_iᵀ R_i, and (λ_i, as in the linear model, a force per reference area)

    Φ_i,0 = −(w_i / c_i) φ(a_i, b_i),   b_i = −c_i R̃_i,0 / w_i = c_i p_i   (normal),
    Φ_i,t = R̃_i,t                        (frictionless: no tangential force),

Φ_j = R_j at every other DoF.  With friction (:attr:`DiscreteProblem.friction`), the
tangential rows are those of :mod:`contact.solvers.friction` (HSW / projection,
Tresca / Coulomb) in the current frame: μ_t = −R̃_t / w and the slip

    s_i = F_i,tᵀ (x_i − x_i^prev − Δc) = F_i,tᵀ (u_i − u_i^prev − Δc),

the increment of the deformed position since the previous load step (since the unloaded
start on the first), relative to the obstacle's own translation Δc over the same interval,
along the current tangent plane.

Generalized Jacobian.  With dR̃_i = F_iᵀ K_i du + M(R_i) Dñ_i du_i (K_i the node's rows of
K_T(u)) and the law's derivative S_i = ∂Φ_i/∂R̃_i (bs × bs: φ_b on the normal row, I or
friction's J_μ on the tangential rows, and Coulomb's J_ρ coupling to R̃_0), every contact
node contributes a block row to

    H = B K_T + D,   B_i = S_i F_iᵀ,
                     D_i = S_i M(R_i) Dñ_i + [ (w/c) φ_a nᵀ ;  −w J_s (F_tᵀ + M_t(d_i) Dñ_i)
                                                            − (w F [ξ>0] / c) J_ρ nᵀ ],

d_i = u_i − u_i^prev − Δc (friction only).  S_i M(R_i) Dñ_i is the obstacle's curvature term:
against a circle the tangential row of a node in contact gets p_i w_i / |x − c| times its
tangent (the normal force turns with the normal), which a Jacobian without it misses by a
relative O(p h / (E R_o)) — Newton is then only linearly convergent.  The Jacobian is exact
where Φ is differentiable (tests/test_current_contact.py compares it with finite
differences).  H is not symmetric: the Newton system stays assembled (MUMPS, or BiCGStab).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from . import ncp
from .newton import BlockComplementarity
from .problem import CurrentContact, DiscreteProblem

#: 3D frames take the helper e_y instead of e_x where |ñ_x| reaches this (as basis.frame)
HELPER_SWITCH = 0.9
#: the gap rows' round-off floor in units of ε · (coordinate size) · ‖w / c‖₂
#: (:meth:`CurrentComplementarity.gap_roundoff`; as snes.ROUNDOFF for K x − b)
GAP_ROUNDOFF = 16.0


@dataclass
class NodalGeometry:
    """The obstacle seen from the deformed contact nodes (module doc)."""

    g: np.ndarray  # (k,) gap a_i = g(x_i)
    n: np.ndarray  # (k, d) normal n(x_i) (∂a/∂u = −nᵀ)
    frames: np.ndarray  # (k, d, d) F_i = [ñ t (t2)] in columns
    dn: np.ndarray  # (k, d, d) Dñ_i = dñ/dx
    omega: np.ndarray  # (k, d) the frame's spin (3D, no fixed axis; else 0)


def nodal_geometry(cc: CurrentContact, u: np.ndarray) -> NodalGeometry:
    """:class:`NodalGeometry` at the nodal displacements u (k, gdim)."""
    g, n, Dn = cc.surface.project(cc.X + u)
    free = ~cc.fixed
    Pn = np.where(free, n, 0.0)
    length = np.linalg.norm(Pn, axis=1)
    length = np.where(length > 0, length, 1.0)
    nt = Pn / length[:, None]
    d = n.shape[1]
    tangential = np.eye(d)[None] - nt[:, :, None] * nt[:, None, :]
    dn = tangential @ (free[:, :, None] * Dn) / length[:, None, None]
    frames, omega = frames_and_spin(nt, cc.fixed)
    return NodalGeometry(g, n, frames, dn, omega)


def frames_and_spin(n: np.ndarray, fixed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F, ω): the frames [n t (t2)] (k, d, d) of unit normals n (k, d) with the fixed axes
    of ``fixed`` (k, d) as columns of their own, and the 3D spin vectors ω (module doc)."""
    k, d = n.shape
    F = np.zeros((k, d, d))
    omega = np.zeros((k, d))
    F[:, :, 0] = n
    if d == 2:
        F[:, 0, 1], F[:, 1, 1] = -n[:, 1], n[:, 0]
        return F, omega
    count = fixed.sum(axis=1)
    eye = np.eye(3)
    free3 = count == 0
    h = np.where((np.abs(n[:, 0]) < HELPER_SWITCH)[:, None], eye[0], eye[1])
    v = np.cross(n, h)
    vn = np.linalg.norm(v, axis=1)
    vn = np.where(vn > 0, vn, 1.0)
    t1 = v / vn[:, None]
    first = np.argmax(fixed, axis=1)  # the (first) fixed axis
    t1 = np.where(free3[:, None], t1, eye[first])
    t2 = np.cross(n, t1)
    second = 2 - np.argmax(fixed[:, ::-1], axis=1)  # the last fixed axis (two fixed: e_b)
    t2 = np.where((count == 2)[:, None], eye[second], t2)
    F[:, :, 1], F[:, :, 2] = t1, t2
    omega[free3] = (np.cross(h, t2) / vn[:, None])[free3]
    return F, omega


def frame_rate(v: np.ndarray, geo: NodalGeometry) -> np.ndarray:
    """M(v) (k, d, d) with d(Fᵀ v)|_v = M(v) dñ (module doc), for vectors v (k, d)."""
    F, omega = geo.frames, geo.omega
    vt = np.einsum("kab,ka->kb", F, v)
    M = np.empty_like(F)
    M[:, 0, :] = v
    M[:, 1:, :] = -vt[:, 0, None, None] * F[:, :, 1:].transpose(0, 2, 1)
    if v.shape[1] == 3:
        M[:, 1, :] += vt[:, 2, None] * omega
        M[:, 2, :] -= vt[:, 1, None] * omega
    return M


class CurrentComplementarity(BlockComplementarity):
    """Φ and its generalized Jacobian H = B K_T + D for contact on the current configuration
    (module doc), frictionless or with the friction law of ``problem.friction``; vectorised
    over the contact nodes."""

    #: the curvature term S M(R) Dñ of D (module doc); False drops it (a Jacobian that
    #: misses how the normal turns: kept selectable to measure what it buys)
    curvature = True

    #: reuse the last :meth:`evaluate` at an unchanged iterate (False: the old path, to
    #: measure the gain)
    reuse = True

    def __init__(self, problem: DiscreteProblem):
        super().__init__(problem)
        cc = problem.current
        assert cc is not None, "a problem with contact on the current configuration"
        self.cc, bs = cc, self.bs
        self.rows = (cc.nodes[:, None] * bs + np.arange(bs)).astype(np.int32)  # (k, bs)
        self.fs = problem.friction
        self._last: tuple | None = None  # (x's owned values, c, evaluate's dict)

    def evaluate(self, x: PETSc.Vec) -> dict:
        """Every nodal quantity at x: the geometry, R̃ = Fᵀ R, a, b and (friction) μ_n, ξ, ρ,
        μ_t, the slip s, the tangential law.  The last evaluation is kept: SNES asks for Φ,
        the monitor for the active set and the Jacobian for the law at the same iterate,
        and each would re-assemble R (measured on configs/hyperelastic_sphere.yaml: 147
        residual assemblies for 41 Newton steps, 15 % of the run).  It is reused when x's
        owned values are equal and the NCP scaling c is the same object."""
        last = self._last if self.reuse else None
        if last is not None and last[1] is self.p.c and np.array_equal(last[0], x.array_r):
            u = self.p.u_h.x  # u_h = x, as a residual evaluation leaves it
            self.p.to_displacement(x, u.petsc_vec)
            u.scatter_forward()
            return last[2]
        st = self._evaluate(x)
        self._last = (x.array_r.copy(), self.p.c, st)
        return st

    def _evaluate(self, x: PETSc.Vec) -> dict:
        self.p.residual(x, self.R)
        r = self.R.array_r
        u = x.array_r[self.rows]
        geo = nodal_geometry(self.cc, u)
        R = r[self.rows]
        Rt = np.einsum("kab,ka->kb", geo.frames, R)
        a = geo.g
        b = -self.c * Rt[:, 0] / self.w
        st = {"geo": geo, "R": R, "Rt": Rt, "a": a, "b": b, "r": r, "u": u}
        fs = self.fs
        if fs is None:
            return st
        from .friction import tangential_law

        xi = (b - a) / self.c
        if fs.threshold is None:
            assert fs.coefficient is not None  # a Coulomb set has its coefficient F
            rho = fs.coefficient * np.maximum(xi, 0.0)
        else:
            rho = fs.threshold
        mu_t = -Rt[:, 1:] / self.w[:, None]
        d = u - self.cc.u_prev - self.cc.motion
        s = np.einsum("kat,ka->kt", geo.frames[:, :, 1:], d)
        fs.frames = geo.frames[:, :, 1:]  # the current tangents (friction_fields' vectors)
        law = tangential_law(mu_t, s, rho, fs.c_t, fs.free, fs.options.form)
        st.update(
            mu_n=-Rt[:, 0] / self.w,
            xi=xi,
            rho=rho,
            mu_t=mu_t * fs.free,
            s=s * fs.free,
            d=d,
            law=law,
        )
        return st

    def gap_roundoff(self, x: PETSc.Vec) -> float:
        """The round-off of the gap rows: a_i = g(x_i) subtracts numbers of the size
        s = max_i |x_i| + the surface's scale (|x − c| − R_o against a circle of radius
        R_o = 10⁶ is known to ~10⁻¹⁰ only), and the normal row weighs it by w_i / c_i:
        GAP_ROUNDOFF · ε · s · ‖w / c‖₂ over all ranks (collective).  Without it a scene
        with a large obstacle stalled above the stopping tolerance."""
        comm = self.p.V.mesh.comm
        x_nodes = self.cc.X + x.array_r[self.rows]
        size = float(np.max(np.abs(x_nodes), initial=0.0))
        weight = float(np.sum((self.w / self.c) ** 2))
        size = comm.allreduce(size, op=MPI.MAX) + self.cc.surface.scale
        return GAP_ROUNDOFF * np.finfo(float).eps * size * np.sqrt(comm.allreduce(weight))

    def pair(self, x: PETSc.Vec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(a, b, R) at x: the current gap, the scaled normal multiplier, the residual."""
        st = self.evaluate(x)
        return st["a"], st["b"], st["r"]

    def phi(
        self, x: PETSc.Vec, f: PETSc.Vec, method: str, mu: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """f = Φ(x): R off the contact nodes, their rows in the current frame (module doc)."""
        return self.phi_of(self.evaluate(x), f, method, mu)

    def phi_of(
        self, st: dict, f: PETSc.Vec, method: str, mu: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """f = Φ at the iterate of ``st``, the :meth:`evaluate` just done (its residual R is
        still this object's); returns (a, b)."""
        a, b, Rt = st["a"], st["b"], st["Rt"]
        self.R.copy(f)
        out = f.array_w
        tangential = Rt[:, 1:]
        if self.fs is not None:
            free = self.fs.free
            tangential = np.where(free, -self.w[:, None] * st["law"].C, tangential)
        out[self.rows[:, 0]] = -(self.w / self.c) * ncp.phi(a, b, method, mu)
        out[self.rows[:, 1:]] = tangential
        return a, b

    def block_jacobian(
        self, x: PETSc.Vec, H: PETSc.Mat, method: str, mu: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """H = B K_T(x) + D, the generalized-Jacobian element at x (module doc); returns the
        blocks of B and D."""
        self.p.linearize(x)
        st = self.evaluate(x)
        geo, a, b = st["geo"], st["a"], st["b"]
        w, c = self.w, np.broadcast_to(self.c, self.w.shape)
        tau = self.tie_tolerance(a, b)
        da, db = ncp.dphi(a, b, method, mu, tau)
        k, bs = self.rows.shape
        S = np.tile(np.eye(bs), (k, 1, 1))  # ∂Φ_i / ∂R̃_i
        S[:, 0, 0] = db
        E = np.zeros((k, bs, bs))  # Φ_i's own dependence on u_i (gap, slip)
        E[:, 0, :] = ((w / c) * da)[:, None] * geo.n
        fs = self.fs
        if fs is not None:
            law, free = st["law"], fs.free
            t = slice(1, bs)
            S[:, t, t] = law.J_mu + np.eye(bs - 1)[None] * (~free)[:, :, None]
            Ft = geo.frames[:, :, 1:].transpose(0, 2, 1)  # (k, m, d)
            ds = Ft + frame_rate(st["d"], geo)[:, 1:, :] @ geo.dn
            E[:, t, :] = -w[:, None, None] * (law.J_s @ ds)
            if fs.threshold is None:  # Coulomb: ρ = F max(0, ξ)
                assert fs.coefficient is not None
                gate = fs.coefficient * ncp.active_min(a, b, tau)  # F [ξ > 0]
                S[:, t, 0] = gate[:, None] * law.J_rho
                E[:, t, :] -= ((w * gate / c)[:, None] * law.J_rho)[:, :, None] * geo.n[:, None, :]
        Bv = self.B.identity()
        Dv = np.zeros_like(Bv)
        nodes = self.cc.nodes
        Bv[nodes] = S @ geo.frames.transpose(0, 2, 1)
        Dv[nodes] = E + (S @ frame_rate(st["R"], geo) @ geo.dn if self.curvature else 0.0)
        self.B.set(Bv).matMult(self.p.K, result=H)
        H.axpy(1.0, self.D.set(Dv), structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)  # type: ignore[arg-type]
        return Bv, Dv

    def destroy(self) -> None:
        self._last = None  # holds a view of R's array
        super().destroy()
