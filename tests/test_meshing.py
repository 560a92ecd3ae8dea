"""Meshing the parametric gmsh scenes and the 3D Hertz peak pressure (issue 29): gmsh's HXT
tetrahedra are repeatable, of fair shape, the same on 1 and 2 ranks, and keep the sphere on
a block within 2 % of Hertz; half_disks meshed a surface per thread gives the one-thread
mesh; the worst angle of structured meshes is known exactly; the patch average of the
nodal pressures reproduces a constant, is the same on 1 and 2 ranks, and brings the peak
pressure on Dörfler-refined tetrahedra within 2 % of Hertz where the nodal maximum is 6 %
off."""

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from unittest import mock

import contact
from contact.post.hertz import patch_average
from contact.post.reference import compare
from contact.setup import geometry
from contact.setup.build import build_problem
from contact.setup.posed import posed_of

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"
SPHERE = ROOT / "configs" / "two_body_hertz_3d.yaml"
SMALL_BLOCK = dict(radius=1.0, block=[1.0, 1.0], h=0.25, h_contact=0.02, zone=0.15)


def _sorted_vertices(X: np.ndarray) -> np.ndarray:
    return X[np.lexsort(X.T[::-1])]


def test_worst_angle_of_structured_meshes():
    """Right triangles of a 2 × 1 rectangle: atan(1/2); of the unit square: 45°; Kuhn's
    tetrahedra of a cube: 45° (their dihedral angles are 45°, 60° and 90°)."""
    comm = MPI.COMM_WORLD
    rectangle = dmesh.create_rectangle(comm, [np.zeros(2), np.array([2.0, 1.0])], [1, 1])
    square, cube = dmesh.create_unit_square(comm, 4, 4), dmesh.create_unit_cube(comm, 2, 2, 2)
    assert geometry.worst_angle(rectangle) == pytest.approx(math.degrees(math.atan(0.5)), abs=1e-10)
    assert geometry.worst_angle(square) == pytest.approx(45.0, abs=1e-10)
    assert geometry.worst_angle(cube) == pytest.approx(45.0, abs=1e-10)


def test_tetrahedra_are_repeatable_and_of_fair_shape():
    """The builder meshes twice to the same vertices (HXT on one thread; on two, its mesh
    changes from run to run), no dihedral angle below 10° (measured 13.5–15.7°)."""
    first, _, _ = geometry.sphere_on_block(MPI.COMM_WORLD, **SMALL_BLOCK)
    second, _, _ = geometry.sphere_on_block(MPI.COMM_WORLD, **SMALL_BLOCK)
    assert np.array_equal(_sorted_vertices(first.geometry.x), _sorted_vertices(second.geometry.x))
    assert geometry.worst_angle(first) > 10.0


def test_half_disks_on_two_threads_give_the_one_thread_mesh():
    """Each half-disk on its own thread: exactly the triangles of one thread."""
    args = dict(comm=MPI.COMM_WORLD, radius=8.0, radius2=8.0, h=1.0, h_contact=0.05, zone=1.0)
    assert geometry.TRIANGLES["Mesh.MaxNumThreads2D"] == 2
    threads, _, _ = geometry.half_disks(**args)
    with mock.patch.dict(geometry.TRIANGLES, {"Mesh.MaxNumThreads2D": 1}):
        serial, _, _ = geometry.half_disks(**args)
    assert threads.topology.index_map(2).size_global == serial.topology.index_map(2).size_global
    assert np.array_equal(_sorted_vertices(threads.geometry.x), _sorted_vertices(serial.geometry.x))


def test_hxt_mesh_keeps_hertz_accuracy():
    """The sphere on a block on HXT's mesh at h_contact = 0.01 (14k DoFs, one solve): the
    contact radius and the peak pressure within 2 % of Hertz (measured −0.5 % and +0.3 %)."""
    overrides = ["output.verbose=false", "adapt=null", "mesh.h_contact=0.01"]
    scene = contact.load_scene(SPHERE, overrides)
    result = contact.solve(scene, method="fb", verbose=False)
    assert result.converged
    values = compare(posed_of(scene), result).values
    assert abs(values["a_error"]) < 0.02 and abs(values["p0_error"]) < 0.02, values


