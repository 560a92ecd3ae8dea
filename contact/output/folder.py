"""An atomically written result folder with JSON and CSV files (VTK: :mod:`.vtk`).

``atomic_folder`` gives a temporary sibling directory; only when everything inside was
written does rank 0 move it to the requested name.  After a failure there is either no
folder or the previous complete one — never a half-written folder.

The tool never touches what it did not write.  Every folder it writes carries a marker
file :data:`MARKER` (JSON: tool, version, command, time, host, pid, and the list of the
entries it wrote), and an existing ``outdir`` is replaced only when it is such a folder
holding nothing but those entries.  Any other existing folder, a file, a symbolic link,
or a place the user cannot write is refused before anything is solved
(:func:`check_output`, a one-line :class:`~contact.base.errors.ConfigError`).

Temporaries are siblings named ``.NAME.partial-HOST-PID-XXXX`` (being written) and
``.NAME.old-HOST-PID`` (the previous result during the replace).  The replace is one
atomic exchange of the two folders (Linux ``renameat2(RENAME_EXCHANGE)``), then the old
one is deleted: at every instant ``NAME`` is a complete result.  Where the exchange is not
available (other kernels, some network file systems) it is two renames, NAME → .old, then
.partial → NAME; a run killed between the two leaves no ``NAME``.  The next run targeting
the same ``NAME`` (on the same host) repairs that (:func:`tidy_temporaries`): temporaries
whose writer is gone are deleted, after the newest complete one (carrying the marker) is
moved back to ``NAME`` if ``NAME`` is missing.  Temporaries of a live process or of another
host are left alone.

Writing is collective and agreed: every file is written by rank 0 (or, for the HDF5 data of
the XDMF files, by every rank through MPI-IO) inside :func:`write_on_root`, and a failure there —
a full disk, a quota, a file too large — becomes an :class:`OutputError` on every rank,
which :func:`atomic_folder` turns into one :class:`~contact.base.errors.ConfigError` naming
the option that chose the folder; the temporary folder is deleted, a previous result stays.
A folder name too long for its temporary siblings is refused by :func:`check_output`,
before anything is solved.
"""

from __future__ import annotations

import contextlib
import csv
import ctypes
import datetime
import json
import os
import re
import shutil
import socket
import sys
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from ..base.errors import ConfigError
from ..base.version import __version__

MARKER = ".contact-result"  # the marker file of every folder the tool writes


class OutputError(OSError):
    """A file of the output folder could not be written (raised on every rank alike by
    :func:`write_on_root`, or by the collective HDF5 writer); ``str(err)`` names the file and the
    cause, e.g. ``cannot write solution.vtu: No space left on device``."""


def write_on_root[T](comm: MPI.Comm, action: Callable[[], T], name: str) -> T | None:
    """``action()`` — the writing of the file ``name`` — on rank 0 (collective): its value
    there, None elsewhere.  If it fails, every rank raises: an :class:`OutputError` naming
    the file for an OSError (a full disk), else a RuntimeError naming the file and the
    error (a bug: exit code 3), so that no rank goes on into a collective the others left.
    """
    value, problem = None, None
    if comm.rank == 0:
        try:
            value = action()
        except OSError as err:
            problem = ("os", f"cannot write {name}: {err.strerror or err}")
        except Exception as err:  # noqa: BLE001 - reported on every rank below
            problem = ("bug", f"writing {name} failed: {type(err).__name__}: {err}")
    if comm.size > 1:
        problem = comm.bcast(problem, root=0)
    if problem is not None:
        kind, text = problem
        raise OutputError(text) if kind == "os" else RuntimeError(text)
    return value


