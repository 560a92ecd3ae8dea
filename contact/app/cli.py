"""Command line:  contact run SCENE.yaml [-o OUTDIR] [--set key.path=value ...] [--debug]
               contact study STUDY.yaml [-o OUTDIR] [--debug]

Exit codes (:mod:`contact.app.failures`): 0 solved and written; 1 the solver did not converge
(an adaptive run keeps its completed levels); 2 bad input (one line on stderr naming the
key, file or option); 3 internal error (one line; ``--debug`` or ``CONTACT_DEBUG=1`` adds
the traceback); 130 interrupted (Ctrl-C; one line); 143 terminated (SIGTERM; one line, as
Ctrl-C).  Under MPI a failure raised on every
rank is reported once by rank 0; a failure on some ranks only is reported by each of them
and ends the job with ``MPI_Abort`` and the same exit code (the other ranks would wait
forever; the rules are in :mod:`contact.app.failures`).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import gc
import os
import signal
import sys
import time
import traceback
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import numpy as np
from mpi4py import MPI

from ..base.errors import ConfigError
from ..output import picture_process
from . import failures

if TYPE_CHECKING:
    from ..output.report import Report
    from ..setup.scene_config import SceneConfig


class _Parser(argparse.ArgumentParser):
    """Usage errors are one line on stderr with exit code 2, like bad scene input."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"contact: error: {message} (see {self.prog} --help)\n")


_DEBUG_HELP = "print the traceback of an internal error (also: environment CONTACT_DEBUG=1)"


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="contact", description="Contact problems by semismooth Newton on DOLFINx.")
    p.add_argument("--version", action="version", version=_version())
    sub = p.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="solve one scene and write its output folder")
    run.add_argument("scene", help="scene YAML file (see configs/)")
    run.add_argument("-o", "--output", help="output folder (default: results/<scene name>)")
    run.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scene key, e.g. --set solver.method=min (repeatable)",
    )
    run.add_argument("-q", "--quiet", action="store_true", help="no per-iteration progress")
    run.add_argument("--debug", action="store_true", help=_DEBUG_HELP)
    study = sub.add_parser(
        "study",
        help="run a parameter study (a sweep over methods, meshes, ...) "
        "and write study.csv and speed_accuracy.png",
    )
    study.add_argument("study", help="study YAML file (see configs/studies/)")
    study.add_argument(
        "-o", "--output", help="output folder (default: results/studies/<study name>)"
    )
    study.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a key of the study's scene (after the study's own 'set'), "
        "e.g. --set mesh.cells=[32,32] (repeatable)",
    )
    study.add_argument("-q", "--quiet", action="store_true", help="no per-run progress")
    study.add_argument("--debug", action="store_true", help=_DEBUG_HELP)
    return p


def _say(comm: MPI.Comm, *args, **kw) -> None:
    if comm.rank == 0:
        print(*args, **kw, flush=True)


def _error(comm: MPI.Comm, line: str) -> None:
    """A failure's message, said by rank 0 on stderr as one line of at most
    :data:`~contact.app.failures.MAX_LINE` characters (:func:`~contact.app.failures.one_line`,
    as every message the command prints on stderr)."""
    if comm.rank == 0:
        print(failures.one_line(line), file=sys.stderr, flush=True)


def one_line_warning(message, category, filename, lineno, file=None, line=None):
    """Every warning as one line on stderr (at most MAX_LINE characters): the project's
    (ContactWarning) ``contact: warning: <message>``, any other (a library's)
    ``contact: warning: <Category>: <message> (<file>:<line>)`` — not Python's two lines
    with the source line."""
    from ..base.errors import ContactWarning

    text = (
        f"contact: warning: {message}"
        if issubclass(category, ContactWarning)
        else f"contact: warning: {category.__name__}: {message} ({Path(filename).name}:{lineno})"
    )
    print(failures.one_line(text), file=sys.stderr, flush=True)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    warnings.showwarning = one_line_warning
    comm = MPI.COMM_WORLD
    debug = args.debug or os.environ.get("CONTACT_DEBUG", "") not in ("", "0")
    if args.command == "run" and comm.rank == 0 and _asks_for_pictures(args):
        # matplotlib is imported there while this process imports DOLFINx and solves
        picture_process.start()
    try:
        return _main(args, comm, debug)
    finally:
        picture_process.stop()


