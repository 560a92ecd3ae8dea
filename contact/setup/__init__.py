"""From a YAML file to a :class:`~contact.setup.scene.Scene`: the configuration and its
one-line errors (:mod:`.config`), expressions (:mod:`.expressions`), data checked on the
mesh (:mod:`.checks`), the DoF budget (:mod:`.budget`), meshes (:mod:`.meshes`, gmsh and
the parametric bodies of :mod:`.geometry`), the declared curved boundaries refinement
snaps to (:mod:`.surfaces`), and the scene itself (:mod:`.scene`)."""
