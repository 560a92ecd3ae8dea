"""A process of its own that draws a command's 2D pictures (:mod:`.drawing`).

``contact run`` starts it on rank 0 as soon as it has parsed its arguments and the scene
file asks for pictures (:func:`start`), before it imports DOLFINx, builds and solves the
scene: the process imports matplotlib meanwhile — on a second core; the import is about as
long as all of a small run's own work — and then waits.  The pictures are built as before
(:func:`contact.output.plots.draw_in_turn`); rank 0 sends each one it draws with
:mod:`.drawing` (the function with its keywords bound and the gathered
:class:`~contact.output.grid.Grid`, pickled: numpy arrays and text) through a pipe, and
collects the outcomes before the command writes ``summary.json``, so that the pictures
exist when the command returns.  The process draws each picture in a child forked from it
(matplotlib is loaded there already), :data:`DRAWERS` at once: the command waits for its
pictures with a core free.  Pictures of other kinds (3D, friction) are drawn in the
command's process.

The process imports neither the package's ``__init__`` (which sets up MPI and PETSc, the
FEniCS wheel's start-up) nor DOLFINx: it loads ``contact.output`` under an empty ``contact``
package, and it is started by fork and exec (a new interpreter), never a fork of the
command.  It ignores Ctrl-C (the command handles it) and ends when its input closes: when
the command stops it (:func:`stop`), or ends in any way.  A picture that fails in it is
one warning line as in the command's process; if the process or a child drawing a
picture ends without drawing it (killed, crashed), that picture costs one warning line
saying so, and the results are written all the same.
"""

from __future__ import annotations

import contextlib
import gc
import os
import pickle
import select
import signal
import socket
import struct
import subprocess
import sys
import warnings
from pathlib import Path
from typing import Any

from . import figures

#: draw the 2D pictures of ``contact run`` in a process of their own (False: in the
#: command's process, the old path, kept to measure the difference)
ENABLED = True

#: seconds the command waits for an idle picture process to end before it kills it
GRACE = 10.0

#: pictures the process draws at once, each in a child forked from it (at most the cores
#: this process may run on; 1: one after the other)
DRAWERS = 2

_LENGTH = "<Q"  # the length before each part of a picture sent to the process
_POLL = 0.05  # seconds between looks for ended children while waiting for a picture
_TEXT = 500  # characters of an error or warning text sent back

#: the picture process: an empty ``contact`` package over this folder (its ``__init__``
#: would set up MPI and PETSc), then :func:`serve`
_BOOT = (
    "import sys, types\n"
    "package = types.ModuleType('contact')\n"
    "package.__path__ = [{root!r}]\n"
    "sys.modules['contact'] = package\n"
    "from contact.output.picture_process import serve\n"
    "serve()\n"
)

_started: list[PictureProcess] = []  # the process of the running command, if any


class RemoteError(Exception):
    """A picture's failure in the picture process: ``text`` is ``<Type>: <message>`` of the
    exception raised there (an OSError comes back as itself, with its errno)."""


