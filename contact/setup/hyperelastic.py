"""A hyperelastic scene's model (finite strain, :mod:`contact.models.hyperelastic`): the body's
energy, residual and tangent from the scene's law and data, its rigid obstacle as a contact
condition — a plane's nodal bound, or the gap of the deformed point on the current
configuration for a circle or sphere and with friction — built by the same
:func:`~contact.models.forms.make_problem` as a user's own residual."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import ufl
from dolfinx import fem

from ..base import spaces
from ..models.discrete import Problem
from ..models.forms import ResidualProblem, make_problem
from ..models.hyperelastic import (
    deformed_area,
    hyperelastic_forms,
    jacobian_check,
    quadrature_degree,
)
from ..models.physics import lame, piola_and_cauchy
from ..solvers.problem import ProblemData
from .checks import check_scene_data
from .elastic import elastic_physics, elastic_setting, materials, scene_pairs, scene_rigid
from .scene import Scene


def hyperelastic_problem(scene: Scene, coupled_at: np.ndarray | None = None) -> Problem:
    """The contact problem of a hyperelastic body against the scene's rigid obstacle, or of
    several hyperelastic bodies in contact through the scene's mortar pairs
    (:mod:`contact.models.hyperelastic`): R(u; v) and K_T = ∂R/∂u from the energy
    (quadrature of degree 2p; one law, Lamé parameters per body), Π(u) for the energy
    line search, det F checked for admissibility; the obstacle's bound, rotated bound or
    contact on the current configuration (:func:`~contact.models.contacts.contact_set`),
    with the scene's friction law; the pairs coupled on the current configuration of the
    nodal displacements ``coupled_at`` (None: the reference one, as a current configuration:
    a slave node facing no master facet is out of contact, not an error;
    :mod:`contact.drivers.recouple` iterates the coupling to its fixed point)."""
    t0 = time.perf_counter()
    check_scene_data(scene)
    config = scene.config
    model = config.model
    assert model.law is not None  # required by the loader
    body = None
    mu: Any
    lmbda_L: Any
    if config.bodies:  # one material per body (DG0 Lamé parameters)
        mu, lmbda_L, body = materials(scene)
    else:
        assert model.E is not None  # required by the loader for one body
        mu, lmbda_L = lame(model.E, model.nu)
    s = elastic_setting(scene)
    V = s.V
    u_h = spaces.zero_function(V, "u_h")
    v = ufl.TestFunction(V)
    # P1: F is constant per cell, one point is exact; P2: degree 2p for the nonpolynomial ψ
    degree = quadrature_degree(scene.config.mesh.degree)
    R, J, potential = hyperelastic_forms(u_h, model.law, mu, lmbda_L, s.L_ufl, degree)
    F_form, J_form = fem.form(R), fem.form(J)
    law = model.law
    conditions: tuple = scene_pairs(scene, s.data["ds"])
    obstacle = scene_rigid(scene, s.data["ds"]) if config.obstacle is not None else None
    if obstacle is not None:
        conditions += (obstacle,)

    def stresses(u):
        return piola_and_cauchy(u, law, mu, lmbda_L)

    data = ProblemData(
        f=s.data["f"],
        t=s.data["t"],
        ds=s.data["ds"],
        reaction_form=F_form,
        stresses=stresses,
        **({} if body is None else {"body": body, "mu": mu, "lmbda_L": lmbda_L}),
    )
    if obstacle is not None:
        data.deformed_area = fem.form(deformed_area(u_h, v, obstacle.measure))
    if coupled_at is None and config.pairs:
        coupled_at = np.zeros_like(u_h.x.array)
    return make_problem(
        "residual",
        V,
        u_h,
        s.bcs,
        lambda: ResidualProblem.matrices(J_form, s.bcs),
        conditions,
        t0,
        physics=elastic_physics(scene, s, mu, lmbda_L, law=model.law),
        data=data,
        residual={
            "F_form": F_form,
            "J_form": J_form,
            "energy_form": fem.form(potential),
            "min_jacobian": jacobian_check(u_h, degree),
        },
        current=True,
        u_prev=scene.history.get("u_prev"),
        bodies=(scene.bodies, list(config.bodies or ())),
        coupled_at=coupled_at,
    )
