"""Shared test helpers, and the test-only perturbation of the load (tests/perturb)."""

import importlib.util
import os
from pathlib import Path

PERTURB = Path(__file__).resolve().parent / "perturb"
if os.environ.get("CONTACT_TEST_PERTURB"):
    # this process, and every Python subprocess of the suite (PYTHONPATH → sitecustomize)
    _spec = importlib.util.spec_from_file_location(
        "contact_test_perturb", PERTURB / "sitecustomize.py"
    )
    _spec.loader.exec_module(importlib.util.module_from_spec(_spec))
    os.environ["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(PERTURB), os.environ.get("PYTHONPATH")) if p
    )


def make_square_msh(path: Path, size: float) -> Path:
    """Write a gmsh mesh of the unit square with facet groups bottom 1, top 2, sides 3 and
    the surface group 10 (mesh size ``size``)."""
    import gmsh

    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("square")
        surface = gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
        gmsh.model.occ.synchronize()
        groups: dict[str, list[int]] = {"bottom": [], "top": [], "sides": []}
        for dim, tag in gmsh.model.getBoundary([(2, surface)], oriented=False):
            _, y, _ = gmsh.model.occ.getCenterOfMass(dim, tag)
            groups["bottom" if y < 1e-8 else "top" if y > 1 - 1e-8 else "sides"].append(tag)
        for tag, name in ((1, "bottom"), (2, "top"), (3, "sides")):
            gmsh.model.addPhysicalGroup(1, groups[name], tag, name=name)
        gmsh.model.addPhysicalGroup(2, [surface], 10, name="body")
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


def make_quarter_disk_msh(
    path: Path, radius: float = 1.0, h: float = 0.15, h_contact: float = 0.02
) -> Path:
    """Write a gmsh mesh of the quarter {x ≥ 0, y ≤ R} of the disk of radius R about (0, R)
    — a user's mesh of the Hertz cylinder: facet groups arc 1 (through the origin), top 2,
    axis x = 0 3, surface 10; mesh size ``h_contact`` at the origin growing to ``h``."""
    import gmsh

    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("disk")
        occ, R = gmsh.model.occ, radius
        bottom, centre, corner = (
            occ.addPoint(0, 0, 0, h_contact),
            occ.addPoint(0, R, 0, h),
            occ.addPoint(R, R, 0, h),
        )
        arc = occ.addCircleArc(bottom, centre, corner)
        top, axis = occ.addLine(corner, centre), occ.addLine(centre, bottom)
        surface = occ.addPlaneSurface([occ.addCurveLoop([arc, top, axis])])
        occ.synchronize()
        for tag, curve in ((1, arc), (2, top), (3, axis)):
            gmsh.model.addPhysicalGroup(1, [curve], tag)
        gmsh.model.addPhysicalGroup(2, [surface], 10)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path