class PictureProcess:
    """The picture process of one command (rank 0): :meth:`send` pictures, then
    :meth:`outcomes`; :meth:`close` at the end."""

    def __init__(self) -> None:
        root = str(Path(__file__).resolve().parents[1])
        # the pictures go through a socket: writing to one whose reader has ended raises
        # (MSG_NOSIGNAL) instead of SIGPIPE, which PETSc's handler would make an abort
        self.requests, theirs = socket.socketpair()
        with theirs:
            self.proc = subprocess.Popen(
                [sys.executable, "-P", "-c", _BOOT.format(root=root)],
                stdin=theirs.fileno(),
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                process_group=0,  # with the children it draws in: close() can end them all
            )
        self.pending: list[str] = []  # names sent, outcome not yet read
        self.used = False  # a picture was sent

    def takes(self, draw: Any, grid: Any) -> bool:
        """Whether the process can draw ``draw(grid)``: a function of :mod:`.drawing` with
        its keywords bound, on a :class:`~contact.output.grid.Grid` (or none, a chart), and
        the process has taken a picture before or
        still runs (one that ended before its first picture leaves the pictures to the
        command's process; one that ends later fails those it has not drawn)."""
        import functools

        from . import drawing
        from .grid import Grid

        return (
            (self.used or self.proc.poll() is None)
            and isinstance(draw, functools.partial)
            and getattr(draw.func, "__module__", None) == drawing.__name__
            and (grid is None or isinstance(grid, Grid))
        )

    def send(self, name: str, draw: Any, grid: Any) -> None:
        """Hand picture ``name`` to the process; its outcome comes with :meth:`outcomes`
        (a process that has ended fails it there)."""
        self.used = True
        self.pending.append(name)
        switches = {switch: getattr(figures, switch) for switch in figures.SWITCHES}
        payload = pickle.dumps((switches, draw, grid), protocol=pickle.HIGHEST_PROTOCOL)
        try:
            for part in (name.encode(), payload):
                self.requests.sendall(struct.pack(_LENGTH, len(part)) + part, socket.MSG_NOSIGNAL)
        except OSError:  # the process has ended: outcomes() says so
            pass

    def outcomes(self) -> list[tuple[str, BaseException | None]]:
        """(name, None if drawn else the error) of every picture sent since the last call,
        in order, once each is drawn; the warnings raised while drawing are raised here."""
        done: list[tuple[str, BaseException | None]] = []
        while self.pending:
            try:
                assert self.proc.stdout is not None
                name, error, caught = pickle.load(self.proc.stdout)
            except (EOFError, OSError, pickle.UnpicklingError):
                ended = _ended(self.proc.wait())
                done += [(name, RemoteError(ended)) for name in self.pending]
                self.pending.clear()
                break
            self.pending.remove(name)
            for category, message, filename, lineno in caught:
                warnings.warn_explicit(message, _category(category), filename, lineno)
            done.append((name, _error(error)))
        return done

    def close(self) -> None:
        """End the process: an idle one (every picture sent was drawn) ends when its input
        closes; any other is killed.  Waits for it (no process is left behind)."""
        idle = self.used and not self.pending
        self.requests.close()
        if idle:
            try:
                self.proc.wait(timeout=GRACE)
            except subprocess.TimeoutExpired:
                pass
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait()
        if self.proc.stdout is not None:
            self.proc.stdout.close()


def start() -> PictureProcess | None:
    """Start the picture process of this command (None if :data:`ENABLED` is False or it
    cannot start: then the pictures are drawn in the command's process)."""
    stop()
    if not ENABLED:
        return None
    try:
        _started.append(PictureProcess())
    except OSError:
        return None
    return _started[-1]


def current() -> PictureProcess | None:
    """The picture process of the running command, if it has one."""
    return _started[-1] if _started else None


def stop() -> None:
    """End the picture process of the running command (if any; :meth:`PictureProcess.close`)."""
    while _started:
        _started.pop().close()


def _ended(code: int) -> str:
    how = f"signal {-code}" if code < 0 else f"exit code {code}"
    return f"the picture process ended ({how})"


def _error(error: tuple | None) -> BaseException | None:
    """The error of a reply: None, an OSError (its errno kept: a full disk fails the run),
    or a RemoteError."""
    if error is None:
        return None
    kind, message, number, strerror = error
    if number is not None:
        return OSError(number, strerror or message)
    return RemoteError(f"{kind}: {message}" if kind else message)


def _category(name: str) -> type[Warning]:
    """The warning class of a built-in category's name; UserWarning for any other (a
    library's own category is not imported here for it)."""
    import builtins

    category = getattr(builtins, name, None)
    return category if isinstance(category, type) and issubclass(category, Warning) else UserWarning


