"""The documentation site's sources (docs/README.md): README.md stays what a visitor needs
and every link of it into the site resolves (file and heading), every public name has a
reference page, every demo is rendered, every guide page is in the guide's table of
contents, and the docs extra is what docs/conf.py uses. (`make docs` builds the site with
warnings as errors: links between the pages are checked there.)"""

import re
import tomllib
from pathlib import Path

import contact

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)")
IMAGE = re.compile(r"!\[[^\]]*\]\(([^)\s]+)\)")
#: pages docs/conf.py writes at build time (docs/.gitignore), and the file each is made from
GENERATED = {DOCS / "results.md": ROOT / "demos" / "RESULTS.md"} | {
    DOCS / "demos" / "generated" / f"{demo.stem}.ipynb": demo
    for demo in (ROOT / "demos").glob("demo_*.py")
}


def slug(heading: str) -> str:
    """GitHub's (and MyST's myst_heading_anchors) anchor of a Markdown heading."""
    text = re.sub(r"[`*_]|\[([^\]]*)\]\([^)]*\)", r"\1", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
    return {slug(m) for m in re.findall(r"^#{1,6} (.+)$", text, re.M)}


def test_readme_is_short_and_links_into_the_site():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) < 150
    targets = [t for t in LINK.findall(text) if not re.match(r"[a-z]+:", t)]
    into_docs = [t for t in targets if t.startswith("docs/")]
    assert len(into_docs) >= 15, "the README links into the site"
    for target in targets:
        file, _, anchor = target.partition("#")
        path = ROOT / file
        assert path.is_file(), f"README links to a missing file: {target}"
        if anchor:
            assert anchor in anchors(path), f"README: no heading #{anchor} in {file}"
    for image in IMAGE.findall(text):
        assert (ROOT / image).is_file(), f"README shows a missing picture: {image}"


def test_every_page_links_resolve_on_github_too():
    """Relative links between the Markdown pages (what GitHub renders): files and headings."""
    for page in DOCS.rglob("*.md"):
        if {"_build", "reference", "generated"} & set(page.relative_to(DOCS).parts):
            continue
        text = re.sub(r"```.*?```|`[^`\n]*`", "", page.read_text(), flags=re.S)
        for target in LINK.findall(text):
            if re.match(r"[a-z]+:|#", target) or "{" in target:
                continue
            file, _, anchor = target.partition("#")
            path = (page.parent / file).resolve()
            path = path if path.is_file() else GENERATED.get(path, path)
            assert path.is_file(), f"{page.relative_to(ROOT)}: missing {target}"
            if anchor and path.suffix == ".md":
                assert anchor in anchors(path), f"{page.relative_to(ROOT)}: no #{anchor} in {file}"


def test_every_public_name_has_a_reference_page():
    text = (DOCS / "api.md").read_text()
    listed = set(re.findall(r"^   (\w+)$", text, re.M))
    assert set(contact.__all__) <= listed


def test_every_demo_and_guide_page_is_rendered():
    conf = (DOCS / "conf.py").read_text()
    demos = sorted(p.stem.removeprefix("demo_") for p in (ROOT / "demos").glob("demo_*.py"))
    index = (DOCS / "demos" / "index.md").read_text()
    for name in demos:
        assert f'"{name}":' in conf, f"docs/conf.py DEMO_ARGS has no size for demo_{name}.py"
        assert f"generated/demo_{name}\n" in index
    guide = (DOCS / "guide" / "index.md").read_text()
    for page in (DOCS / "guide").glob("*.md"):
        assert page.stem == "index" or f"\n{page.stem}\n" in guide, page.name


def test_the_docs_extra_is_what_conf_py_uses():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    docs = set(extras["optional-dependencies"]["docs"])
    conf = (DOCS / "conf.py").read_text()
    assert {"sphinx", "myst-nb", "jupytext", "furo", "ipykernel"} <= docs
    assert '"myst_nb"' in conf and "import jupytext" in conf and 'html_theme = "furo"' in conf
    makefile = (ROOT / "Makefile").read_text()
    assert "sphinx-build -b html -E -n -W --keep-going docs" in makefile
    assert "make docs" in (ROOT / ".ci" / "run").read_text()
