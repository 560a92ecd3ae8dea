"""Open a result folder of `contact run` in ParaView with a sensible view.

The body warped by its displacement and coloured by the von Mises stress (elasticity; the
solution u_h otherwise), and the contact surface (contact_surface.xdmf) warped the same
way and coloured by the contact pressure; the last level or load step. In 3D the camera
looks at the contact zone from below and aside, across the symmetry planes of a quarter
model, where the stress under the contact shows.

In the ParaView GUI: View → Python Shell → Run Script, after setting RESULT below, or

    pvpython docs/paraview/view_result.py results/hertz_3d            # an interactive window
    xvfb-run pvpython docs/paraview/view_result.py results/hertz_3d shot.png   # a screenshot

Checked with ParaView 5.11 (Debian's `paraview` package). Options: --scale S multiplies
the displacement (default 1: the true deformation).
"""

import argparse
import os
import sys

from paraview import simple as pv

RESULT = "results/hertz_3d"  # the folder to open when run from the GUI's Python shell


def _last_time(source):
    times = list(source.TimestepValues) if source.TimestepValues else [0.0]
    return times[-1]


def _range(source, name, association="POINTS"):
    data = source.PointData if association == "POINTS" else source.CellData
    return data[name].GetRange(-1) if name in data.keys() else (0.0, 0.0)


def _contact_zone(surface, name, t):
    """Centre and radius of the nodes whose pressure is above 1 % of its peak (3D)."""
    from paraview import servermanager
    from vtk.numpy_interface import dataset_adapter as dsa

    data = dsa.WrapDataObject(servermanager.Fetch(surface))
    points = data.Points
    if points is None or name not in data.PointData.keys():
        return None
    import numpy as np

    points = (
        np.vstack([np.asarray(a) for a in points.Arrays])
        if hasattr(points, "Arrays")
        else np.asarray(points)
    )
    values = data.PointData[name]
    values = (
        np.concatenate([np.asarray(a).ravel() for a in values.Arrays])
        if hasattr(values, "Arrays")
        else np.asarray(values).ravel()
    )
    pressed = values > 0.01 * values.max() if values.max() > 0 else values > np.inf
    if not pressed.any():
        return None
    centre = points[pressed].mean(axis=0)
    radius = float(np.linalg.norm(points[pressed] - centre, axis=1).max())
    return centre, radius


def show(folder, screenshot=None, scale=1.0, size=(1000, 700)):
    """Open ``folder``'s solution.xdmf and contact_surface.xdmf; optionally save a PNG."""
    body = pv.Xdmf3ReaderT(
        registrationName="body", FileName=[os.path.join(folder, "solution.xdmf")]
    )
    view = pv.GetActiveViewOrCreate("RenderView")
    t = _last_time(body)
    view.ViewTime = t
    body.UpdatePipeline(t)
    bounds = body.GetDataInformation().GetBounds()
    warped = pv.WarpByVector(registrationName="body warped", Input=body, Vectors=["POINTS", "u_h"])
    warped.ScaleFactor = scale
    shown = pv.Show(warped, view)
    if "von_mises" in body.CellData.keys():
        pv.ColorBy(shown, ("CELLS", "von_mises"))
        lut = pv.GetColorTransferFunction("von_mises")
        lut.ApplyPreset("Cool to Warm", True)
        bar = pv.GetScalarBar(lut, view)
        bar.Title, bar.ComponentTitle = "von Mises stress (units of E)", ""
    else:
        pv.ColorBy(shown, ("POINTS", "u_h", "Magnitude"))
    shown.RescaleTransferFunctionToDataRange(True, False)
    shown.SetScalarBarVisibility(view, True)

    zone = None
    surface_file = os.path.join(folder, "contact_surface.xdmf")
    if os.path.exists(surface_file):
        surface = pv.Xdmf3ReaderT(registrationName="contact surface", FileName=[surface_file])
        surface.UpdatePipeline(t)
        name = "pressure" if "pressure" in surface.PointData.keys() else "flux"
        lifted = pv.WarpByVector(
            registrationName="contact surface warped", Input=surface, Vectors=["POINTS", "u_h"]
        )
        lifted.ScaleFactor = scale
        drawn = pv.Show(lifted, view)
        pv.ColorBy(drawn, ("POINTS", name))
        lut = pv.GetColorTransferFunction(name)
        lut.ApplyPreset("Inferno (matplotlib)", True)
        drawn.RescaleTransferFunctionToDataRange(True, False)
        drawn.SetScalarBarVisibility(view, True)
        drawn.LineWidth = 4.0  # a 2D Γ_C is a line
        pv.GetScalarBar(lut, view).Title = f"contact {name} (units of E)"
        if bounds[5] - bounds[4] > 0:
            zone = _contact_zone(lifted, name, t)
        if zone is not None:  # drawn a hair towards the camera: no fight with the body's faces
            import numpy as np

            towards = np.array([-1.0, -1.0, -1.3]) / np.linalg.norm([-1.0, -1.0, -1.3])
            moved = pv.Transform(registrationName="contact surface drawn", Input=lifted)
            moved.Transform.Translate = list(0.01 * zone[1] * towards)
            pv.Hide(lifted, view)
            drawn = pv.Show(moved, view)
            pv.ColorBy(drawn, ("POINTS", name))
            drawn.LookupTable = lut
            drawn.SetScalarBarVisibility(view, True)
            drawn.Ambient, drawn.Diffuse = 1.0, 0.0  # the colour map's colours, unshaded
    view.ViewSize = list(size)
    view.OrientationAxesVisibility = 1
    pv.ResetCamera(view)
    if zone is not None:  # 3D: the contact zone from below and aside, a few radii across
        import numpy as np

        centre, radius = zone
        direction = np.array([-1.0, -1.0, -1.3]) / np.linalg.norm([-1.0, -1.0, -1.3])
        camera = view.GetActiveCamera()
        camera.SetFocalPoint(*centre)
        camera.SetPosition(*(centre + 12.0 * radius * direction))
        camera.SetViewUp(0.0, 0.0, 1.0)
        view.CenterOfRotation = list(centre)
    note = f"{os.path.basename(os.path.normpath(folder))}: t = {t:g}, displacement x {scale:g}"
    text = pv.Text(registrationName="title", Text=note)
    pv.Show(text, view).FontSize = 14
    pv.Render(view)
    if screenshot:
        pv.SaveScreenshot(screenshot, view, ImageResolution=list(size), TransparentBackground=0)
    return view


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", nargs="?", default=RESULT, help="a result folder")
    parser.add_argument("screenshot", nargs="?", help="write this PNG and quit")
    parser.add_argument("--scale", type=float, default=1.0, help="displacement scale factor")
    args = parser.parse_args(argv)
    if not os.path.exists(os.path.join(args.folder, "solution.xdmf")):
        sys.exit(f"view_result: no solution.xdmf in {args.folder!r}")
    show(args.folder, args.screenshot, args.scale)
    if not args.screenshot and sys.argv[0].endswith(".py"):  # pvpython: a window of its own
        pv.Interact()  # (in the GUI's Python shell the view is the GUI's)


if __name__ == "__main__":
    main(sys.argv[1:] if sys.argv[0].endswith(".py") else [])
