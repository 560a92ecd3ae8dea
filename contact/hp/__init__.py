"""hp-adaptivity (docs/theory.md §11): a degree p_T per cell, the space V_hp ⊂ P_{p_max} with
the minimum rule as the change of basis u = Q x (:mod:`.space`, :mod:`.reference`), the
scalar Signorini problem in it (:mod:`.problem`)."""
