"""Models: the pieces of a contact problem a DOLFINx user composes with their own UFL forms,
and that a scene's models build alike (:mod:`contact.setup.build`).

* :mod:`.physics` — the equations a problem discretises (:class:`~.physics.Diffusion`,
  :class:`~.physics.Elasticity`: fluxes, loads, boundary parts, exact solutions), which the
  estimators read;
* :mod:`.constraints` — the contact conditions: :class:`~.constraints.Unilateral`,
  :class:`~.constraints.RigidObstacle` (plane, ball, cylinder, a signed distance),
  :class:`~.constraints.MortarPair`, the friction laws :class:`~.constraints.Tresca` and
  :class:`~.constraints.Coulomb`;
* :mod:`.contacts` — their constraint set on an assembled system (:mod:`.obstacles`: a rigid
  obstacle's nodes and rotations; :mod:`.mortar`, :mod:`.overlap`, :mod:`.basis`: the mortar
  coupling and the change of basis u = Q x; :mod:`.friction`: the tangential unknowns);
* :mod:`.discrete` — :class:`~.discrete.Problem`, the solver's discrete problem with its
  physics and conditions; :mod:`.forms` — the problem of a user's forms
  (:class:`~.forms.ComplementarityProblem`, :func:`~.forms.make_problem` that every builder
  calls) and the residual problems of finite strain; :mod:`.problem` — assembly;
* :mod:`.elasticity`, :mod:`.hyperelastic` — what an elastic body needs beyond its forms (the
  near-nullspace, von Mises, the finite-strain energy and stability).
"""
