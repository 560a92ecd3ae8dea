"""Compile every variant of the equilibration's C kernels with warnings as errors.

``make lint`` runs it: each kernel of ``contact/adaptivity/equilibration/kernels`` for every
reference element a scene can ask for (2D and 3D; the flux of P1 and P2 solutions and the
lowest-order flux of a P1 solution; the stress of P1 and P2 solutions), with each set of
optimization flags the cache builds with (the warnings that need the optimizer's analysis
differ between them) and ``-Wall -Wextra -Werror``, into a temporary folder.  Prints one
line per compile; exit 1 with the compiler's messages on any warning or error.  With
``--stamp FILE`` a check is skipped when FILE records the same recipe (the SHA-256 of the
sources, the variants, the flags and the compiler's ``--version``), and FILE is written
after a check without a warning.

    python tools/check_kernels.py [--sources DIR] [--kernel NAME] [--jobs N] [--stamp FILE]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from math import comb
from pathlib import Path

import contact  # noqa: F401 - MPI before the FEniCS modules
from contact.adaptivity.equilibration import compiled
from contact.adaptivity.equilibration.reference import reference
from contact.adaptivity.equilibration.stress import EXTRA

#: the degrees of u_h a scene takes (mesh.degree)
DEGREES = (1, 2)


def variants() -> list[tuple[str, dict[str, int]]]:
    """(kernel, constants) of every library a scene can build."""
    out = []
    for d in (2, 3):
        for q, p in [(p, p) for p in DEGREES] + [(0, 1)]:  # (flux degree, degree of u_h)
            out.append(("eqlb", compiled.dimensions(reference(d, q, p), comb(p + d, d))))
        for p in DEGREES:
            out.append(("stress", compiled.stress_dimensions(reference(d, p + EXTRA))))
    return out


def check(name: str, dims: dict[str, int], flags: tuple[str, ...]) -> tuple[str, str]:
    """A line naming the compile and its outcome, and the compiler's messages."""
    label = f"{name} {' '.join(f'{k}={v}' for k, v in dims.items())} {' '.join(flags)}"
    with tempfile.TemporaryDirectory(prefix="contact-kernels-") as tmp:
        t0 = time.perf_counter()
        try:
            run = compiled.compile_in(
                Path(tmp), name, dims, (*flags, *compiled.WERROR), compiled.compiler()
            )
        except OSError as err:
            return f"FAIL {label}: {err}", str(err)
        seconds = time.perf_counter() - t0
    ok = run.returncode == 0 and not run.stderr.strip()
    return f"{'ok  ' if ok else 'FAIL'} {label} ({seconds:.1f} s)", "" if ok else run.stderr


def recipe(jobs: list) -> str:
    """The SHA-256 of what a check depends on."""
    cc = compiled.compiler()
    what = {
        "sources": {f"{n}/{f}": hashlib.sha256(t).hexdigest() for n in compiled.KERNELS
                    for f, t in compiled.sources(n).items()},
        "jobs": jobs,
        "werror": compiled.WERROR,
        "common": compiled.COMMON,
        "cc": cc,
        "version": compiled.compiler_version(cc),
    }  # fmt: skip
    return hashlib.sha256(json.dumps(what, sort_keys=True).encode()).hexdigest()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sources", type=Path, help="the kernels' folder (default: the package's)")
    parser.add_argument(
        "--kernel", action="append", choices=sorted(compiled.KERNELS), help="only these kernels"
    )
    parser.add_argument("--jobs", type=int, default=2, help="compiles at a time (default 2)")
    parser.add_argument("--stamp", type=Path, help="skip if this file records the same recipe")
    args = parser.parse_args(argv)
    if args.sources:
        compiled.SOURCES = args.sources.resolve()
    jobs = [
        (name, dims, flags)
        for name, dims in variants()
        if not args.kernel or name in args.kernel
        for flags in compiled.FLAGS
    ]
    digest = recipe(jobs)
    if args.stamp and args.stamp.is_file() and args.stamp.read_text().strip() == digest:
        print(f"check_kernels: {len(jobs)} compiles unchanged since the last check ({args.stamp})")
        return 0
    failed = 0
    with ThreadPoolExecutor(max_workers=max(args.jobs, 1)) as pool:
        for line, messages in pool.map(lambda job: check(*job), jobs):
            print(line, flush=True)
            if messages:
                failed += 1
                print(messages.rstrip(), file=sys.stderr, flush=True)
    print(f"check_kernels: {len(jobs) - failed} of {len(jobs)} compiles without a warning")
    if failed:
        return 1
    if args.stamp:
        args.stamp.write_text(digest + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