def check_output(outdir: str | Path, label: str, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """Refuse (ConfigError ``<label>: <problem>``, on every rank) an output folder the tool
    may not write: see :func:`output_problem`.  Stale temporaries of the same target are
    tidied first.  Collective; call it before the solve."""
    target = _absolute(outdir)

    def check() -> str | None:
        if too_long := name_too_long(target, _existing_ancestor(target.parent)):
            return too_long  # before any file system call that would fail on the name
        tidy_temporaries(target)
        return output_problem(target)

    _on_root(comm, check, label)


def _on_root(comm: MPI.Comm, action, label: str) -> Any:
    """Run ``action()`` on rank 0 — it returns a problem text or a value — and share the
    outcome: a problem text (or an OSError) becomes a ConfigError ``<label>: <problem>`` on
    every rank, a value is returned on every rank."""
    outcome = None
    if comm.rank == 0:
        try:
            outcome = action()
        except OSError as err:
            outcome = f"cannot write: {err.strerror or err}" + (
                f" ({err.filename})" if err.filename else ""
            )
    outcome = comm.bcast(outcome, root=0)
    if isinstance(outcome, str):
        raise ConfigError(f"{label}: {outcome}")
    return outcome


def output_problem(outdir: Path) -> str | None:
    """Why the tool may not (re)place the folder ``outdir``, or None.

    Allowed: a path that does not exist yet, below a folder the user can create entries in,
    or a previous result of the tool (it has :data:`MARKER`) holding only what the tool
    wrote.  Refused: an existing file or symbolic link, any other folder (the user's own,
    ``.``, a folder with files added to a result), a path below a file, a place without
    write permission."""
    outdir = _absolute(outdir)
    anc = _existing_ancestor(outdir.parent)
    if too_long := name_too_long(outdir, anc):
        return too_long
    if outdir.is_symlink():
        return "is a symbolic link; give the folder itself"
    if outdir.exists():
        if not outdir.is_dir():
            return (
                "is an existing file; nothing was changed (give a folder name that does not exist)"
            )
        written = _manifest(outdir)
        if written is None:
            return (
                f"is an existing folder that contact did not write (no {MARKER} marker); "
                f"nothing was "
                "changed (give a new folder name, or remove it yourself)"
            )
        foreign = sorted(set(_entries(outdir)) - written - {MARKER})
        if foreign:
            return (
                f"is a contact result, but holds {len(foreign)} file(s) contact did not write "
                f"({', '.join(foreign[:3])}); nothing was changed"
            )
    if not anc.is_dir():
        return f"cannot be created: {anc} is a file, not a folder"
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".contact-probe-", dir=anc))
    except OSError as err:
        return (
            f"cannot be written: no permission to create entries in {anc} ({err.strerror or err})"
        )
    return None


def _existing_ancestor(path: Path) -> Path:
    """``path`` or its nearest ancestor that exists (or is a symbolic link)."""
    while path != path.parent:
        try:
            if path.exists() or path.is_symlink():
                return path
        except OSError:  # a component too long: not there
            pass
        path = path.parent
    return path


def name_too_long(outdir: Path, existing: Path) -> str | None:
    """Why the last component of ``outdir`` is too long for the file system of its nearest
    ``existing`` ancestor — the folder itself or its temporary sibling
    ``.NAME.partial-HOST-PID-XXXXXXXX`` (:func:`atomic_folder`) would exceed the longest
    file name there (``NAME_MAX``, 255 bytes on Linux) — or None.  Components of ``outdir``
    that do not exist yet are checked too."""
    try:
        limit = os.pathconf(existing, "PC_NAME_MAX")
    except (OSError, ValueError):
        limit = 255
    rest = outdir.relative_to(existing).parts if outdir.is_relative_to(existing) else ()
    for part in rest[:-1]:
        if len(os.fsencode(part)) > limit:
            return (
                f"a folder name on the way is {len(os.fsencode(part))} bytes long, more than "
                f"the {limit} the file system allows"
            )
    # mkdtemp adds "-" and 8 random characters to the temporary sibling's prefix
    need = len(os.fsencode(_temp_name(outdir, "partial"))) + 9
    if need > limit:
        most = limit - (need - len(os.fsencode(outdir.name)))
        return (
            f"the folder name is {len(os.fsencode(outdir.name))} bytes long; at most {most} "
            f"here (the file system allows {limit}, and contact writes beside it first, as "
            f".NAME.partial-…); give a shorter name"
        )
    return None


def _absolute(path: str | Path) -> Path:
    return Path(os.path.abspath(Path(path).expanduser()))


