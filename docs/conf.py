"""Sphinx configuration of the contact documentation (`make docs`, docs/README.md).

Why Sphinx (not MkDocs): the API reference is generated from the docstrings by autodoc and
napoleon (Google-style Args:/Returns:/Raises:), with one page per public name through
autosummary, and every cross-reference into the package is checked (nitpicky mode) — the
toolchain DOLFINx and scikit-fem use. The pages are Markdown (MyST), so they read on GitHub
as they do on the site, and the demos (jupytext "light" scripts, as DOLFINx's) are turned
into notebooks here and executed by myst-nb at build time, at small sizes, with their
printed output and pictures. Everything runs offline: no intersphinx inventory, no
download.
"""

import os
import re
import sys
from pathlib import Path

import jupytext
import nbformat

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))

project = "contact"
author = "the contact developers"
copyright = "2026, the contact developers"
release = version = "0.1.0"

extensions = [
    "myst_nb",  # Markdown pages (MyST) and the executed demo notebooks
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",  # Google-style docstrings
    "sphinx.ext.mathjax",
]

# The sources: Markdown pages, the theory, the demos' generated notebooks, the API pages.
exclude_patterns = ["_build", "README.md", "Thumbs.db", ".DS_Store", "**.ipynb_checkpoints"]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
root_doc = "index"
templates_path = ["_templates"]

# Every warning is an error in `make docs` (-W --keep-going). Nitpicky mode reports every
# cross-reference that resolves to nothing: a link into the package or between the pages
# that is wrong fails the build. Names of other packages (dolfinx, ufl, PETSc, numpy, the
# standard library) have no inventory offline (no intersphinx), so they are not checked.
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(dolfinx|ufl|basix|petsc4py|PETSc|mpi4py|MPI|numpy|np|npt|pydantic)(\..*)?"),
    (r"py:.*", r"(pathlib|collections|typing|os|types|abc|dataclasses|io|enum)(\..*)?"),
    (r"py:.*", r"(Path|Callable|Sequence|Mapping|Iterable|Iterator|Any|Self|NDArray)"),
    (r"py:class", r"(float|int|str|bool|dict|list|tuple|object|None|type|array-like)"),
    (r"py:.*", r"(optional|default.*|callable|sequence|mapping|number)"),
]
# Internal types that public signatures and fields name but that are not API (not in
# contact.__all__): each is documented in its own module's docstrings.
nitpick_ignore = [
    ("py:class", "contact.setup.scene_config.SceneConfig"),
    ("py:class", "contact.setup.meshes.Boundary"),
    ("py:class", "contact.setup.posed.PosedProblem"),
    ("py:class", "PosedProblem"),
    ("py:class", "contact.solvers.problem.DiscreteProblem"),
    ("py:class", "DiscreteProblem"),
    ("py:class", "contact.solvers.stopping.AdaptiveStopping"),
    ("py:class", "contact.solvers.options.FrictionOptions"),
    ("py:class", "contact.drivers.adaptive.Stowed"),
]
# The validators of the typed options' fields (Annotated[..., BeforeValidator(...)]), which
# autodoc shows with each field's type: functions and constants of contact.base.validation
# and contact.solvers.options, not API.
nitpick_ignore_regex += [
    (r"py:class", r"BeforeValidator|[A-Z_]+|[a-z_]+"),
]

# MyST: $…$ math, definition lists, heading anchors for [text](page.md#anchor) links.
myst_enable_extensions = ["dollarmath", "amsmath", "deflist", "colon_fence"]
myst_heading_anchors = 4
suppress_warnings: list[str] = []

# The API reference: a page per public name of contact.__all__ (docs/api.md).
autosummary_generate = True
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False}
autodoc_typehints = "description"
autodoc_typehints_description_target = "documented"
autodoc_member_order = "bysource"
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
napoleon_attr_annotations = False
napoleon_use_ivar = True  # attributes as a field list: no second object description