def test_patch_average_removes_the_scatter_of_refined_tetrahedra():
    """two_body_hertz_3d as shipped, three Dörfler levels (to 71k DoFs): the nodal pressures
    on the refined tetrahedra scatter, their maximum 6 % above Hertz's p0; the largest
    patch average, the reported p0, is within 2 % (measured −0.1 %), and so is a."""
    scene = contact.load_scene(SPHERE, ["output.verbose=false", "adapt.max_levels=3"])
    values = []
    contact.adapt(
        scene,
        method="fb",
        verbose=False,
        on_level=lambda level: values.append(compare(level.posed, level.result).values),
    )
    last = values[-1]
    assert len(values) == 3 and last["p0_nodal_error"] > 0.04, last
    assert abs(last["p0_error"]) < 0.02 and abs(last["a_error"]) < 0.02, last
    reported = (1 + last["p0_error"]) * last["hertz_p0"]
    assert last["peak_pressure_patch"] == pytest.approx(reported, rel=1e-12)


def test_patch_average_of_a_constant_is_the_constant():
    scene = contact.load_scene(SPHERE, ["output.verbose=false", "adapt=null"])
    problem = build_problem(scene)
    try:
        slave = problem.constraint.dofs[: problem.data.pair_nodes]
        nodes = slave // problem.V.dofmap.index_map_bs
        assert len(nodes) > 100
        averaged = patch_average(posed_of(scene), problem.V, nodes, np.full(len(nodes), 2.5))
        assert np.allclose(averaged, 2.5, rtol=1e-14)
    finally:
        problem.destroy()


SCRIPT = """
import json, sys
import numpy as np
import contact
from mpi4py import MPI
from contact.setup import geometry
from contact.post.reference import compare
from contact.setup.posed import posed_of
msh, _, _ = geometry.sphere_on_block(MPI.COMM_WORLD, **json.loads(sys.argv[1]))
nodes = np.unique(geometry.vertex_nodes(msh)[: msh.topology.index_map(3).size_local])
X = msh.geometry.x[nodes[nodes < msh.geometry.index_map().size_local]]
X = np.vstack(msh.comm.gather(X, root=0) or [np.zeros((0, 3))])
scene = contact.load_scene(sys.argv[2],
                           ["output.verbose=false", "adapt=null", "mesh.h_contact=0.01"])
values = compare(posed_of(scene), contact.solve(scene, method="fb", verbose=False)).values
if msh.comm.rank == 0:
    np.save(sys.argv[3], X)
    print(json.dumps({"ranks": msh.comm.size, "cells": msh.topology.index_map(3).size_global,
                      "p0_error": values["p0_error"], "p0_nodal_error": values["p0_nodal_error"]}))
"""


@pytest.mark.mpi
def test_same_mesh_and_peak_pressure_on_one_and_two_ranks(tmp_path):
    """gmsh meshes on rank 0 only: 2 ranks hold the serial mesh (the same vertices), and the
    patch average, which sums facets across the ranks' boundaries, the same p0."""
    runs = []
    for n in (1, 2):
        command = [
            str(MPIRUN),
            "-n",
            str(n),
            sys.executable,
            "-c",
            SCRIPT,
            json.dumps(SMALL_BLOCK),
            str(SPHERE),
            str(tmp_path / f"X{n}.npy"),
        ]
        proc = subprocess.run(
            command,
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=600,
            env={**os.environ, "OMP_NUM_THREADS": "1"},
        )
        assert proc.returncode == 0, proc.stderr
        runs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    serial, parallel = runs
    assert parallel["ranks"] == 2 and parallel["cells"] == serial["cells"]
    X1, X2 = (np.load(tmp_path / f"X{n}.npy") for n in (1, 2))
    assert np.array_equal(_sorted_vertices(X1), _sorted_vertices(X2))
    for key in ("p0_error", "p0_nodal_error"):
        assert parallel[key] == pytest.approx(serial[key], abs=1e-7), key