def serve() -> None:
    """The picture process: read pictures from stdin until it closes — each the name and
    the pickled (switches, draw, grid), both prefixed by their length — and draw each in a
    child forked from this process, which has matplotlib loaded already, :data:`DRAWERS` at
    a time; each child answers (name, error or None, warnings) on stdout in one write."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the command's to handle
    replies = os.dup(1)
    os.dup2(2, 1)  # what a library prints goes to stderr, not into the replies
    gc.disable()  # the modules' objects live as long as the process: no collection scans them
    _prepare()
    gc.freeze()
    gc.enable()
    drawers = max(1, min(DRAWERS, len(os.sched_getaffinity(0))))
    running: dict[int, str] = {}  # child pid: picture name
    while True:
        while not select.select([0], [], [], _POLL)[0]:
            _reap(running, replies, block=False)
        name = _read_part(0)
        payload = _read_part(0)
        if name is None or payload is None:  # the command has closed the pipe
            break
        while len(running) >= drawers:
            _reap(running, replies, block=True)
        pid = os.fork()
        if pid == 0:  # the child: draw, answer, end without the interpreter's clean-up
            code = 1
            try:
                code = _draw(name.decode(), payload, replies)
            finally:
                os._exit(code)
        running[pid] = name.decode()
    while running:
        _reap(running, replies, block=True)
    os._exit(0)  # every answer is written: no clean-up (matplotlib's modules) to wait for


def _read_part(fd: int) -> bytes | None:
    """One length-prefixed part of a picture from ``fd``; None at the end of the input."""
    head = _read_exactly(fd, struct.calcsize(_LENGTH))
    if head is None:
        return None
    return _read_exactly(fd, struct.unpack(_LENGTH, head)[0])


def _read_exactly(fd: int, n: int) -> bytes | None:
    chunks, left = [], n
    while left:
        chunk = os.read(fd, min(left, 1 << 20))
        if not chunk:
            return None
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def _draw(name: str, payload: bytes, replies: int) -> int:
    """Draw one picture (a child of the picture process) and write its answer to
    ``replies`` in one write of at most PIPE_BUF bytes, which the pipe keeps whole beside
    the other children's.  Returns the child's exit code."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        try:
            switches, draw, grid = pickle.loads(payload)
            del payload
            for switch, value in switches.items():  # the command's (contact.output.figures)
                setattr(figures, switch, value)
            draw(grid)
            error = None
        except Exception as err:  # noqa: BLE001 - the picture's failure, sent back
            error = (
                type(err).__name__,
                str(err)[:_TEXT],
                err.errno if isinstance(err, OSError) else None,
                (err.strerror or "")[:_TEXT] if isinstance(err, OSError) else None,
            )
    found = [
        (w.category.__name__, str(w.message)[:_TEXT], str(w.filename)[-_TEXT:], w.lineno)
        for w in caught
    ]
    answer = pickle.dumps((name, error, found))
    while len(answer) > select.PIPE_BUF and found:  # drop warnings rather than the answer
        found.pop()
        answer = pickle.dumps((name, error, found))
    os.write(replies, answer)
    return 0


def _reap(running: dict[int, str], replies: int, block: bool) -> None:
    """Wait for the children that have ended (one at least if ``block``); one that ended
    without its answer (killed, crashed) is answered for here."""
    while running:
        pid, status = os.waitpid(-1, 0 if block else os.WNOHANG)
        if pid == 0:
            return
        name = running.pop(pid, None)
        code = os.waitstatus_to_exitcode(status)
        if name is not None and code != 0:
            how = _ended(code).replace("the picture process", "the process drawing it")
            os.write(replies, pickle.dumps((name, ("", how, None, None), [])))
        block = False


def _prepare() -> None:
    """What every picture needs, loaded before the first one arrives: matplotlib's figure,
    Agg canvas, triangulations and colour-bar axes, and :mod:`.drawing`.  A failure here
    is each picture's failure later."""
    try:
        import matplotlib.backends.backend_agg  # noqa: F401
        import matplotlib.figure  # noqa: F401
        import matplotlib.tri  # noqa: F401
        import mpl_toolkits.axes_grid1  # noqa: F401

        from . import drawing  # noqa: F401
    except Exception:  # noqa: BLE001 - raised again by the picture that needs it
        pass
