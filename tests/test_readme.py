"""The Python example in README.md runs as written."""
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_readme_python_example_runs():
    text = (ROOT / "README.md").read_text()
    section = text.split("## Python API", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    assert 5 <= len(code.strip().splitlines()) <= 12
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert any(line.startswith("True ") for line in proc.stdout.splitlines())
    assert "min (primal-dual active set):" in proc.stdout


def test_readme_study_example_validates(monkeypatch):
    """The study YAML of README's "Parameter studies" section is a valid study (paths
    relative to configs/studies/, as a study file there would be)."""
    import yaml

    from contact.study import load_study

    section = (ROOT / "README.md").read_text().split("## Parameter studies", 1)[1]
    block = re.search(r"```yaml\n(.*?)```", section, re.S).group(1)
    monkeypatch.chdir(ROOT / "configs" / "studies")
    study = load_study(yaml.safe_load(block))
    assert study.axes["method"] == ["fb", "min", "vinewtonrsls"] and set(study.cases) == {"cold far", "obtuse"}
    assert len(study.runs()) == 2 * 3 * 3 and study.charts == ["speed_accuracy", "stability"]