def _asks_for_pictures(args: argparse.Namespace) -> bool:
    """Whether ``contact run`` will draw pictures, as far as the scene file's ``output.png``
    and the ``--set output.png=…`` overrides say, read without validating (a file that
    cannot be read says yes): the picture process is started only for such a run.  The
    validated scene decides: a process started for a run without pictures is stopped once
    the scene is loaded, and a run that draws pictures without one draws them itself."""
    import yaml

    try:
        scene = yaml.safe_load(Path(args.scene).read_text())
        png = scene["output"]["png"] if "png" in scene.get("output", {}) else True
        for item in args.overrides:
            key, _, value = item.partition("=")
            if key.strip() == "output.png":
                png = yaml.safe_load(value)
    except Exception:  # noqa: BLE001 - bad input is reported when the scene is loaded
        return True
    return png is not False


def _main(args: argparse.Namespace, comm: MPI.Comm, debug: bool) -> int:
    agree = comm.Dup() if comm.size > 1 else None  # only for agreeing on a failure
    # SIGTERM as Ctrl-C (PETSc's own handler would print its stack and MPI_Abort).  PETSc
    # installs that handler when it starts, so it starts first: ours replaces it.
    from petsc4py import PETSc  # noqa: F401

    previous = _handle(signal.SIGTERM, failures.on_sigterm)
    try:
        code = _study(args, comm) if args.command == "study" else _run(args, comm)
    except _Failed:  # raised on every rank alike, after its message
        code = failures.NOT_CONVERGED
    except ConfigError as err:
        code = _fail(comm, agree, failures.BAD_INPUT, f"contact: error: {err}", debug)
    except (Exception, KeyboardInterrupt) as err:  # noqa: BLE001 - MemoryError, PETSc errors, bugs: one line, exit 3
        if failures.interrupted(err):
            code = _interrupted(comm, agree, debug, *failures.interrupt_report(err))
        else:
            head, tail = (
                "contact: internal error: ",
                "" if debug else " (rerun with --debug for the traceback)",
            )
            what = failures.describe(err, failures.MAX_LINE - len(head) - len(tail) - 10)
            code = _fail(comm, agree, failures.INTERNAL, head + what + tail, debug)
    if agree is not None:  # every rank is here: a failure that was not agreed on aborted
        agree.Free()
    if previous is not None:
        signal.signal(signal.SIGTERM, previous)
    return code


#: the cyclic garbage collector is off while a command loads its modules, configuration and
#: scene, and what they loaded is then frozen out of its later collections (gc.freeze): they
#: live until the process ends, and scanning them cost a tiny run about a tenth of its CPU
#: time (demos/RESULTS.md §14), once per process (a program or a test suite that calls main()
#: many times freezes only what its first command loaded); False: the collector runs
#: throughout (the old path)
FREEZE_LOADED = True
_frozen: list[bool] = []  # [True] once a command of this process froze what it loaded


@contextlib.contextmanager
def loading():
    """The collector off in the block (:data:`FREEZE_LOADED`); at its end the objects alive
    are moved to the collector's permanent generation and the collector is on again (if it
    was on before).  Cycles that die later among those objects are not collected: they are
    the modules and the first scene, which the process keeps anyway."""
    if not FREEZE_LOADED or _frozen or not gc.isenabled():
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        gc.enable()
        _frozen.append(True)


def _handle(signum: int, handler: Any) -> Any:
    """Install ``handler`` for ``signum``; the previous one (None where main() runs outside
    the main thread, which cannot handle signals)."""
    try:
        return signal.signal(signum, handler)
    except ValueError:
        return None


