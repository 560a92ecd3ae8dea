"""Command line:  contact run SCENE.yaml [-o OUTDIR] [--set key.path=value ...]
               contact study STUDY.yaml [-o OUTDIR]

Exit codes: 0 solved and written; 1 the solver did not converge (nothing written);
2 bad input (one line on stderr naming the key or file).
"""
from __future__ import annotations

import argparse
import sys

import numpy as np
import time
import warnings
from pathlib import Path
from typing import NoReturn

from mpi4py import MPI

from .config import ConfigError


class _Parser(argparse.ArgumentParser):
    """Usage errors are one line on stderr with exit code 2, like bad scene input."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"contact: error: {message} (see {self.prog} --help)\n")


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="contact", description="Contact problems by semismooth Newton on DOLFINx.")
    p.add_argument("--version", action="version", version=_version())
    sub = p.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="solve one scene and write its output folder")
    run.add_argument("scene", help="scene YAML file (see configs/)")
    run.add_argument("-o", "--output", help="output folder (default: results/<scene name>)")
    run.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                     help="override a scene key, e.g. --set solver.method=min (repeatable)")
    run.add_argument("-q", "--quiet", action="store_true", help="no per-iteration progress")
    study = sub.add_parser("study", help="run a parameter study (a sweep over methods, meshes, ...) "
                                         "and write study.csv and speed_accuracy.png")
    study.add_argument("study", help="study YAML file (see configs/studies/)")
    study.add_argument("-o", "--output", help="output folder (default: results/studies/<study name>)")
    study.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                       help="override a key of the study's scene (after the study's own 'set'), "
                            "e.g. --set mesh.cells=[32,32] (repeatable)")
    study.add_argument("-q", "--quiet", action="store_true", help="no per-run progress")
    return p


def _say(comm: MPI.Comm, *args, **kw) -> None:
    if comm.rank == 0:
        print(*args, **kw, flush=True)


def _one_line_warning(message, category, filename, lineno, file=None, line=None, _default=warnings.showwarning):
    """The project's warnings (ContactWarning) as one line on stderr; others as Python prints them."""
    from .surfaces import ContactWarning

    if issubclass(category, ContactWarning):
        print(f"contact: warning: {message}", file=sys.stderr, flush=True)
    else:
        _default(message, category, filename, lineno, file, line)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    warnings.showwarning = _one_line_warning
    comm = MPI.COMM_WORLD
    try:
        return _study(args, comm) if args.command == "study" else _run(args, comm)
    except _Failed:
        return 1
    except ConfigError as err:
        if comm.rank == 0:
            print(f"contact: error: {err}", file=sys.stderr, flush=True)
        return 2
    except Exception:
        if comm.size == 1:
            raise
        import traceback  # a bug on one rank must not leave the others waiting forever

        traceback.print_exc()
        comm.Abort(1)
        raise


