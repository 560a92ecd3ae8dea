"""Drivers: they take a scene and run solves — one solve (the problem, its initial guess by
grid sequencing, :mod:`.sequencing`), the adaptive loop SOLVE → ESTIMATE → MARK → REFINE
(:mod:`.adaptive`) and quasi-static load paths (:mod:`.load_path`)."""
