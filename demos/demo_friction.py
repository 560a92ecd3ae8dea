# # Coulomb friction: a block pressed onto a plane and dragged along it
#
# This demo shows frictional contact by semismooth Newton (docs/theory.md §1.4).  An elastic block
# $\Omega = [-1, 1] \times [0, 0.5]$ (plane strain, $E = 1$, $\nu = 0.3$) rests on the rigid
# plane $y = 0$.  Over a quasi-static load path $t \in (0, 1]$ its top is first pressed
# down, then moved sideways.  On the contact part $\Gamma_C$ (the bottom) the multiplier
# has a normal part $\lambda_n \le 0$ (the pressure) and a tangential part $\lambda_t$
# (the traction on the body), and Coulomb's law bounds it by $\rho = F\,(-\lambda_n)$:
#
# $$ |\lambda_t| \le \rho, \qquad |\lambda_t| < \rho \Rightarrow s_t = 0 \ \text{(stick)},
#    \qquad |\lambda_t| = \rho \Rightarrow \lambda_t = -\rho\, s_t/|s_t| \ \text{(slip)}, $$
#
# where $s_t = u_t - u_t^{\rm prev}$ is the slip increment of the load step.  The solver
# writes this law as a nonsmooth equation per contact node (Hüeber–Stadler–Wohlmuth, with
# $\mu_t = -\lambda_t$, $z = \mu_t + c_t s_t$):
#
# $$ \max(\rho, |z|)\,\mu_t - \rho\, z = 0, $$
#
# next to the normal complementarity function (here `min`), and solves both with one
# semismooth Newton method whose generalized Jacobian is $H = B K + D$, $B$ and $D$
# block-diagonal over the contact nodes.
#
# What you see: the stick zone shrinking as the drag grows, then full sliding, where the
# total tangential force is exactly $F$ times the normal force; the Tresca fixed point
# (a sequence of problems with a given bound) giving the same solution; and a picture of
# the tractions along $\Gamma_C$ at every step.
#
# Run it with `python demos/demo_friction.py [N]` (N × N/4 cells, N = 80 by default; a few
# seconds, also under `mpirun -n 2`).  It prints the steps, Coulomb's force law at full
# sliding and the fixed-point check, and writes `demo_friction.png`.

# +
import sys

import contact
from contact.output.plots import plot_traction
from contact.post.contact_table import contact_table
from contact.post.friction_resultants import surface_figures

import numpy as np
from mpi4py import MPI

N = int(sys.argv[1]) if len(sys.argv) > 1 else 80
comm = MPI.COMM_WORLD


def say(*args):
    if comm.rank == 0:
        print(*args, flush=True)


# -

# ## The scene
#
# The scene is a plain mapping with the keys of a scene file (`configs/friction_block_2d.yaml`
# is the same scene).  Data expressions may use the pseudo-time `t`: the top is pressed by
# `delta` over $t \in (0, 0.2]$ and dragged by `drag` over $t \in (0.2, 1]$; the `load`
# section asks for 10 equal steps, each starting from the previous solution.

# +
scene_data = {
    "name": "demo_friction",
    "constants": {"delta": 0.01, "drag": 0.04},
    "mesh": {"type": "rectangle", "corners": [[-1, 0], [1, 0.5]], "cells": [N, N // 4]},
    "boundaries": {
        "bottom": {"role": "contact", "where": "y < 1e-10"},
        "top": {"role": "dirichlet", "where": "y > 0.5 - 1e-10"},
    },
    "model": {"type": "elasticity", "E": 1.0, "nu": 0.3},
    "obstacle": {"type": "plane", "point": [0, 0], "normal": [0, 1]},
    "data": {"u_D": ["drag*max(t - 0.2, 0)/0.8", "-delta*min(t/0.2, 1)"]},
    "friction": {"law": "coulomb", "coefficient": 0.3},  # tangential form: hsw (default)
    "load": {"steps": 10},
    "solver": {"method": "min"},
    "output": {"verbose": False},
}
scene = contact.load_scene(scene_data)
# -

# ## The load path
#
# `run_load_path` solves step after step and hands each step to `on_step` as it is done
# (a step before the last keeps only its figures afterwards: a path may be long).  Every
# `Result` carries the nodal friction fields (`result.friction`: $\lambda_n$, $\lambda_t$,
# the bound $\rho$, the slip increment and the status 0 separated / 1 stick / 2 slip).
# `surface_figures` sums them into forces: $F_n = \sum_i w_i \lambda_{n,i}$,
# $F_t = \sum_i w_i \lambda_{t,i}$ with the lumped weights $w_i = \int_{\Gamma_C} \varphi_i$.

# +
tables = []  # (t, contact table) of every step, for the picture below


def show(step):
    tables.append((step.time, contact_table(step.posed, step.result)))
    fig = surface_figures(step.posed, step.result)
    say(
        f"{step.index:5d} {step.time:5.2f} {step.result.iterations:7d} {fig['stick_nodes']:7d} "
        f"{fig['slip_nodes']:6d} {fig['friction_ratio']:11.6f}"
    )


say(" step     t  Newton   stick   slip   F_t / F_n")
path = contact.run_load_path(scene, on_step=show)
fig = surface_figures(path.steps[-1].posed, path.steps[-1].result)
say(
    f"at t = 1 every node slides: |F_t| / |F_n| = {fig['friction_ratio']:.10f} (F = 0.3); "
    f"the support's reaction balances the contact force to "
    f"{abs(fig['reaction_force'][0] + fig['contact_force'][0]):.1e}"
)
# -

# ## An independent check: the fixed point on the pressure
#
# Coulomb friction is a Tresca problem whose bound is the (unknown) pressure times $F$.
# Solving Tresca problems with $\rho^k = F(-\lambda_n^{k-1})^+$ until the bound stops
# changing is slower but independent of the coupled Newton method.  Both solve the load path
# in one step here (from u = 0 to t = 1) and reach the same solution.

# +
newton = contact.solve(contact.load_scene({**scene_data, "load": {"steps": 1}}))
fixed = contact.solve(
    contact.load_scene(
        {
            **scene_data,
            "load": {"steps": 1},
            "friction": {"law": "coulomb", "coefficient": 0.3, "coulomb": "fixed_point"},
        }
    )
)
diff = comm.allreduce(float(np.max(np.abs(newton.u_h.x.array - fixed.u_h.x.array))), op=MPI.MAX)
diff /= comm.allreduce(float(np.max(np.abs(newton.u_h.x.array))), op=MPI.MAX)
say(
    f"one step to t = 1: Newton {newton.iterations} iterations, fixed point "
    f"{fixed.friction['fixed_point_iterations']} Tresca solves ({fixed.iterations} Newton "
    f"iterations); max |u_newton - u_fixed| / max |u| = {diff:.1e}"
)
# -

# ## The tractions along Γ_C
#
# `demo_friction.png`: the pressure $-\lambda_n$ and the tangential traction $\lambda_t$
# along the bottom (against the arc length s from its left end) at every step (colour = $t$),
# the friction bound $\pm\rho$ of the last step dashed, slipping nodes circled.
# `contact run configs/friction_block_2d.yaml` writes the same picture as `traction.png`,
# with the VTK series of the steps and a contact CSV per step.

# +
if comm.rank == 0:
    plot_traction("demo_friction.png", tables, title="demo_friction: tractions along the bottom")
say("wrote demo_friction.png")
# -
