"""MARK (docs/theory.md §6): the cells whose indicators η_T carry the error.

By Dörfler's bulk criterion, the maximum criterion, or all of them — the same cells on any
number of MPI ranks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from dolfinx import fem
from mpi4py import MPI

STRATEGIES = ("dorfler", "maximum", "uniform")
#: indicators within this relative distance of the marking threshold count as equal to it:
#: mirror-image cells differ by round-off, and by the solver's tolerance, that depend on the
#: partition (CG + GAMG solves: η_T² near the threshold up to 2e-8 apart on 1 and 3 ranks)
MARK_RTOL = 1e-6


#: ``fraction`` marking may add up to this share more cells than asked, to cut at a gap
SNAP_WINDOW = 0.25
#: indicators within this share of max η_T of the cut are one class with it: all or none are
#: marked (perturbations of the load or the model move η_T by more than round-off, and a cut
#: inside such a class would move the marked set with them)
CLASS_ATOL = 1e-8


def dorfler_threshold(
    eta_sq: np.ndarray, theta: float, comm: MPI.Comm = MPI.COMM_WORLD, fraction: float = 0.0
) -> float:
    """Return the global threshold τ of Dörfler (bulk) marking.

    The set {η_T² ≥ τ} is the smallest set M with Σ_M η_T² ≥ θ Σ_T η_T² (ties at τ are all
    included). With ``fraction`` f > 0 it has at least ⌈f N⌉ of the N cells; where that
    count decides, the cut is moved to the widest relative gap η_j/η_{j+1} of the sorted
    indicators among the next ``SNAP_WINDOW`` · f N cells (:func:`snap_to_gap`): a cut at a
    fixed count falls inside a cluster of nearly equal indicators, and a perturbation that
    Dörfler's threshold ignores would move the marked set.

    The owned indicators of all ranks are gathered on rank 0, sorted once there and τ is
    broadcast: every rank marks against the same global threshold (no per-rank sorting).
    """
    parts = comm.gather(np.asarray(eta_sq, dtype=float), root=0)
    tau = None
    if parts is not None:  # rank 0
        values = np.sort(np.concatenate(parts))[::-1]
        cumulative = np.cumsum(values)
        if len(values) == 0 or cumulative[-1] <= 0:
            tau = np.inf
        elif theta >= 1.0:
            tau = float(values[-1])  # everything
        else:
            k = int(np.searchsorted(cumulative, theta * cumulative[-1] * (1 - 1e-14)))
            share = math.ceil(fraction * len(values)) - 1  # the share of the cells
            if share > k:
                k = snap_to_gap(np.sqrt(values), share, SNAP_WINDOW)
            tau = float(values[min(k, len(values) - 1)])
    return comm.bcast(tau, root=0)


def snap_to_gap(eta: np.ndarray, k: int, window: float) -> int:
    """Return the index j ∈ [k, k + window·(k + 1)] of the widest relative gap after it.

    Args:
        eta: the indicators η_T ≥ 0 sorted descending.
        k: the index of the last cell a count-based cut would mark.
        window: how many more cells (a share of k + 1) may be marked to cut at a gap.

    Returns:
        j maximising η_j / η_{j+1} (the cut between a cluster of nearly equal indicators and
        the next, so that perturbations smaller than the gap leave the set alone); the
        first such j on ties; the last index if the window reaches the end.
    """
    last = len(eta) - 1
    if k >= last:
        return last
    hi = min(last, k + math.ceil(window * (k + 1)))
    head, tail = eta[k:hi], eta[k + 1 : hi + 1]
    # relative gaps, with the class tolerance: differences ≤ CLASS_ATOL·max are no gap
    floor = CLASS_ATOL * eta[0]
    gap = np.where(head - tail > floor, (head - tail) / np.maximum(head, floor), 0.0)
    if not np.any(gap > 0):
        return hi
    return k + int(np.argmax(gap))


def mark(
    eta_T: fem.Function, strategy: str = "dorfler", theta: float = 0.5, fraction: float = 0.0
) -> np.ndarray:
    """Choose the cells to refine from the indicators η_T (the MARK step).

    Values within a relative ``MARK_RTOL`` (1e-6) below the threshold are marked too:
    cells that are equal up to round-off and solver tolerance (symmetric ones, whose η_T
    differ by ~1e-16 depending on how the partition summed them, and by ~1e-8 where the
    partition changed GAMG's aggregates) are treated alike, so the refined meshes are the
    same on any number of MPI ranks; so are, for ``dorfler``, the values within
    ``CLASS_ATOL`` · max η_T (1e-8) of the cut's √τ (a cut among small indicators). Collective.

    Args:
        eta_T: The DG0 indicators of :func:`contact.estimate` (``Estimate.eta_T``).
        strategy: ``dorfler``: the smallest set M with Σ_M η_T² ≥ θ Σ η_T² (one global
            threshold); ``maximum``: the cells with η_T ≥ θ max η_T (global maximum);
            ``uniform``: every cell.
        theta: θ ∈ (0, 1] of ``dorfler`` and ``maximum``.
        fraction: ``dorfler`` marks at least this share f ∈ [0, 1] of the cells, those of
            largest η_T, cut at the widest gap of the sorted η_T within ``SNAP_WINDOW``
            (25 %) more cells (``Growth`` chooses f so that each level's DoFs grow by a
            factor); 0: Dörfler's set alone.

    Returns:
        The owned local indices of the marked cells (int32), as :func:`contact.refine`
        takes them.

    Raises:
        ValueError: For an unknown strategy, θ outside (0, 1], or indicators that are not
            finite numbers ≥ 0 (a NaN would mark no cell).

    Example:
        >>> import contact
        >>> scene = contact.load_scene("configs/signorini_free_boundary.yaml", ["adapt=none"])
        >>> est = contact.estimate(scene, contact.solve(scene, verbose=False))
        >>> cells = contact.mark(est.eta_T, "dorfler", theta=0.5)
        >>> 0 < len(cells) < scene.mesh.topology.index_map(2).size_local
        True
    """
    _check_mark_args(eta_T, strategy, theta)
    real = isinstance(fraction, (int, float)) and not isinstance(fraction, bool)
    if not real or not 0 <= fraction <= 1:
        raise ValueError(f"fraction: must be a number in [0, 1], got {fraction!r}")
    W = eta_T.function_space
    comm = W.mesh.comm
    n_owned = W.dofmap.index_map.size_local
    eta = eta_T.x.array[:n_owned]
    bad = comm.allreduce(int(np.count_nonzero(~np.isfinite(eta) | (eta < 0))), op=MPI.SUM)
    if bad:  # a NaN is never >= a threshold: nothing would be marked, silently
        total = W.dofmap.index_map.size_global
        raise ValueError(
            f"eta_T: {bad} of {total} indicators are not finite numbers >= 0 "
            "(NaN, inf or negative); mark needs the indicators of contact.estimate"
        )
    if strategy == "uniform":
        return np.arange(n_owned, dtype=np.int32)
    if strategy == "maximum":
        top = comm.allreduce(float(eta.max(initial=0.0)), op=MPI.MAX)
        return np.flatnonzero(eta >= theta * top * (1 - MARK_RTOL)).astype(np.int32)
    tau = dorfler_threshold(eta**2, theta, comm, fraction)
    if not math.isfinite(tau):
        return np.zeros(0, dtype=np.int32)
    # the class of the cut: within a relative MARK_RTOL of τ, or CLASS_ATOL·max η_T of √τ
    top = comm.allreduce(float(eta.max(initial=0.0)), op=MPI.MAX)
    cut = min(tau * (1 - MARK_RTOL), max(0.0, math.sqrt(tau) - CLASS_ATOL * top) ** 2)
    return np.flatnonzero(eta**2 >= cut).astype(np.int32)


def _check_mark_args(eta_T: Any, strategy: Any, theta: Any) -> None:
    if not isinstance(eta_T, fem.Function):
        raise ValueError(
            f"eta_T: expected the DG0 indicator function of contact.estimate, got "
            f"{type(eta_T).__name__}"
        )
    if strategy not in STRATEGIES:
        raise ValueError(
            f"strategy: unknown marking strategy {strategy!r}; expected one of "
            f"{', '.join(STRATEGIES)}"
        )
    if isinstance(theta, bool) or not isinstance(theta, (int, float)) or not 0 < theta <= 1:
        raise ValueError(f"theta: must be a number in (0, 1], got {theta!r}")


@dataclass
class Growth:
    """Marking for a DoF growth: each level has at least ``factor`` times its parent's DoFs.

    The loop's cost is the sum of its levels' costs, each about proportional to its DoFs:
    when the DoFs grow by a factor g ≥ 2 per level, the sum is at most g/(g − 1) times the
    last level's, and the number of levels is O(log N).  Dörfler's set alone grows a
    smooth solution's mesh by ~1.7× per level (θ = 0.5) and a singular one's by much less.
    The cells of largest η_T are added to Dörfler's set until they make up the share

        f = (g − 1) / ρ,   ρ = (N_{k+1}/N_k − 1) / f_k,

    of the cells, ρ the DoFs a marked share of the cells adds, as observed on the last
    refinement (its conforming closure included), at first 2^d − 1 (uniform refinement:
    f = 1 gives 2^d times the DoFs).

    Attributes:
        factor: g ≥ 1; 1: Dörfler's set alone.
        rate: ρ, the relative DoF increase per marked share of the cells (None: 2^d − 1).
    """

    factor: float = 2.0
    rate: float | None = None

    def fraction(self, dim: int) -> float:
        """Return the share f ∈ [0, 1] of the cells to mark on a mesh of dimension ``dim``."""
        if self.factor <= 1:
            return 0.0
        rate = self.rate if self.rate is not None else 2**dim - 1.0
        return min(1.0, (self.factor - 1) / rate)

    def observe(self, marked: float, dofs: int, new_dofs: int) -> None:
        """Learn ρ from a refinement.

        Args:
            marked: the share of the cells it marked.
            dofs: the DoFs before it.
            new_dofs: the DoFs after it.
        """
        if marked > 0 and new_dofs > dofs:
            self.rate = (new_dofs / dofs - 1) / marked
