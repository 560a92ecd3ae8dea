"""A hyperelastic scene's model (finite strain, :mod:`contact.models.hyperelastic`): the body's
energy, residual and tangent from the scene's law and data, its rigid obstacle as a contact
condition — a plane's nodal bound, or the gap of the deformed point on the current
configuration for a circle or sphere and with friction — built by the same
:func:`~contact.models.forms.make_problem` as a user's own residual."""

from __future__ import annotations

import time

import ufl
from dolfinx import fem

from ..models.discrete import Problem
from ..models.elasticity import lame
from ..models.forms import ResidualProblem, make_problem
from ..models.hyperelastic import (
    deformed_area,
    hyperelastic_forms,
    jacobian_check,
    quadrature_degree,
)
from ..models.physics import piola_and_cauchy
from .checks import check_scene_data
from .elastic import elastic_physics, elastic_setting, scene_rigid
from .scene import Scene


def hyperelastic_problem(scene: Scene) -> Problem:
    """The contact problem of a hyperelastic body against the scene's rigid obstacle
    (:mod:`contact.models.hyperelastic`): R(u; v) and K_T = ∂R/∂u from the energy
    (quadrature of degree 2p), Π(u) for the energy line search, det F checked for
    admissibility; the obstacle's bound, rotated bound or contact on the current
    configuration (:func:`~contact.models.contacts.contact_set`), with the scene's friction
    law."""
    t0 = time.perf_counter()
    check_scene_data(scene)
    model = scene.config.model
    assert model.E is not None and model.law is not None  # required by the loader
    mu, lmbda_L = lame(model.E, model.nu)
    s = elastic_setting(scene)
    V = s.V
    u_h = fem.Function(V, name="u_h")
    v = ufl.TestFunction(V)
    # P1: F is constant per cell, one point is exact; P2: degree 2p for the nonpolynomial ψ
    degree = quadrature_degree(scene.config.mesh.degree)
    R, J, potential = hyperelastic_forms(u_h, model.law, mu, lmbda_L, s.L_ufl, degree)
    F_form, J_form = fem.form(R), fem.form(J)
    law = model.law
    obstacle = scene_rigid(scene, s.data["ds"])

    def stresses(u):
        return piola_and_cauchy(u, law, mu, lmbda_L)

    data = {
        **s.data,
        "exact": None,
        "reaction_form": F_form,
        "stresses": stresses,
        "law": model.law,
        "deformed_area": fem.form(deformed_area(u_h, v, obstacle.measure)),
    }
    return make_problem(
        "residual",
        V,
        u_h,
        s.bcs,
        lambda: ResidualProblem.matrices(J_form, s.bcs),
        (obstacle,),
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
    )
