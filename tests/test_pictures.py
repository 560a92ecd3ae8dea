"""Pictures say what they show: every curve of a traction picture is in a legend (both
friction bounds too), 3D pressures are drawn as points with a binned profile (never a line
joining scattered nodal values), a scene's declared exact flux is drawn, and every axis of
the contact pictures names its units."""

import runpy
import sys
from pathlib import Path

import contact
from contact.output import plots
from contact.post.contact_table import contact_columns
from contact.setup.posed import posed_of

import numpy as np
import pytest
from matplotlib.figure import Figure

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def figures(monkeypatch):
    """Every figure saved while the test runs (before the code closes it)."""
    saved: list[Figure] = []
    original = Figure.savefig

    def savefig(self, *args, **kwargs):
        saved.append(self)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return saved


def _legend_texts(fig: Figure) -> set[str]:
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    return {text.get_text() for legend in legends for text in legend.get_texts()}


def _curves(fig: Figure) -> list:
    return [line for ax in fig.axes for line in ax.get_lines()]


def _assert_every_curve_in_a_legend(fig: Figure) -> None:
    texts = _legend_texts(fig)
    for line in _curves(fig):
        label = line.get_label()
        assert not label.startswith("_"), f"a curve without a label ({len(line.get_xdata())} pts)"
        assert label in texts, f"{label!r} is in no legend"


def _assert_units(fig: Figure) -> None:
    for ax in fig.axes:
        for label in (ax.get_xlabel(), ax.get_ylabel()):
            if label:
                assert "(" in label and ("unit" in label or "dimensionless" in label), label


def test_demo_friction_picture_has_every_curve_in_its_legend(figures, tmp_path, monkeypatch):
    """demos/demo_friction.py as a user runs it: its 10 load steps, both friction bounds
    and the slipping nodes each have a legend entry."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", ["demo_friction.py", "24"])
    runpy.run_path(str(ROOT / "demos" / "demo_friction.py"), run_name="__main__")
    assert (tmp_path / "demo_friction.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    (fig,) = figures
    _assert_every_curve_in_a_legend(fig)
    texts = _legend_texts(fig)
    assert sum(t.startswith("t = ") for t in texts) == 10
    assert any("+ρ" in t for t in texts) and any("−ρ" in t for t in texts)
    _assert_units(fig)


def _friction_table(n: int, t: float) -> dict:
    s = np.linspace(0.0, 2.0, n)
    lam_n = -0.02 * t * np.ones(n)
    return {
        "s": s,
        "lambda_n": lam_n,
        "lambda_t": 0.3 * lam_n * t,
        "bound": -0.3 * lam_n,
        "status": np.array(["slip"] * n, dtype=object),
    }


def test_traction_picture_of_many_steps_draws_ten_and_says_so(figures, tmp_path):
    steps = [(t, _friction_table(9, t)) for t in np.linspace(0.04, 1.0, 25)]
    plots.plot_traction(tmp_path / "traction.png", steps, title="many")
    (fig,) = figures
    _assert_every_curve_in_a_legend(fig)
    assert sum(t.startswith("t = ") for t in _legend_texts(fig)) == plots.MAX_TRACTION_CURVES
    assert "10 of 25 load steps drawn" in fig.axes[0].get_title()
    assert plots.drawn_steps(25)[0] == 0 and plots.drawn_steps(25)[-1] == 24


def test_bin_average_of_scattered_values():
    rng = np.random.default_rng(1)
    r = rng.uniform(0.0, 1.0, 4000)
    p = np.sqrt(np.clip(1 - r**2, 0, None)) * (1 + 0.25 * rng.uniform(-1, 1, r.size))
    x, y = plots.bin_average(r, p)
    assert len(x) == 30 and np.all(np.diff(x) > 0)
    assert np.max(np.abs(y - np.sqrt(np.clip(1 - x**2, 0, None)))) < 0.08  # ±25 % scatter


def test_3d_pressure_is_points_and_a_binned_profile(figures, tmp_path):
    """A 3D table (r): the nodal pressures are markers only, and the profile line is the
    bin average, within the scatter's mean of the pressure they scatter about."""
    rng = np.random.default_rng(2)
    r = np.sort(rng.uniform(0.0, 1.0, 300))
    lam = -np.clip(1 - r**2, 0, None) * (1 + 0.2 * rng.uniform(-1, 1, r.size))
    table = {"r": r, "lambda_n": lam, "active": (lam < 0).astype(int)}
    plots.plot_pressure(tmp_path / "pressure.png", table, "lambda_n", title="3D")
    (fig,) = figures
    lines = _curves(fig)
    nodal = [ln for ln in lines if len(ln.get_xdata()) in ((lam < 0).sum(), (lam >= 0).sum())]
    assert nodal and all(ln.get_linestyle() == "None" for ln in nodal)
    (profile,) = [ln for ln in lines if "bins" in ln.get_label()]
    x, y = profile.get_xdata(), profile.get_ydata()
    assert len(x) == 30 and np.max(np.abs(y - np.clip(1 - x**2, 0, None))) < 0.12
    _assert_every_curve_in_a_legend(fig)
    _assert_units(fig)


def test_exact_flux_of_a_declared_solution_is_in_the_table_and_the_picture(figures, tmp_path):
    """Problem A declares u = −r^{3/2} cos(3θ/2): contact.csv gets its flux λ = −(3/2)|x|^{1/2}
    (averaged over each node's support) beside λ_h, and pressure.png draws it."""
    scene = contact.load_scene(
        ROOT / "configs" / "signorini_free_boundary.yaml", ["adapt=none", "mesh.cells=[64,32]"]
    )
    result = contact.solve(scene, verbose=False)
    cols = contact_columns(posed_of(scene), result)
    exact = -1.5 * np.sqrt(np.abs(np.minimum(cols["x"], 0.0)))
    inner = np.abs(cols["x"]) > 0.1  # away from the free boundary's root singularity
    assert np.max(np.abs(cols["lambda_exact"] - exact)[inner]) < 2e-3
    assert np.max(np.abs(cols["lambda"] - cols["lambda_exact"])) < 0.05
    table = {**cols, "s": cols["x"] + 1.0}
    plots.plot_pressure(tmp_path / "pressure.png", table, "lambda", title="A")
    (fig,) = figures
    assert any("exact flux" in t for t in _legend_texts(fig))
    _assert_every_curve_in_a_legend(fig)
    _assert_units(fig)