def _entries(folder: Path) -> list[str]:
    """Relative paths of every file and folder below ``folder`` (links not followed)."""
    out = []
    for root, dirs, files in os.walk(folder):
        rel = Path(root).relative_to(folder)
        out += [str(rel / name) for name in dirs + files]
    return out


def _manifest(folder: Path) -> set[str] | None:
    """The entries the tool wrote into ``folder`` according to its marker; None if the
    folder has no readable marker."""
    try:
        data = json.loads((folder / MARKER).read_text())
        return set(data["entries"]) if data.get("tool") == "contact" else None
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _write_marker(folder: Path) -> None:
    info = {
        "tool": "contact",
        "version": __version__,
        "command": [Path(sys.argv[0]).name, *sys.argv[1:]],
        "cwd": os.getcwd(),
        "time": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "host": socket.gethostname(),
        "pid": os.getpid(),
        "entries": sorted(_entries(folder)),
    }
    (folder / MARKER).write_text(json.dumps(info, indent=1) + "\n")


# ------------------------------------------------------------------------- temporaries
def host_tag() -> str:
    """This machine's name as it appears in temporary folder names (letters, digits, dots)."""
    return re.sub(r"[^A-Za-z0-9.]", "_", socket.gethostname())


def _temp_name(outdir: Path, kind: str) -> str:
    """``.NAME.KIND-HOST-PID`` (KIND partial or old)."""
    return f".{outdir.name}.{kind}-{host_tag()}-{os.getpid()}"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


def stale_temporaries(outdir: Path) -> list[Path]:
    """The temporaries of ``outdir`` left by a writer that is gone (same host, dead pid)."""
    outdir = _absolute(outdir)
    pattern = re.compile(
        rf"\.{re.escape(outdir.name)}\.(partial|old)-([A-Za-z0-9._]+)-(\d+)(-[A-Za-z0-9_]+)?"
    )
    out: list[Path] = []
    if not outdir.parent.is_dir():
        return out
    for entry in outdir.parent.iterdir():
        m = pattern.fullmatch(entry.name)
        if (
            m
            and entry.is_dir()
            and not entry.is_symlink()
            and m[2] == host_tag()
            and not _alive(int(m[3]))
        ):
            out.append(entry)
    return sorted(out)


def tidy_temporaries(outdir: str | Path) -> list[Path]:
    """Delete the stale temporaries of ``outdir``; first, if ``outdir`` is missing, move
    the newest complete one (it has the marker) back to ``outdir`` — the window of a
    replace killed between its two renames.  Returns what was deleted."""
    outdir = _absolute(outdir)
    stale = stale_temporaries(outdir)
    if not outdir.exists() and not outdir.is_symlink():
        complete = [(_marker_time(p), p) for p in stale if _manifest(p) is not None]
        if complete:
            newest = max(complete)[1]
            newest.rename(outdir)
            stale.remove(newest)
    for path in stale:
        shutil.rmtree(path, ignore_errors=True)
    return stale


