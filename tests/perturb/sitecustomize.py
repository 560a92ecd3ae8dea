"""Test-only switch: ``CONTACT_TEST_PERTURB=ε`` multiplies the assembled load b of every
model by (1 + ε ξ), ξ ∈ [−1, 1) a hash of the DoF's coordinates, its component and the
seed (so the same perturbed problem on any number of ranks), on the rows without a
Dirichlet condition (so the prescribed values and the initial guess still
agree): the problem every solver sees then differs from the unperturbed one by a relative
ε, far below its tolerances, and a test that passes only on one rounding of b asserts a
path, not a property.

tests/conftest.py loads this file in the pytest process and puts its folder first on
PYTHONPATH, where Python imports it at start-up as ``sitecustomize``: so ``contact run``
subprocesses and ``mpirun`` ranks of the suite are perturbed alike.  Nothing in the package
knows of it: an import hook wraps ``contact.models.problem.assemble_system`` when that
module is first executed, before the models import the name.  ``CONTACT_TEST_PERTURB_SEED``
changes the seed (default 20261125).
"""

from __future__ import annotations

import functools
import importlib.abc
import os
import sys

TARGET = "contact.models.problem"


def perturbed(assemble_system, eps: float, seed: int):
    """``assemble_system`` with its b multiplied by (1 + ε ξ) off the Dirichlet rows."""

    @functools.wraps(assemble_system)
    def wrapper(a, L, bcs):

        K, b = assemble_system(a, L, bcs)
        xi = _hash(L.function_spaces[0], seed)[: b.getLocalSize()]
        for bc in bcs:
            dofs = bc.dof_indices()[0]
            xi[dofs[dofs < len(xi)]] = 0.0
        b.array[:] *= 1.0 + eps * xi
        return K, b

    return wrapper


def _hash(V, seed: int):
    """ξ_i ∈ [−1, 1) per owned DoF: a hash of its node's coordinates (rounded to 1e-9, so
    the same on every partition), its component and ``seed``."""
    import numpy as np

    bs = V.dofmap.index_map_bs
    n = V.dofmap.index_map.size_local
    X = np.round(V.tabulate_dof_coordinates()[:n], 9)
    node = X @ np.array([12.9898, 78.233, 37.719]) + 1e-3 * seed
    keys = (node[:, None] + 4.1 * np.arange(bs)[None, :]).ravel()
    return 2.0 * np.modf(np.abs(np.sin(keys) * 43758.5453))[0] - 1.0


class _Hook(importlib.abc.MetaPathFinder):
    """Wraps assemble_system as soon as ``contact.models.problem`` has been executed."""

    def __init__(self, eps: float, seed: int):
        self.eps, self.seed = eps, seed

    def find_spec(self, name, path, target=None):
        if name != TARGET:
            return None
        sys.meta_path.remove(self)
        try:
            import importlib.util

            spec = importlib.util.find_spec(name)
        finally:
            sys.meta_path.insert(0, self)
        loader, eps, seed = spec.loader, self.eps, self.seed
        exec_module = loader.exec_module

        def patched(module):
            exec_module(module)
            module.assemble_system = perturbed(module.assemble_system, eps, seed)

        loader.exec_module = patched
        return spec


def install() -> float:
    """Install the hook if CONTACT_TEST_PERTURB is set (a second call does nothing);
    returns ε (0 when unset)."""
    eps = float(os.environ.get("CONTACT_TEST_PERTURB") or 0.0)
    if eps == 0.0 or any(isinstance(f, _Hook) for f in sys.meta_path):
        return eps
    if TARGET in sys.modules:
        raise RuntimeError(f"CONTACT_TEST_PERTURB: {TARGET} was imported before the hook")
    sys.meta_path.insert(
        0, _Hook(eps, int(os.environ.get("CONTACT_TEST_PERTURB_SEED", "20261125")))
    )
    return eps


install()
