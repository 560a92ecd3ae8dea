"""The application: the ``contact`` command line (:mod:`.cli`), parameter studies
(:mod:`.study`), exit codes and how MPI ranks agree on a failure (:mod:`.failures`)."""
