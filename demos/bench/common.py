"""Helpers shared by the benchmark scripts of this folder."""

from __future__ import annotations

import collections
import time
from pathlib import Path

from contact.output.folder import write_csv

from mpi4py import MPI

#: the adaptive loop's phases (functions of contact.drivers.adaptive) and the key each
#: one's CPU seconds add up under (:func:`count_phase_cpu`)
PHASES = {
    "build_problem": "assembly",
    "solve": "solve",
    "estimate": "estimate",
    "solution_error": "error",
    "mark": "mark",
    "refine": "refine",
}
#: where the loop looks each phase up: a scene's level is built and solved by
#: contact.setup.run, estimated, marked and refined by the core's loop (contact.drivers.adaptive)
PHASE_MODULES = {
    "build_problem": "contact.setup.run",
    "solve": "contact.setup.run",
    "estimate": "contact.drivers.adaptive",
    "solution_error": "contact.drivers.adaptive",
    "mark": "contact.drivers.adaptive",
    "refine": "contact.drivers.adaptive",
}


def wrap_phases(wrap) -> None:
    """Replace each of the adaptive loop's phase functions (:data:`PHASES`) in its module by
    ``wrap(fn, key)``, ``key`` its phase's name."""
    import importlib

    for name, key in PHASES.items():
        module = importlib.import_module(PHASE_MODULES[name])
        setattr(module, name, wrap(getattr(module, name), key))


def count_phase_cpu(cpu: dict[str, float] | None = None) -> dict[str, float]:
    """Wrap the adaptive loop's phase functions (:data:`PHASES`) so that their CPU seconds
    add up in ``cpu`` (a new dict if None; keys: the phases' names), which is returned."""
    cpu = collections.defaultdict(float) if cpu is None else cpu

    def timed(fn, key):
        def call(*args, **kwargs):
            c = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                cpu[key] = cpu.get(key, 0.0) + time.process_time() - c

        return call

    wrap_phases(timed)
    return cpu


def save_csv(path: str | Path, rows: list[dict]) -> None:
    """Write the rows (rank 0; the folder is made) and say where."""
    if MPI.COMM_WORLD.rank != 0:
        return
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_csv(out, rows)
    print(f"wrote {out}", flush=True)


def elastic_reference(scene, u_h, refinements: int = 2):
    """The solve of the elastic ``scene`` on its mesh refined uniformly ``refinements`` times
    (2: 4× finer), from ``u_h`` prolonged: a reference for scenes without an exact solution."""
    import contact

    import numpy as np

    for _ in range(refinements):
        n = scene.mesh.topology.index_map(scene.mesh.topology.dim).size_local
        scene, u_h = contact.refine(scene, np.arange(n, dtype=np.int32), u_h)
    return contact.solve(scene, u0=u_h, verbose=False)


def energy_distance(reference, u_h) -> float:
    """|||u_ref − u_h||| = a(e, e)^{1/2} of linear elasticity on the reference's mesh, u_h moved
    there by point location (exact where its mesh is nested in the reference's, linear
    extrapolation in the slivers a snapped curved boundary adds)."""
    from contact.drivers.sequencing import point_transfer

    import numpy as np
    import ufl
    from dolfinx import fem

    data = reference.problem.data
    mu, lam = float(data.mu), float(data.lmbda_L)
    e = reference.u_h - point_transfer(u_h, reference.u_h.function_space)
    eps = ufl.sym(ufl.grad(e))
    energy = fem.form((2 * mu * ufl.inner(eps, eps) + lam * ufl.tr(eps) ** 2) * ufl.dx)
    return float(np.sqrt(MPI.COMM_WORLD.allreduce(fem.assemble_scalar(energy))))
