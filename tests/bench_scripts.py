"""A benchmark script of demos/bench imported as a module (demos/bench is not a package),
for the tests of its functions."""

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

BENCH = Path(__file__).resolve().parents[1] / "demos" / "bench"


def load(name: str) -> ModuleType:
    """demos/bench/``name``.py as a module, its ``common`` found while it loads."""
    sys.path.insert(0, str(BENCH))
    try:
        spec = importlib.util.spec_from_file_location(name, BENCH / f"{name}.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(BENCH))
    return module
