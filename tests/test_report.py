"""What a run writes (contact.output.report.Report) is read from the scene's configuration
once, by contact.app.dispatch.report_of: the writers take the record and a result, and the
record's fields are the configuration's."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import contact  # noqa: F401  # sets up the DOLFINx libraries
from contact.app.dispatch import report_of
from contact.setup.config import load_config

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_an_adaptive_scene_with_a_reference():
    sets = ["output.png=false", "output.formats=[vtk]", "output.levels=last", "adapt.pictures=2"]
    cfg = load_config(ROOT / "configs" / "hertz_2d.yaml", sets + ["output.verbose=false"])
    report = report_of(cfg)
    assert (report.name, report.model, report.elastic) == ("hertz_2d", "elasticity", True)
    assert (report.formats, report.png, report.levels) == (("vtk",), False, "last")
    assert (report.pictures, report.verbose) == (2, False)
    assert cfg.adapt is not None and report.strategy == cfg.adapt.strategy
    assert report.reference == "hertz" and report.estimator == cfg.estimator
    assert (report.friction, report.tangential_form) == ("none", None)
    with pytest.raises(dataclasses.FrozenInstanceError):
        report.png = True  # type: ignore[misc]


def test_a_scene_without_adapt_and_with_friction():
    cfg = load_config(ROOT / "configs" / "friction_block_2d.yaml")
    report = report_of(cfg)
    assert cfg.adapt is None and (report.strategy, report.pictures) == (None, 3)
    assert cfg.friction is not None and report.friction == cfg.friction.law != "none"
    assert report.tangential_form == cfg.friction.form
    assert report.reference is None and report.formats == tuple(cfg.output.formats)


def test_a_scalar_scene():
    report = report_of(load_config(ROOT / "configs" / "signorini_square.yaml"))
    assert (report.model, report.elastic) == ("signorini", False)