def _marker_time(folder: Path) -> str:
    try:
        return str(json.loads((folder / MARKER).read_text()).get("time", ""))
    except (OSError, ValueError):
        return ""


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux renameat2 with RENAME_EXCHANGE); False where the
    kernel, C library or file system cannot."""
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    return renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0


def _replace(tmp: Path, outdir: Path) -> None:
    """Make the complete folder ``tmp`` the folder ``outdir`` (see the module doc)."""
    umask = os.umask(0)
    os.umask(umask)
    tmp.chmod(0o777 & ~umask)  # mkdtemp makes 0700; give the folder the usual mode
    if not outdir.exists():
        tmp.rename(outdir)
    elif _exchange(tmp, outdir):
        shutil.rmtree(tmp)  # now the previous result
    else:
        old = outdir.with_name(_temp_name(outdir, "old"))
        outdir.rename(old)
        tmp.rename(outdir)
        shutil.rmtree(old)


_KEPT = "nothing was written (a previous result there is kept)"


@contextlib.contextmanager
def atomic_folder(
    outdir: str | Path, comm: MPI.Comm = MPI.COMM_WORLD, label: str | None = None
) -> Iterator[Path]:
    """Yield a temporary directory that becomes ``outdir`` on success (collective).  On an
    exception rank 0 deletes it and nothing communicates (the exception may be this rank's
    alone; :mod:`contact.app.failures`).

    ``outdir`` must pass :func:`output_problem` (else a ConfigError naming ``label``, the
    option that chose it, or the path), at the start and again at the end, before the
    replace; the folder gets the :data:`MARKER` file last, when everything else is in it."""
    target = _absolute(outdir)
    label = label or str(outdir)
    check_output(target, label, comm)

    def create() -> Path:
        target.parent.mkdir(parents=True, exist_ok=True)
        return Path(tempfile.mkdtemp(prefix=_temp_name(target, "partial") + "-", dir=target.parent))

    tmp = _on_root(comm, create, label)
    try:
        yield tmp
    except OutputError as err:  # raised on every rank alike: the folder's one-line error
        if comm.rank == 0:
            shutil.rmtree(tmp, ignore_errors=True)
        raise ConfigError(f"{label}: {err}; {_KEPT}") from err
    except BaseException:
        if comm.rank == 0:  # local: no collective on the way out of an exception (app.failures)
            shutil.rmtree(tmp, ignore_errors=True)
        raise
    # Every rank finished its part of the folder (pictures are drawn on several ranks).  A
    # rank that raised never gets here: the others wait until its handler aborts the job.
    comm.Barrier()

    def commit() -> str | None:  # the target may have changed during the run
        try:
            if problem := output_problem(target):
                return problem
            _write_marker(tmp)
            _replace(tmp, target)
        except OSError as err:
            return f"cannot write {MARKER}: {err.strerror or err}; {_KEPT}"
        finally:
            shutil.rmtree(tmp, ignore_errors=True)  # gone once moved: the previous result
        return None

    _on_root(comm, commit, label)


class Collection:
    """A text file of entries between a fixed ``head`` and ``tail`` — an XML collection such
    as a .pvd or a temporal XDMF file — valid after every :meth:`append` (call on the rank
    that writes it).  An append writes the new entry and the tail over the old tail: its cost
    is that of the entry however many came before, and nothing is kept in memory but the
    tail's byte offset."""

    def __init__(self, path: str | Path, head: str, tail: str):
        self.path, self.head, self.tail = Path(path), head.encode(), tail.encode()
        self._end: int | None = None  # where the tail starts, once the file exists

    def append(self, entry: str) -> None:
        data = entry.encode()
        if self._end is None:
            with open(self.path, "wb") as fh:
                fh.write(self.head + data + self.tail)
            self._end = len(self.head) + len(data)
            return
        with open(self.path, "r+b") as fh:
            fh.seek(self._end)
            fh.write(data + self.tail)
            fh.truncate()
        self._end += len(data)


class RowLog:
    """Rows of figures (dicts) appended one by one to a JSON-lines file ``path`` by rank 0
    (collective: :func:`write_on_root`), so that a load path of any length keeps none of
    them in memory; :meth:`rows` reads them back (rank 0) and :meth:`write_csv` writes them
    as CSV with the union of their keys as header.  A hidden file of the output folder,
    deleted by :meth:`remove` before the folder is listed."""

    def __init__(self, path: str | Path, comm: MPI.Comm = MPI.COMM_WORLD):
        self.path, self.comm, self.count = Path(path), comm, 0

    def add(self, rows: Sequence[Mapping[str, Any]]) -> None:
        """Append ``rows`` (the same on every rank; rank 0 writes them)."""
        if not rows:
            return
        text = "".join(json.dumps(row, default=_jsonable) + "\n" for row in rows)

        def append() -> None:
            with open(self.path, "a") as fh:
                fh.write(text)

        write_on_root(self.comm, append, self.path.name)
        self.count += len(rows)

    def rows(self) -> Iterator[dict[str, Any]]:
        """The rows, read back one at a time (rank 0)."""
        if not self.path.exists():
            return
        with open(self.path) as fh:
            for line in fh:
                yield json.loads(line)

    def write_csv(self, path: str | Path, flat: Callable[[dict], dict] = lambda row: row) -> None:
        """The rows (each through ``flat``) as CSV at ``path`` (collective; rank 0 reads and
        writes, twice through the rows: the header, then the rows)."""

        def write() -> None:
            keys: dict[str, None] = {}
            for row in self.rows():
                keys.update(dict.fromkeys(flat(row)))
            with open(path, "w", newline="") as fh:
                writer = csv.DictWriter(fh, fieldnames=list(keys))
                writer.writeheader()
                writer.writerows(flat(row) for row in self.rows())

        write_on_root(self.comm, write, Path(path).name)

    def remove(self) -> None:
        if self.comm.rank == 0:
            self.path.unlink(missing_ok=True)


