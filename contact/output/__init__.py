"""What a run writes: the atomic result folder and its CSV/JSON files (:mod:`.folder`), the
field files (:mod:`.fields`: :mod:`.xdmf`, :mod:`.vtk`), the pictures of one run
(:mod:`.plots`) and of a study (:mod:`.charts`), the output of one run (:mod:`.run_report`)
and of the steps of a load path (:mod:`.step_report`)."""