def _interrupted(comm: MPI.Comm, agree: MPI.Comm | None, debug: bool, code: int, line: str) -> int:
    """Ctrl-C (SIGTERM): one line and exit code 130 (143), agreed on like any failure
    (:func:`_fail`); a second Ctrl-C or SIGTERM while the ranks agree is ignored (mpiexec's
    own handling of a second Ctrl-C still ends the job at once)."""
    previous = {s: _handle(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        return _fail(comm, agree, code, line, debug)
    finally:
        for signum, handler in previous.items():
            if handler is not None:
                signal.signal(signum, handler)


def _fail(comm: MPI.Comm, agree: MPI.Comm | None, code: int, line: str, debug: bool) -> int:
    """Report a failure in one line (capped, :func:`contact.app.failures.one_line`) and return
    its exit code.  Under MPI the failing ranks first wait up to AGREE_SECONDS for every
    rank to fail (:func:`contact.app.failures.all_failed`): then they agree on one code and
    line — an interrupt's if any rank was interrupted, else rank 0's —, rank 0 alone
    reports and all return that code; otherwise each failing rank reports with its rank
    and calls MPI_Abort(code), which ends the job with that exit code."""
    if debug:
        traceback.print_exc()
    if agree is None:
        print(failures.one_line(line), file=sys.stderr, flush=True)
        return code
    if not failures.all_failed(agree):
        failures.abort(comm, code, line)
    outcomes = agree.allgather((code, line))  # every rank is in this call now
    stops = (failures.INTERRUPTED, failures.TERMINATED)
    code, line = next((o for o in outcomes if o[0] in stops), outcomes[0])
    if comm.rank == 0:
        print(failures.one_line(line), file=sys.stderr, flush=True)
    return code


def _run(args: argparse.Namespace, comm: MPI.Comm) -> int:
    with loading():  # the modules, the configuration and the scene
        from .. import solve
        from ..base import progress
        from ..output import folder, hdf5
        from ..output.run_report import files_text, write_run
        from ..setup.config import load_config
        from ..setup.posed import posed_of
        from ..setup.scene import build_scene
        from ..solvers.result import newton_text, not_converged_text
        from .dispatch import choose_driver, report_of

        hdf5.silence()  # HDF5's error stacks: a failed write is one line (contact.output.folder)
        t0 = time.perf_counter()
        overrides = list(args.overrides) + (["output.verbose=false"] if args.quiet else [])
        cfg = load_config(args.scene, overrides)
        outdir, label = _output_folder(args.output, cfg)
        folder.check_output(outdir, label, comm)  # before meshing and solving
        scene = build_scene(cfg, comm)
        report = report_of(cfg)  # what the run writes, read once from the configuration
        if not report.png:
            picture_process.stop()
        if report.verbose:
            progress.enable(comm)
        method = scene.config.solver.method
        _say(
            comm,
            f"contact: scene {scene.name!r}, model {scene.config.model.type}, method {method}, "
            f"{comm.size} MPI rank(s)",
        )
        _report_posed(scene, comm)
        driver = choose_driver(scene.config)
    if driver == "load_path":
        return _run_steps(scene, report, outdir, label, comm, t0)
    if driver == "adapt":
        return _run_adaptive(scene, report, outdir, label, comm, t0)
    result = solve(scene)
    _say(
        comm,
        f"contact: {result.dofs} DoFs, {newton_text(result)}, "
        f"|Phi| = {result.residual:.3e}, reason {result.reason}, {result.n_active} active "
        f"nodes",
    )
    if not result.converged:
        _error(
            comm, f"contact: error: solver {method} {not_converged_text(result)}; nothing written"
        )
        return failures.NOT_CONVERGED
    info = write_run(
        outdir, report, posed_of(scene), result, wall=time.perf_counter() - t0, label=label
    )
    _say(comm, f"contact: wrote {outdir}/ ({files_text(info['files'])})")
    return failures.SOLVED


def _report_posed(scene, comm: MPI.Comm) -> None:
    """One line on the exterior facets in no boundary part (the natural condition they
    carry is then a visible choice), and a warning line per boundary part on which a
    declared exact solution misses the scene's condition (collective)."""
    from ..setup.exact_data import warn_exact_mismatches
    from ..setup.untagged import mark_reported, untagged_boundary

    untagged = untagged_boundary(scene.mesh, scene.boundary)
    _say(comm, f"contact: {untagged.line(scene.config.elastic)}")
    mark_reported(scene)  # the public API the run calls warns no second time
    warn_exact_mismatches(scene)


def _output_folder(option: str | None, cfg: SceneConfig) -> tuple[Path, str]:
    """The output folder and how it was chosen (for messages): ``-o``, ``output.dir``
    (relative to the current directory), or ``results/<name>``."""
    if option is not None:
        return _output_option(option), f"-o {_shown(option)}"
    if cfg.output.dir:
        return Path(cfg.output.dir), f"output.dir {_shown(cfg.output.dir)}"
    path = Path("results") / cfg.name
    return path, f"output folder {_shown(str(path))} (from name {_shown(cfg.name)!r})"


def _shown(text: str, limit: int = 80) -> str:
    """``text`` for a message: its start and end around '…' when longer than ``limit``
    characters (the one-line message keeps room for the problem)."""
    half = (limit - 1) // 2
    return text if len(text) <= limit else f"{text[:half]}…{text[-half:]}"


def _output_option(option: str) -> Path:
    """The folder of ``-o``; an empty one is bad input (it is no folder, not the default)."""
    if not option.strip():
        raise ConfigError("-o: the output folder must not be empty (leave -o out for the default)")
    return Path(option)


def _run_adaptive(
    scene, report: Report, outdir: Path, label: str, comm: MPI.Comm, t0: float
) -> int:
    """The adaptive loop, writing what ``report`` says into one atomic folder.  If the
    solver fails on level k > 0, levels 0 … k−1 are kept: the folder is written as complete
    for them, with ``converged: false`` and ``failed_level: k`` in summary.json, and the
    exit code is 1."""
    from ..drivers.adaptive import AdaptResult, format_table
    from ..hp.adapt import adapt
    from ..output import folder
    from ..output.run_report import files_text, level_writer, write_adaptive

    a = scene.config.adapt
    assert a is not None  # _run chose the adaptive loop for it
    _say(
        comm,
        f"contact: adaptive loop, strategy {a.strategy} (theta {a.theta}), "
        f"at most {a.max_levels} levels / {a.max_dofs} DoFs",
    )
    with folder.atomic_folder(outdir, comm, label) as tmp:
        write_level = level_writer(tmp, report, comm)
        every = report.levels == "all"  # else the last level's files only
        result = adapt(
            scene,
            on_level=lambda lv: write_level(lv) if every and lv.result.converged else None,
            keep=_kept_levels(report),
        )
        last = result.levels[-1].result
        failed = None
        if not last.converged:
            k = len(result.levels) - 1
            kept = (
                f"kept levels 0-{k - 1} in {outdir}/ (summary.json: converged false)"
                if k
                else "nothing written"
            )
            hint = f" ({last.hint})" if last.hint else ""
            _error(
                comm,
                f"contact: error: solver did not converge on level {k} ({last.reason}), "
                f"last |Phi| = {last.residual:.3e}{hint}; {kept}",
            )
            if k == 0:
                raise _Failed()
            failed = {"converged": False, "failed_level": k, "failed_reason": last.reason}
            result = AdaptResult(result.levels[:-1], stop=result.stop)
        if not every:
            write_level(result.levels[-1])
        info = write_adaptive(
            tmp,
            report,
            result,
            wall=time.perf_counter() - t0,
            failure=failed,
            files=write_level.files,
        )
    _say(comm, f"contact: stopped: {result.stop}")
    if not report.verbose:  # the loop printed the table as it went otherwise
        _say(comm, format_table(result.rows))
    _say(comm, f"contact: wrote {outdir}/ ({files_text(info['files'])})")
    return failures.NOT_CONVERGED if failed else failures.SOLVED


def _kept_levels(report: Report):
    """Which levels the adaptive loop keeps whole for the pictures drawn after it: with
    ``adapt.pictures`` ≤ 2 (the first level and the last) or no pictures, level 0 or
    none, and the loop releases the others as it goes (the files of every level are
    written as it goes); with more, the levels between are known only at the end, and it
    keeps them all."""
    count = report.pictures if report.png else 0
    if count > 2:
        return None
    return lambda level: count > 0 and level.index == 0


def _run_steps(scene, report: Report, outdir: Path, label: str, comm: MPI.Comm, t0: float) -> int:
    """A load path (or a frictional or hyperelastic scene, one step at t = 1), writing into one
    atomic folder step by step.  If step k > 1 does not converge, steps 1 … k−1 are kept (the
    folder is complete for them, summary.json has ``converged: false`` and
    ``failed_step: k``) and the exit code is 1; a failing first step writes nothing."""
    from ..output import folder
    from ..output.run_report import files_text
    from ..output.step_report import StepWriter
    from ..setup.run import run_load_path
    from ..solvers.energy_search import tangent_text

    with folder.atomic_folder(outdir, comm, label) as tmp:
        writer = StepWriter(tmp, report, comm)

        def on_step(s) -> None:  # one line per step as it finishes, then its files
            fr = s.result.friction
            counts = (
                ""
                if fr is None
                else "  "
                + "  ".join(
                    f"{name} {comm.allreduce(int(np.sum(fr['status'] == code)))}"
                    for code, name in enumerate(("separated", "stick", "slip"))
                )
            )
            tangent = tangent_text(s.result.tangent_log)  # what the energy search did
            _say(
                comm,
                f"contact: step {s.index} t = {s.time:g}: {s.result.dofs} DoFs, "
                f"{s.result.iterations} Newton iterations, reason {s.result.reason}{counts}"
                + (f"; {tangent}" if tangent else ""),
            )
            if s.branch:  # the energy search found no stable state: the branch followed
                _say(comm, f"contact: {s.branch}")
            writer(s)

        # each step's figures go to disk as it finishes (StepWriter): the path forgets them
        path = run_load_path(scene, on_step=on_step, forget=True)
        failed = None
        if not path.converged:
            k, last = path.count, path.steps[-1].result
            steps = "step 1" if k == 2 else f"steps 1-{k - 1}"
            kept = (
                f"kept {steps} in {outdir}/ (summary.json: converged false)"
                if k > 1
                else "nothing written"
            )
            _error(
                comm, f"contact: error: {path.failure}; last |Phi| = {last.residual:.3e}; {kept}"
            )
            if k == 1:
                raise _Failed()
            failed = {"converged": False, "failed_step": k, "failed_reason": last.reason}
            path = dataclasses.replace(path, steps=path.steps[:-1])
        info = writer.finish(path, wall=time.perf_counter() - t0, failure=failed)
    _say(comm, f"contact: wrote {outdir}/ ({files_text(info['files'])})")
    return failures.NOT_CONVERGED if failed else failures.SOLVED


def _study(args: argparse.Namespace, comm: MPI.Comm) -> int:
    """Exit code 0 once study.csv is written, even if some runs failed (they are rows)."""
    with loading():
        from ..output import hdf5
        from .study import load_study, run_study

        hdf5.silence()
        study = load_study(args.study, overrides=args.overrides)
    given = args.output is not None
    outdir = _output_option(args.output) if given else Path("results") / "studies" / study.name
    label = (
        f"-o {_shown(args.output)}"
        if given
        else f"output folder {_shown(str(outdir))} (from name {study.name!r})"
    )
    run_study(study, outdir, comm=comm, verbose=not args.quiet, label=label)
    return failures.SOLVED


def _version() -> str:
    from ..base.version import __version__

    return f"contact {__version__}"


class _Failed(Exception):
    """A run that did not converge, after its message was printed (exit code 1)."""


if __name__ == "__main__":
    sys.exit(main())
