"""The version of ``contact`` (``contact.__version__``, pyproject.toml's), on the ground floor:
the output folder's marker and ``contact --version`` read it without loading the package's
public API."""

__version__ = "0.1.0"
