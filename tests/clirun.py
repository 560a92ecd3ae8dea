"""Run the real ``contact`` command line as a subprocess (serial or under mpirun)."""

from __future__ import annotations

import copy
import csv
import json
import os
import subprocess
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"


def contact(
    cwd: Path,
    *args: str,
    ranks: int = 0,
    env: dict | None = None,
    prefix: tuple = (),
    timeout: float = 300,
) -> subprocess.CompletedProcess:
    """``python -m contact.app.cli ARGS`` in ``cwd`` (under ``mpirun -n ranks`` when ranks > 0);
    ``prefix`` is prepended to the command (e.g. ``("unshare", "-U")``)."""
    cmd = [sys.executable, "-m", "contact.app.cli", *args]
    if ranks:
        cmd = [str(MPIRUN), "-n", str(ranks), *cmd]
    full_env = {**os.environ, "PYTHONWARNINGS": "ignore", "OMP_NUM_THREADS": "1", **(env or {})}
    return subprocess.run(
        [*prefix, *cmd], cwd=cwd, env=full_env, capture_output=True, text=True, timeout=timeout
    )


def run_scene(
    tmp: Path, scene: str, ranks: int, sets: Sequence[str], timeout: float
) -> tuple[Path, subprocess.CompletedProcess]:
    """``contact run configs/<scene> -o tmp/np<ranks> -q --set …`` (``sets``), serially
    (``ranks`` 0) or under ``mpirun -n ranks``, which must exit 0 within ``timeout`` seconds:
    the output folder and the finished process."""
    out = tmp / f"np{ranks}"
    args = ["run", str(ROOT / "configs" / scene), "-o", str(out), "-q"]
    for item in sets:
        args += ["--set", item]
    proc = contact(tmp, *args, ranks=ranks, timeout=timeout)
    assert proc.returncode == 0, f"{scene} on {ranks or 1} rank(s): {proc.stderr[-2000:]}"
    return out, proc


def serial_runs(factory, run: Callable[[Path, str, int], Path]) -> Callable[[str], Path]:
    """The serial run of each scene, made by ``run(folder, scene, 0)`` when a test first
    asks for it and kept (the value of a module-scoped fixture; ``factory``: pytest's
    ``tmp_path_factory``)."""
    done: dict[str, Path] = {}

    def get(scene: str) -> Path:
        if scene not in done:
            folder = factory.mktemp(scene.replace("/", "_").removesuffix(".yaml"))
            done[scene] = run(folder, scene, 0)
        return done[scene]

    return get


def script_json(script: str, folder: Path, *args: str, ranks: int = 1) -> object:
    """Run the Python ``script`` (text) under ``mpirun -n ranks`` in ``folder`` with ``args``;
    the JSON its rank 0 prints last (the run must exit 0)."""
    path = folder / "script.py"
    path.write_text(script)
    proc = subprocess.run(
        [str(MPIRUN), "-n", str(ranks), sys.executable, str(path), *args],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=folder,
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def pytest_on_ranks(
    test_file: str, select: str, ranks: int = 2, timeout: float = 600
) -> subprocess.CompletedProcess:
    """The tests of ``test_file`` that ``-k select`` picks, run by pytest on each of
    ``ranks`` MPI ranks (one ``mpirun``), under ``timeout`` seconds: a rank left waiting
    is a ``TimeoutExpired``, not a hung suite."""
    return subprocess.run(
        [str(MPIRUN), "-n", str(ranks), sys.executable, "-m", "pytest", "-q"]
        + ["-p", "no:cacheprovider", test_file, "-k", select],
        cwd=ROOT / "tests",
        capture_output=True,
        text=True,
        timeout=timeout,
        env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"},
    )


def small_scene(path: Path, cells: int = 8, **changes) -> Path:
    """configs/signorini_square.yaml on a ``cells`` × ``cells`` mesh without pictures (they
    take most of a small run's time), with dotted-key ``changes`` (``data__f="1"`` sets
    data.f), written to ``path``."""
    scene = copy.deepcopy(yaml.safe_load((ROOT / "configs" / "signorini_square.yaml").read_text()))
    scene["mesh"]["cells"] = [cells, cells]
    scene.setdefault("output", {})["png"] = False
    for key, value in changes.items():
        node, parts = scene, key.split("__")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    path.write_text(yaml.safe_dump(scene, sort_keys=False))
    return path


def error_lines(proc: subprocess.CompletedProcess) -> list[str]:
    return [ln for ln in proc.stderr.splitlines() if ln.strip()]


def tree(folder: Path) -> dict[str, bytes | None]:
    """Every entry below ``folder`` (hidden ones included) with its content (None for folders)."""
    return {
        str(p.relative_to(folder)): (None if p.is_dir() else p.read_bytes())
        for p in folder.rglob("*")
    }


def h5_field(path: Path, name: str) -> np.ndarray:
    """The values of every dataset whose path contains ``name`` in the HDF5 file ``path`` (a
    cell or point field of an XDMF output), concatenated; empty if there is none."""
    import h5py

    found: list = []
    with h5py.File(path) as f:
        f.visititems(
            lambda key, obj: (
                found.append(np.ravel(obj[()]))
                if name in key and isinstance(obj, h5py.Dataset)
                else None
            )
        )
    return np.concatenate(found) if found else np.zeros(0)


#: the columns of convergence.csv an hp run must repeat exactly on any number of ranks
HP_LEVEL_KEYS = ("dofs", "cells", "p_min", "p_max", "h_cells", "p_cells")


def hp_serial_equals_two_ranks(
    tmp: Path, scene: str, sets: Sequence[str], levels: int, timeout: float = 300
) -> tuple[list[dict], list[dict]]:
    """Run the hp scene ``configs/<scene>`` with ``sets`` serially and on 2 ranks and check
    that its convergence.csv has ``levels`` rows each time, the same :data:`HP_LEVEL_KEYS`
    per level and η to 1e-8: the two tables (serial, 2 ranks)."""
    tables = []
    for ranks in (0, 2):
        out, _ = run_scene(tmp, scene, ranks, sets, timeout)
        with open(out / "convergence.csv", newline="") as f:
            tables.append(list(csv.DictReader(f)))
    one, two = tables
    assert len(one) == len(two) == levels
    for a, b in zip(one, two):
        for key in HP_LEVEL_KEYS:
            assert a[key] == b[key], (key, a, b)
        assert abs(float(a["eta"]) - float(b["eta"])) <= 1e-8 * float(a["eta"])
    return one, two
