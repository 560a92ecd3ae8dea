"""Quantities computed from a solve: resultants and reactions (:mod:`.resultants`), the
contact table of ``contact.csv`` (:mod:`.contact_table`), friction on Γ_C
(:mod:`.friction_resultants`), a multi-body interface (:mod:`.interface`), and comparisons
with declared references (:mod:`.reference`:
:mod:`.hertz`, :mod:`.cattaneo`, :mod:`.comparison`)."""