def _run(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from . import load_scene, solve
    from .report import files_text, write_run

    t0 = time.perf_counter()
    overrides = list(args.overrides) + (["output.verbose=false"] if args.quiet else [])
    scene = load_scene(args.scene, overrides, comm=comm)
    outdir = Path(args.output or scene.cfg["output"]["dir"] or Path("results") / scene.name)
    method = scene.cfg["solver"]["method"]
    _say(comm, f"contact: scene {scene.name!r}, model {scene.cfg['model']['type']}, method {method}, "
               f"{comm.size} MPI rank(s)")
    if scene.cfg.get("load") or (scene.cfg.get("friction") or {}).get("law", "none") != "none":
        return _run_steps(scene, outdir, comm, t0)
    if scene.cfg.get("adapt"):
        return _run_adaptive(scene, outdir, comm, t0)
    result = solve(scene)
    polished = f" (+{result.polish_solves} polishing)" if result.polish_solves else ""
    _say(comm, f"contact: {result.dofs} DoFs, {result.iterations} Newton iterations{polished}, "
               f"|Phi| = {result.residual:.3e}, reason {result.reason}, {result.n_active} active nodes")
    if not result.converged:
        if comm.rank == 0:
            print(f"contact: error: solver {method} did not converge ({result.reason}) after "
                  f"{result.iterations} iterations, last |Phi| = {result.residual:.3e}; nothing written",
                  file=sys.stderr, flush=True)
        return 1
    info = write_run(outdir, scene, result, wall=time.perf_counter() - t0)
    _say(comm, f"contact: wrote {outdir}/ ({files_text(info['files'])})")
    return 0


def _run_adaptive(scene, outdir: Path, comm: MPI.Comm, t0: float) -> int:
    from . import io
    from .adapt import adapt, format_table
    from .report import files_text, level_writer, write_adaptive

    a = scene.cfg["adapt"]
    _say(comm, f"contact: adaptive loop, strategy {a['strategy']} (theta {a['theta']}), "
               f"at most {a['max_levels']} levels / {a['max_dofs']} DoFs")
    with io.atomic_folder(outdir, comm) as tmp:
        result = adapt(scene, on_level=level_writer(tmp, scene))
        last = result.levels[-1].result
        if not last.converged:
            if comm.rank == 0:
                print(f"contact: error: solver did not converge on level {len(result.levels) - 1} "
                      f"({last.reason}), last |Phi| = {last.residual:.3e}; nothing written",
                      file=sys.stderr, flush=True)
            raise _Failed()
        info = write_adaptive(tmp, scene, result, wall=time.perf_counter() - t0)
    _say(comm, f"contact: stopped: {result.stop}")
    if not scene.cfg["output"]["verbose"]:  # the loop printed the table as it went otherwise
        _say(comm, format_table(result.rows))
    _say(comm, f"contact: wrote {outdir}/ ({files_text(info['files'])})")
    return 0


def _run_steps(scene, outdir: Path, comm: MPI.Comm, t0: float) -> int:
    """A load path (or a frictional scene, one step at t = 1): per-step output."""
    from . import io
    from .loadreport import StepWriter
    from .report import files_text
    from .solvers.loadpath import run_load_path

    with io.atomic_folder(outdir, comm) as tmp:
        writer = StepWriter(tmp, scene)

        def on_step(s) -> None:   # one line per step as it finishes, then its files
            fr = s.result.friction
            counts = "" if fr is None else "  " + "  ".join(
                f"{name} {comm.allreduce(int(np.sum(fr['status'] == code)))}"
                for code, name in enumerate(("separated", "stick", "slip")))
            _say(comm, f"contact: step {s.index} t = {s.time:g}: {s.result.dofs} DoFs, "
                       f"{s.result.iterations} Newton iterations, reason {s.result.reason}{counts}")
            writer(s)

        path = run_load_path(scene, on_step=on_step)
        if not path.converged:
            last = path.steps[-1].result
            if comm.rank == 0:
                print(f"contact: error: {path.stop}, last |Phi| = {last.residual:.3e}; nothing written",
                      file=sys.stderr, flush=True)
            raise _Failed()
        info = writer.finish(path, wall=time.perf_counter() - t0)
    _say(comm, f"contact: wrote {outdir}/ ({files_text(info['files'])})")
    return 0


def _study(args: argparse.Namespace, comm: MPI.Comm) -> int:
    """Exit code 0 once study.csv is written, even if some runs failed (they are rows)."""
    from .study import load_study, run_study

    study = load_study(args.study, overrides=args.overrides)
    outdir = Path(args.output) if args.output else Path("results") / "studies" / study.name
    run_study(study, outdir, comm=comm, verbose=not args.quiet)
    return 0


def _version() -> str:
    from . import __version__

    return f"contact {__version__}"


class _Failed(Exception):
    """A run that failed after its message was printed (the output folder is discarded)."""


if __name__ == "__main__":
    sys.exit(main())
