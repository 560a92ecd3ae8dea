"""ESTIMATE, MARK, REFINE (docs/theory.md §5, §6, §9): the residual estimator
(:mod:`.estimate`), the equilibrated-flux bound (:mod:`.equilibration`), the true error against an
exact solution (:mod:`.energy_error`), functions and tags carried to a refined
mesh (:mod:`.transfer`).  The loop that runs them is :mod:`contact.drivers.adaptive`."""