def read_table(path: str | Path) -> dict[str, np.ndarray]:
    """A table that :func:`write_table` wrote, read back: its columns as float arrays, or
    string arrays where a column holds text (``status``)."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(rows[0] if rows else []):
        column = [row[j] for row in rows[1:]]
        try:
            out[name] = np.array(column, dtype=float)
        except ValueError:
            out[name] = np.array(column)
    return out


def write_json(path: str | Path, data: Mapping[str, Any], comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    if comm.rank == 0:
        Path(path).write_text(json.dumps(data, indent=2, default=_jsonable) + "\n")


def write_csv(
    path: str | Path, rows: Sequence[Mapping[str, Any]], comm: MPI.Comm = MPI.COMM_WORLD
) -> None:
    """Rows of dicts to CSV (header from the union of keys, in first-seen order)."""
    if comm.rank != 0:
        return
    keys: list[str] = []
    for row in rows:
        keys += [k for k in row if k not in keys]
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)


def write_table(path: str | Path, table: Mapping[str, np.ndarray]) -> None:
    """Named columns (a table of :mod:`contact.post.contact_table`) to CSV (call on the rank
    that holds the table)."""
    names = list(table)
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(names)
        for row in zip(*(table[k].tolist() for k in names)):
            writer.writerow(row)


def json_file(path: Path, data: Mapping[str, Any], comm: MPI.Comm) -> None:
    """:func:`write_json` of ``data`` at ``path``, agreed (collective, :func:`write_on_root`)."""
    write_on_root(comm, lambda: write_json(path, data, comm), path.name)


def csv_file(path: Path, rows: Sequence[Mapping[str, Any]], comm: MPI.Comm) -> None:
    """:func:`write_csv` of ``rows`` at ``path``, agreed (collective, :func:`write_on_root`)."""
    write_on_root(comm, lambda: write_csv(path, rows, comm), path.name)


def table_file(path: Path, table: Mapping[str, np.ndarray] | None, comm: MPI.Comm) -> None:
    """:func:`write_table` of ``table`` (held by rank 0, None elsewhere) at ``path``, agreed
    (collective, :func:`write_on_root`); nothing when rank 0 holds no table either."""

    def write() -> None:
        if table is not None:
            write_table(path, table)

    write_on_root(comm, write, path.name)


def _jsonable(obj: Any) -> Any:
    if hasattr(obj, "item"):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def gather_nodal(fn: fem.Function) -> tuple:
    """(coordinates, values) of all owned nodes of a P-k function (values (n, bs) for
    vector functions) on rank 0, sorted
    lexicographically by coordinate (so serial and parallel runs compare entry by entry);
    ``(None, None)`` on other ranks."""
    import numpy as np

    V = fn.function_space
    n, bs = V.dofmap.index_map.size_local, V.dofmap.index_map_bs
    X = V.tabulate_dof_coordinates()[:n]
    vals = fn.x.array[: n * bs].reshape(n, bs) if bs > 1 else fn.x.array[:n]
    parts = V.mesh.comm.gather((X, vals), root=0)
    if V.mesh.comm.rank != 0:
        return None, None
    X = np.vstack([p[0] for p in parts])
    vals = np.concatenate([p[1] for p in parts])
    order = np.lexsort(np.round(X, 12).T[::-1])
    return X[order], vals[order]