# The demos run at build time: a demo that fails fails the build.
nb_execution_mode = "force"
nb_execution_timeout = 600
nb_execution_raise_on_error = True
nb_execution_in_temp = True
nb_merge_streams = True

html_theme = "furo"
html_title = "contact"
html_static_path: list[str] = []

# --- the demos: demos/demo_*.py (jupytext light scripts) -> docs/demos/generated/*.ipynb ---
#: the demos' size argument at build time (the tests' small sizes, tests/test_demos.py)
DEMO_ARGS = {
    "obstacle": "16",
    "signorini_adaptive": "7",
    "hertz": "2",
    "friction": "40",
    "two_bodies": "0.04",
    "large_deformation": "6",
    "curved_indentation": "5",
    "guaranteed_bound": "8",
    "own_forms": "16",
    "torsion": "32",
    "hp": "1e-3",
    "self_contact": "4",
    "self_contact_tube": "4",
}


def demo_notebook(name: str) -> nbformat.NotebookNode:
    """The notebook of demos/demo_<name>.py as the build runs it: a hidden first cell gives
    the script its command line (a small size) and its own path, and turns off interactive
    drawing (the pictures shown are the PNG files the demo writes, displayed by a last cell).
    """
    script = ROOT / "demos" / f"demo_{name}.py"
    nb = jupytext.read(script, fmt="py:light")
    setup = nbformat.v4.new_code_cell(
        "import sys, matplotlib\n"
        f"sys.argv = [{str(script)!r}, {DEMO_ARGS[name]!r}]\n"
        f"__file__ = {str(script)!r}\n"
        "matplotlib.use('Agg')"
    )
    setup.metadata["tags"] = ["remove-cell"]
    show = nbformat.v4.new_code_cell(
        "import glob\n"
        "from IPython.display import Image, display\n"
        "for png in sorted(glob.glob('*.png')):\n"
        "    display(Image(png))"
    )
    show.metadata["tags"] = ["remove-input"]
    note = nbformat.v4.new_markdown_cell(
        f"*Run at build time as `python demos/demo_{name}.py {DEMO_ARGS[name]}` "
        "(a small size; the source's default is larger). The pictures it wrote:*"
    )
    nb.cells = [setup, *nb.cells, note, show]
    nb.metadata["kernelspec"] = {
        "name": "python3",
        "display_name": "Python 3",
        "language": "python",
    }
    return nb


def write_demo_notebooks() -> None:
    out = DOCS / "demos" / "generated"
    out.mkdir(parents=True, exist_ok=True)
    found = sorted(p.stem.removeprefix("demo_") for p in (ROOT / "demos").glob("demo_*.py"))
    missing = set(found) ^ set(DEMO_ARGS)
    if missing:
        raise RuntimeError(f"docs/conf.py DEMO_ARGS and demos/demo_*.py differ: {missing}")
    for name in found:
        target = out / f"demo_{name}.ipynb"
        text = nbformat.writes(demo_notebook(name))
        if not target.exists() or target.read_text() != text:
            target.write_text(text)


def write_results_page() -> None:
    """docs/results.md: demos/RESULTS.md with its links made relative to docs/ — pictures
    shown, files (CSV, scripts, pictures) downloadable, folders named."""
    text = (ROOT / "demos" / "RESULTS.md").read_text()

    def link(m: re.Match) -> str:
        bang, label, target = m.group(1), m.group(2), m.group(3)
        if re.match(r"[a-z]+:|#", target):
            return m.group(0)
        path = (ROOT / "demos" / target).resolve()
        rel = os.path.relpath(path, DOCS)
        if bang:
            return f"![{label}]({rel})"
        if path.is_file():
            return f"{{download}}`{label.replace('`', '')} <{rel}>`"
        return label  # a folder: its name, as written

    text = re.sub(r"(!?)\[([^\]]*)\]\(([^)\s]+)\)", link, text)
    target = DOCS / "results.md"
    if not target.exists() or target.read_text() != text:
        target.write_text(text)


write_demo_notebooks()
write_results_page()
os.environ.setdefault("OMP_NUM_THREADS", "1")
