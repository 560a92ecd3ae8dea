"""HDF5's C library as ``dolfinx.io.XDMFFile`` uses it: its error reports kept off stderr,
the cause of a failed write, and the file a failed write left open.

HDF5 prints its whole error stack on stderr (50 lines and more for one failed write)
unless told not to; :func:`silence` turns that off (the command line reports one line).

HDF5 does not survive a full disk: the libhdf5 of the DOLFINx wheel is built with its
assertions on, and creating a file on a full disk aborts the process in one of them
(``H5F__dest``), while under MPI-IO a failed write leaves a file that may neither close
nor be left to the C++ destructor (``std::terminate``).  So HDF5 never meets a full disk:
:func:`claim` creates the empty file and allocates the space its data will take inside it,
beyond its end (``fallocate`` with ``FALLOC_FL_KEEP_SIZE``), where HDF5's writes land — a
full disk is an ``OSError`` of the claim, before HDF5 runs, and space another process
takes meanwhile is not the file's — and :func:`trim` frees what the file did not use.

Should HDF5 fail all the same (more data than claimed): a failed ``H5Dwrite`` inside
DOLFINx throws before its dataset is closed, and with the MPI-IO driver a file with open
objects cannot be closed (its close degree is "semi"); :func:`release` closes the objects
left open in the file and frees the space its data took, after which the file can close.

The functions are called through ctypes on every libhdf5 the process has loaded (DOLFINx
and h5py may each bring their own), found in ``/proc/self/maps``; where there is no such
file (not Linux) they do nothing.
"""

from __future__ import annotations

import ctypes
import errno
import os
import re
from pathlib import Path

HID = ctypes.c_int64
H5E_DEFAULT = 0  # the current error stack
H5E_WALK_DOWNWARD = 1  # from the API function down to where the error arose
H5F_OBJ_ALL = 0x1F  # as a file id: every open file
H5F_OBJ_FILE, H5F_OBJ_DATASET, H5F_OBJ_GROUP, H5F_OBJ_DATATYPE, H5F_OBJ_ATTR = 1, 2, 4, 8, 16
#: OS errors a write meets on a full or limited file system, looked for by name in HDF5's
#: messages when they carry no errno (MPI-IO reports its own text)
WRITE_ERRORS = ("ENOSPC", "EDQUOT", "EFBIG", "EIO", "EROFS", "EACCES")


class _Error(ctypes.Structure):
    """``H5E_error2_t``: one entry of an error stack."""

    _fields_ = [
        ("cls_id", HID),
        ("maj_num", HID),
        ("min_num", HID),
        ("line", ctypes.c_uint),
        ("func_name", ctypes.c_char_p),
        ("file_name", ctypes.c_char_p),
        ("desc", ctypes.c_char_p),
    ]


_WALK = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_uint, ctypes.POINTER(_Error), ctypes.c_void_p)


def _libraries() -> tuple[ctypes.CDLL, ...]:
    """The libhdf5 libraries loaded in this process (not the high-level libhdf5_hl), with
    the signatures of the functions used here."""
    try:
        with open("/proc/self/maps") as fh:
            paths = {line.split()[-1] for line in fh if "libhdf5" in line}
    except OSError:
        return ()
    libs = []
    for path in sorted(paths):
        name = os.path.basename(path)
        if not name.startswith("libhdf5") or "_hl" in name or not os.path.isabs(path):
            continue
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        lib.H5Eset_auto2.argtypes = [HID, ctypes.c_void_p, ctypes.c_void_p]
        lib.H5Ewalk2.argtypes = [HID, ctypes.c_int, _WALK, ctypes.c_void_p]
        lib.H5Fget_obj_count.argtypes = [HID, ctypes.c_uint]
        lib.H5Fget_obj_count.restype = ctypes.c_ssize_t
        lib.H5Fget_obj_ids.argtypes = [HID, ctypes.c_uint, ctypes.c_size_t, ctypes.POINTER(HID)]
        lib.H5Fget_obj_ids.restype = ctypes.c_ssize_t
        lib.H5Fget_name.argtypes = [HID, ctypes.c_char_p, ctypes.c_size_t]
        lib.H5Fget_name.restype = ctypes.c_ssize_t
        for close in ("H5Oclose", "H5Aclose"):
            getattr(lib, close).argtypes = [HID]
        libs.append(lib)
    return tuple(libs)


def silence() -> None:
    """Turn off the printing of HDF5's error stacks (of the calling thread, in every loaded
    libhdf5); failures still raise where DOLFINx or h5py check them."""
    for lib in _libraries():
        lib.H5Eset_auto2(H5E_DEFAULT, None, None)


