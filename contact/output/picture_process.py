"""A process of its own that draws a command's 2D pictures (:mod:`.drawing`).

``contact run`` starts it on rank 0 as soon as it has parsed its arguments
(:func:`start`), before it imports DOLFINx, builds and solves the scene: the process imports
matplotlib meanwhile — on a second core, the import and the first picture's set-up are
about as long as all of a small run's own work — and then waits.  The pictures are built as
before (:func:`contact.output.plots.draw_in_turn`); rank 0 sends each one it draws with
:mod:`.drawing` (the function with its keywords bound and the gathered
:class:`~contact.output.grid.Grid`, pickled: numpy arrays and text) through a pipe, and
collects the outcomes before the command writes ``summary.json``, so that the pictures
exist when the command returns.  Pictures of other kinds (3D, friction) are drawn in the
command's process.

The process imports neither the package's ``__init__`` (which sets up MPI and PETSc, the
FEniCS wheel's start-up) nor DOLFINx: it loads ``contact.output`` under an empty ``contact``
package.  It ignores Ctrl-C (the command handles it) and ends when its input closes: when
the command stops it (:func:`stop`), or ends in any way.  A picture that fails in it is
one warning line as in the command's process; if the process itself ends (killed,
crashed), each picture it did not finish costs one warning line naming the process, and the
results are written all the same.
"""

from __future__ import annotations

import os
import pickle
import signal
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
        self.proc = subprocess.Popen(
            [sys.executable, "-P", "-c", _BOOT.format(root=root)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
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
        switches = {name: getattr(figures, name) for name in figures.SWITCHES}
        payload = pickle.dumps((switches, draw, grid), protocol=pickle.HIGHEST_PROTOCOL)
        try:
            assert self.proc.stdin is not None
            pickle.dump((name, payload), self.proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            self.proc.stdin.flush()
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
        try:
            if self.proc.stdin is not None:
                self.proc.stdin.close()
        except OSError:
            pass
        if idle:
            try:
                self.proc.wait(timeout=GRACE)
            except subprocess.TimeoutExpired:
                pass
        if self.proc.poll() is None:
            self.proc.kill()
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
    return RemoteError(f"{kind}: {message}")


def _category(name: str) -> type[Warning]:
    """The warning class of a built-in category's name; UserWarning for any other (a
    library's own category is not imported here for it)."""
    import builtins

    category = getattr(builtins, name, None)
    return category if isinstance(category, type) and issubclass(category, Warning) else UserWarning


def serve() -> None:
    """The picture process: read (name, pickled (switches, draw, grid)) from stdin until it
    closes, set the command's switches of :mod:`.figures`, call ``draw(grid)`` for each and
    answer (name, error or None, warnings) on stdout."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the command's to handle
    replies = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # what a library prints goes to stderr, not into the replies
    requests = sys.stdin.buffer
    _prepare()
    while True:
        try:
            name, payload = pickle.load(requests)
        except EOFError:  # every answer is flushed: end without the interpreter's clean-up
            os._exit(0)  # (matplotlib's modules), which the command would wait for
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
                    str(err),
                    err.errno if isinstance(err, OSError) else None,
                    err.strerror if isinstance(err, OSError) else None,
                )
        found = [(w.category.__name__, str(w.message), w.filename, w.lineno) for w in caught]
        pickle.dump((name, error, found), replies, protocol=pickle.HIGHEST_PROTOCOL)
        replies.flush()


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