def cause() -> str | None:
    """The operating system's reason in the current HDF5 error stack of the calling thread
    — ``No space left on device`` for a full disk — or None if it names none.  Read right
    after the failed call (the next HDF5 call clears the stack)."""
    texts: list[str] = []

    @_WALK
    def collect(n, entry, data) -> int:
        texts.append((entry.contents.desc or b"").decode(errors="replace"))
        return 0

    for lib in _libraries():
        lib.H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, collect, None)
    for text in reversed(texts):  # the innermost entry first
        if m := re.search(r"errno = (\d+)", text):
            return os.strerror(int(m[1]))
        for name in WRITE_ERRORS:
            if (reason := os.strerror(getattr(errno, name))) in text:
                return reason
    return None


FALLOC_FL_KEEP_SIZE, FALLOC_FL_PUNCH_HOLE = 1, 2


def claim(path: str | Path, nbytes: int) -> None:
    """Create the empty HDF5 file ``path`` (replacing any) and allocate ``nbytes`` of disk
    space in it beyond its end, for the data HDF5 will write there (module doc; call on one
    rank).  An OSError (ENOSPC, EDQUOT, EFBIG) when the space is not there.  Where the file
    system cannot allocate beyond a file's end, the space is checked by allocating it in a
    scratch file beside it instead (another process may then take it before HDF5 writes)."""
    import h5py

    try:
        h5py.File(path, "w").close()
    except OSError as err:  # h5py's message names the OS error: keep that one
        m = re.search(r"errno = (\d+)", str(err))
        if m is None:
            raise
        raise OSError(int(m[1]), os.strerror(int(m[1])), str(path)) from None
    if _fallocate(path, FALLOC_FL_KEEP_SIZE, 0, nbytes):
        return
    scratch = Path(path).with_name(f".{Path(path).name}.claim")
    fd = os.open(scratch, os.O_CREAT | os.O_WRONLY | os.O_TRUNC, 0o600)
    try:
        os.posix_fallocate(fd, 0, nbytes)
    finally:
        os.close(fd)
        scratch.unlink(missing_ok=True)


def trim(path: str | Path) -> None:
    """Free the space :func:`claim` allocated beyond the end of the closed file ``path``."""
    size = os.path.getsize(path)
    os.truncate(path, size)  # frees the blocks past the end (tmpfs, ext4, xfs)
    _fallocate(path, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, size, 1 << 40)


def _fallocate(path: str | Path, mode: int, offset: int, length: int) -> bool:
    """Linux ``fallocate(2)`` on ``path``: True if done, False where the file system or the
    C library cannot; an OSError for any other failure (ENOSPC)."""
    try:
        fallocate = ctypes.CDLL(None, use_errno=True).fallocate
    except (OSError, AttributeError):
        return False
    fallocate.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int64, ctypes.c_int64]
    fd = os.open(path, os.O_WRONLY)
    try:
        if fallocate(fd, mode, offset, length) == 0:
            return True
        code = ctypes.get_errno()
    finally:
        os.close(fd)
    if code in (errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL):
        return False
    raise OSError(code, os.strerror(code), str(path))


def release(path: str | Path, truncate: bool) -> int:
    """Close the datasets, groups, named datatypes and attributes left open in the HDF5 file
    ``path`` (every libhdf5, every open file of that name) and, if ``truncate``, cut the file
    to zero bytes, so that closing it needs no more than a little space for its metadata.
    Call on every rank that has the file open (closing an object of a file opened through
    MPI-IO is collective), with ``truncate`` on one rank only.  Returns the number of
    objects closed."""
    target = os.path.realpath(path)
    closed = 0
    for lib in _libraries():
        for fid in _ids(lib, H5F_OBJ_ALL, H5F_OBJ_FILE):
            name = ctypes.create_string_buffer(4096)
            if lib.H5Fget_name(fid, name, len(name)) < 0:
                continue
            if os.path.realpath(name.value.decode(errors="replace")) != target:
                continue
            objects = H5F_OBJ_DATASET | H5F_OBJ_GROUP | H5F_OBJ_DATATYPE
            for oid in _ids(lib, fid, H5F_OBJ_ATTR):
                closed += lib.H5Aclose(oid) >= 0
            for oid in _ids(lib, fid, objects):
                closed += lib.H5Oclose(oid) >= 0
    if truncate:
        try:
            os.truncate(path, 0)
        except OSError:
            pass
    return closed


def _ids(lib: ctypes.CDLL, fid: int, types: int) -> list[int]:
    """The ids of the open objects of ``types`` in the file ``fid`` (H5F_OBJ_ALL: any)."""
    count = lib.H5Fget_obj_count(fid, types)
    if count <= 0:
        return []
    ids = (HID * count)()
    got = lib.H5Fget_obj_ids(fid, types, count, ids)
    return list(ids[: max(got, 0)])
