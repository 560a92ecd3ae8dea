"""Write demos/RESULTS.md from the CSVs that `make bench` left in demos/results/.

Every number in the report is read from those CSVs here (nothing is typed in by hand);
the prose around them, which names what the charts show and why, lives in
demos/results_templates/: one Markdown file per section function, in blocks that start
at a line ``<!-- name -->`` with string.Template placeholders ``${name}`` that
:func:`prose` fills, and explanations.json, the tables of why failed runs failed and of
the measurements behind design choices.  Sections whose CSVs are missing are reported as
missing, so a partial run still gives an honest report.

    python demos/make_results.py            (run by demos/run_bench.py as its last step)
    python demos/make_results.py --results DIR --out FILE
"""

from __future__ import annotations

import argparse
import csv
import datetime
import functools
import json
import math
import os
import platform
import re
import statistics
import string
import subprocess
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RES = ROOT / "demos" / "results"
#: the report's prose: Markdown with string.Template placeholders ($name), filled here
TEMPLATES = ROOT / "demos" / "results_templates"
#: the report's tables of explanations and quoted measurements
DATA = json.loads((TEMPLATES / "explanations.json").read_text(encoding="utf-8"))
METHODS = ("fb", "min", "blend", "vinewtonrsls", "vinewtonssls")
EX9_RADIUS = 0.697965148223374  # PETSc ex9: the exact free-boundary radius
STEP41_SOLVES = 19  # deal.II step-41 results.dox: "Newton iteration 0" … "18"


# ------------------------------------------------------------------------------ reading
def _value(v: str):
    if v in ("True", "False"):
        return v == "True"
    try:
        f = float(v)
    except ValueError:
        return v
    return int(f) if f.is_integer() and "." not in v and "e" not in v.lower() else f


def rows(path: Path) -> list[dict] | None:
    if not path.is_file():
        return None
    with open(path, newline="") as fh:
        return [{k: _value(v) for k, v in r.items()} for r in csv.DictReader(fh)]


def study(name: str) -> tuple[list[dict] | None, list[dict] | None]:
    return rows(RES / name / "study.csv"), rows(RES / name / "levels.csv")


def table(header: list[str], body: list[list]) -> str:
    def cell(c) -> str:
        return str(c).replace("|", "\\|")  # a literal | (e.g. |F_t|) must not end the cell

    lines = ["| " + " | ".join(cell(h) for h in header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(c) for c in r) + " |" for r in body]
    return "\n".join(lines)


def g(x, digits: int = 3) -> str:
    return "–" if x in ("", None) else f"{x:.{digits}g}" if isinstance(x, float) else str(x)


def failure_table(fails: list[dict], explain) -> str:
    """The failed runs of a stability map with why each failed (``explain(case, method,
    outcome)``)."""
    return table(
        ["case", "method", "outcome", "iterations", "SNES reason", "why"],
        [
            [
                r["case"],
                r["method"],
                r["outcome"],
                r["newton_iterations"],
                r["reason"],
                explain(r["case"], r["method"], r["outcome"]),
            ]
            for r in fails
        ],
    )


def pct(x) -> str:
    return "–" if x in ("", None) else f"{100 * x:+.2f} %"


def solves(r: dict) -> int:
    """Linear solves of a run or level: Newton iterations + active-set polishing solves."""
    return int(r["newton_iterations"]) + int(r.get("polish_solves") or 0)


def its_text(r: dict) -> str:
    """'n' Newton iterations, or 'n+p' with p polishing solves (as contact.solvers.solves_text;
    this script reads CSVs only and does not import the package)."""
    p = r.get("polish_solves")
    return (
        f"{r['newton_iterations']}+{p}" if p not in (None, "", 0) else str(r["newton_iterations"])
    )


@functools.cache
def template_blocks(section: str) -> dict[str, str]:
    """The blocks of demos/results_templates/<section>.md: each starts at a line
    ``<!-- name -->`` and ends before the next (without its final newline)."""
    text = (TEMPLATES / f"{section}.md").read_text(encoding="utf-8")
    pieces = re.split(r"^<!-- (\w+) -->\n", text, flags=re.MULTILINE)
    return {pieces[i]: pieces[i + 1].removesuffix("\n") for i in range(1, len(pieces), 2)}


def prose(section: str, block: str, **values) -> str:
    """The block ``block`` of the section's template with its placeholders ($name) filled
    from ``values``."""
    return string.Template(template_blocks(section)[block]).substitute(values)


def missing(what: str) -> str:
    return prose("missing", "not_available", what=what)


# ----------------------------------------------------------------------------- sections
def header() -> str:
    commit = (
        subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
        ).stdout.strip()
        or "unknown"
    )
    cpu = (
        next(
            (
                ln.split(":", 1)[1].strip()
                for ln in Path("/proc/cpuinfo").read_text().splitlines()
                if ln.startswith("model name")
            ),
            platform.processor(),
        )
        if Path("/proc/cpuinfo").is_file()
        else "?"
    )
    mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    timing = rows(RES / "timings.csv") or []
    total = sum(float(r["seconds"]) for r in timing)
    out = [
        prose(
            "header",
            "results_speed_against_accuracy",
            date=datetime.date.today(),
            commit=commit,
            cpu=cpu,
            cores=os.cpu_count(),
            mem=f"{mem:.0f}",
        )
    ]
    if timing:
        out += [
            "",
            f"`make bench` took {total / 60:.1f} minutes:",
            "",
            table(["step", "seconds"], [[f"`{r['step']}`", r["seconds"]] for r in timing]),
        ]
    return "\n".join(out) + "\n"


def newton_512() -> str:
    data = rows(RES / "newton_512.csv")
    out = [prose("newton_512", "newton_methods_on_the")]
    if not data:
        return "\n".join(out) + "\n" + missing("newton_512.csv")
    out += [
        prose(
            "newton_512",
            "configs_signorini_square_yaml",
            table=table(
                [
                    "method",
                    "DoFs",
                    "Newton its",
                    "polish",
                    "seconds",
                    "s / solve",
                    "peak MiB",
                    "speed-up vs vinewtonrsls",
                ],
                [
                    [
                        r["method"],
                        r["dofs"],
                        r["iterations"],
                        r.get("polish", ""),
                        g(r["seconds"]),
                        g(r["seconds_per_iteration"]),
                        g(r["peak_rss_mib"], 4),
                        r["speedup_vs_vinewtonrsls"],
                    ]
                    for r in data
                ],
            ),
        )
    ]
    by = {r["method"]: r for r in data}
    if "fb-nopolish" in by and "min" in by:
        out += [
            prose(
                "newton_512",
                "min_needs",
                by_min_iterations=by["min"]["iterations"],
                by_fb_nopolish_iterations=by["fb-nopolish"]["iterations"],
                by_fb_iterations=by["fb"]["iterations"],
                by_fb_get_polish=by["fb"].get("polish", "?"),
            )
        ]
    return "\n".join(out) + "\n"


def _curves(levels: list[dict], key: str) -> dict[tuple, list[dict]]:
    out: dict[tuple, list[dict]] = {}
    for r in levels:
        if r["converged"] and r.get(key, "") != "":
            out.setdefault((r["method"], r["strategy"]), []).append(r)
    return out


def _open(
    heading: str, name: str, chart: str
) -> tuple[list[dict] | None, list[dict] | None, list[str]]:
    """A section on study ``name``: its rows, level rows and the heading lines with the
    chart embedded (or the "not available" line, then the rows are None)."""
    runs, levels = study(name)
    if not runs or not levels:
        return None, None, [heading, "", missing(f"demos/results/{name}")]
    return runs, levels, [heading, "", f"![{name} {chart}](results/{name}/{chart}.png)", ""]


def speed_accuracy(name: str, title: str, key: str, what: str, note: str = "") -> str:
    runs, levels, out = _open(f"### {title}", name, "speed_accuracy")
    if not levels:
        return "\n".join(out)
    curves = _curves(levels, key)
    # the accuracy every curve reaches, and the time/DoFs each needs for it
    target = max(min(abs(r[key]) for r in c) for c in curves.values())
    body = []
    for (m, s), c in curves.items():
        first = next(r for r in c if abs(r[key]) <= target * (1 + 1e-9))
        last = c[-1]
        body.append(
            [
                m,
                s,
                len(c),
                last["dofs"],
                g(abs(last[key])),
                g(last["seconds"]),
                first["dofs"],
                g(first["seconds"]),
            ]
        )
    body.sort(key=lambda r: float(r[-1]))
    out += [
        table(
            [
                "method",
                "refinement",
                "levels",
                "final DoFs",
                f"final {what}",
                "run seconds",
                f"DoFs to {what} ≤ {target:.3g}",
                f"seconds to {what} ≤ {target:.3g}",
            ],
            body,
        ),
        "",
    ]
    front = Counter((r["method"], r["strategy"]) for r in levels if r.get("pareto") is True)
    n_front = sum(front.values())
    fastest = body[0]
    out += [
        prose(
            "speed_accuracy",
            "the_pareto_front_circled",
            n_front=n_front,
            join=", ".join(f"{m}/{s} ×{k}" for (m, s), k in front.most_common()),
            what=what,
            target=f"{target:.3g}",
            fastest_0=fastest[0],
            fastest_1=fastest[1],
            fastest_1_2=fastest[-1],
            fastest_2=fastest[-2],
            body_1_1=body[-1][-1],
            body_1_0=body[-1][0],
            body_1_1_2=body[-1][1],
        )
    ]
    if note:
        out += ["", note]
    failed = [r for r in runs or [] if not r["converged"]]
    if failed:
        out += [
            "",
            "Failed runs: "
            + "; ".join(f"{r['method']}/{r['strategy']}: {r['failure']}" for r in failed),
        ]
    return "\n".join(out) + "\n"


FRICTION_CASES = ("(h)", "(i)", "(j)")

EXPLAIN = {tuple(e[:3]): e[3] for e in DATA["explain"]}


def _explain(case: str, method: str, what: str) -> str:
    for (prefix, m, o), text in EXPLAIN.items():
        if case.startswith(prefix) and m in (method, "*") and o == what:
            return text
    return prose("_explain", "not_yet_explained_new")


def _line_search_verdict(its: dict) -> str:
    """What backtracking did to fb and min in case (d), read from the counts."""
    said = []
    for m in ("fb", "min"):
        plain, bt = its.get(("(d) plain Newton", m)), its.get(("(d) line search bt", m))
        if plain and bt:
            d = solves(bt) - solves(plain)
            said.append(
                f"{m} {'saves' if d < 0 else 'costs'} {abs(d)} linear "
                f"solve{'s' if abs(d) != 1 else ''}"
                if d
                else f"{m} needs as many"
            )
    return (
        (prose("_line_search_verdict", "with_backtracking", and_join=" and ".join(said)))
        if said
        else ""
    )


def _its(r: dict) -> str:
    """Newton steps of a row, the shortened ones in brackets; **fail** if it did not converge."""
    if not r["converged"]:
        return f"**fail** ({r['newton_iterations']})"
    return f"{r['newton_iterations']}" + (f" ({r['backtracked']})" if r["backtracked"] else "")


def _friction_line_search(folder: Path) -> list[str]:
    """Frictional Newton and its cycles: line_search.csv and line_search_rounding.csv of
    demos/bench/bench_friction_cycle.py."""
    out: list[str] = []
    runs = rows(folder / "line_search.csv") or []
    if runs:
        key = ("case", "start", "form", "method")
        cases = list(dict.fromkeys(tuple(r[k] for k in key) for r in runs))
        by = {(tuple(r[k] for k in key), r["line_search"]): r for r in runs}
        searches = list(dict.fromkeys(r["line_search"] for r in runs))
        body = [
            [*c] + [_its(by[c, ls]) for ls in searches]
            for c in cases
            if any(not by[c, ls]["converged"] or by[c, ls]["backtracked"] for ls in searches)
            or by[c, "basic"]["newton_iterations"] != by[c, "auto"]["newton_iterations"]
        ]
        plain = {c for c in cases if by[c, "basic"]["converged"]}
        kept = sum(
            by[c, "auto"]["newton_iterations"] == by[c, "basic"]["newton_iterations"]
            and not by[c, "auto"]["backtracked"]
            for c in plain
        )
        done = {ls: sum(by[c, ls]["converged"] for c in cases) for ls in searches}
        out += [
            prose(
                "_friction_line_search",
                "frictional_newton_and_its",
                join=", ".join(f"{ls} converges in {done[ls]} of {len(cases)}" for ls in searches),
                kept=kept,
                len_plain=len(plain),
            ),
            "",
            table(["scene", "start", "form", "normal φ", *searches], body),
            "",
        ]
    rounding = rows(folder / "line_search_rounding.csv") or []
    if rounding:
        key = ("case", "form", "linear", "method", "line_search")
        cases = list(dict.fromkeys(tuple(r[k] for k in key) for r in rounding))
        where = list(dict.fromkeys((r["perturbation"], r["threads"]) for r in rounding))
        by = {(tuple(r[k] for k in key), (r["perturbation"], r["threads"])): r for r in rounding}
        out += [
            prose("_friction_line_search", "whether_newton_converges_per"),
            "",
            table(
                ["case", "form", "linear", "normal φ", "line search"]
                + [f"ε = {g(e)}, {t} thr." if e else "as assembled" for e, t in where],
                [[*c] + [_its(by[c, w]) for w in where] for c in cases],
            ),
            "",
        ]
    return out


def _friction_rows(its: dict, cases: list[str]) -> str:
    """The paragraph on the friction cases (h)–(j) of the stability map."""
    friction = [c for c in cases if c.startswith(FRICTION_CASES)]
    if not friction:
        return prose("_friction_rows", "h_j_friction_not")
    newton = [m for m in ("fb", "min", "blend")]

    def span(select) -> str:
        vals = [
            its[c, m]["newton_iterations"]
            for c in friction
            if select(c)
            for m in newton
            if (c, m) in its and its[c, m]["converged"]
        ]
        return f"{min(vals)}–{max(vals)}" if vals else "–"

    def failed(select) -> list[str]:
        return [
            f"{c} / {m}"
            for c in friction
            if select(c)
            for m in newton
            if (c, m) in its and not its[c, m]["converged"]
        ]

    hsw = lambda c: c.endswith(" hsw")  # noqa: E731
    proj = lambda c: c.endswith(" projection")  # noqa: E731
    fixed = lambda c: c.endswith(" fixed point")  # noqa: E731
    cured = lambda c: "projection kappa_t" in c or c.endswith("projection bt")  # noqa: E731
    fp = [
        its[c, m].get("fixed_point_iterations")
        for c in friction
        if fixed(c)
        for m in newton
        if (c, m) in its and its[c, m]["converged"]
    ]
    fp = [v for v in fp if v not in ("", None)]
    ratios = [
        its[c, m]["newton_iterations"]
        / its[c.replace(" fixed point", " hsw"), m]["newton_iterations"]
        for c in friction
        if fixed(c)
        for m in newton
        if (c, m) in its
        and its[c, m]["converged"]
        and its.get((c.replace(" fixed point", " hsw"), m), {}).get("converged")
    ]
    bad_proj, bad_hsw = failed(proj), failed(hsw)
    n_proj = sum(1 for c in friction if proj(c)) * len(newton)
    return prose(
        "_friction_rows",
        "h_j_coulomb_friction",
        span_hsw=span(hsw),
        f=f" (failures: {', '.join(bad_hsw)})" if bad_hsw else " everywhere",
        projection_outcome=prose(
            "_friction_rows",
            "projection_fails",
            span_proj=span(proj),
            len_bad_proj=len(bad_proj),
            n_projection_cases=n_proj,
            join_bad_proj=", ".join(bad_proj),
            projection_cycle=prose("friction_shared", "projection_cycle"),
            span_cured=span(cured),
        )
        if bad_proj
        else prose(
            "_friction_rows",
            "projection_guarded",
            span_proj=span(proj),
            n_projection_cases=n_proj,
            projection_cycle=prose("friction_shared", "projection_cycle"),
            span_cured=span(cured),
        ),
        min_fp_if_fp_else=min(fp) if fp else "–",
        max_fp_if_fp_else=max(fp) if fp else "–",
        span_fixed=span(fixed),
        f_min=f"{min(ratios):.1f}–{max(ratios):.1f} times the full Newton method's"
        if ratios
        else "–",
    )


def _issue11_rows(its: dict, cell, span) -> list[str]:
    """The bullets of the stress cases (k)–(o) (issue 11) of the stability map."""

    def cells(case: str, methods=METHODS) -> str:
        return ", ".join(f"{m} {cell(case, m)}" for m in methods)

    def got(case: str, method: str):
        return its.get((case, method))

    out = []
    k = ["(k) kappa=1e4 at 128²", "(k) kappa=1e4 at 128², exact CG", "(k) kappa=1e4 at 128², MUMPS"]
    if got(k[0], "min"):
        out.append(
            prose(
                "_issue11_rows",
                "k_e4_at_the",
                cells_k_0_methods_3=cells(k[0], METHODS[:3]),
                cells_k_1_methods_3=cells(k[1], METHODS[:3]),
                cells_k_2_methods_3=cells(k[2], METHODS[:3]),
                cells_k_0_methods_3_2=cells(k[0], METHODS[3:]),
                cell_k_0_plain_newton_min=cell(k[0] + ", plain Newton", "min"),
            )
        )
    l1, l2 = "(l) semi-coercive", "(l) semi-coercive gamg"
    if got(l1, "fb"):
        luck = got(l1, "min")
        out.append(
            prose(
                "_issue11_rows",
                "l_semi_coercive_configs",
                cells_l1=cells(l1),
                cells_l2=cells(l2),
                mumps_note=prose("_issue11_rows", "with_mumps_min_still")
                if luck and luck["converged"]
                else "With MUMPS min fails on that step too. ",
            )
        )
    m = [
        "(m) k = 1 : 1e6",
        "(m) k, f = 1 : 1e6",
        "(m) k, f = 1 : 1e6 at 128²",
        "(m) k, f = 1 : 1e6 at 128², rtol 1e-10",
    ]
    if got(m[0], "fb"):
        lifted = (
            "no node active" if got(m[0], "min")["active_measure"] == 0 else "nearly no contact"
        )
        out.append(
            prose(
                "_issue11_rows",
                "m_coefficient_jump_k",
                cells_m_0=cells(m[0]),
                lifted=lifted,
                cells_m_1=cells(m[1]),
                plain_newton_cells=cells("(d) plain Newton", METHODS[:3]),
                cells_m_2=cells(m[2]),
                cells_g_level_6=cells("(g) level 6"),
                cells_m_3=cells(m[3]),
            )
        )
    n = "(n) Hertz nu = 0.499"
    if got(n, "fb"):
        f, r = got("(f) elastic Hertz", "fb"), got(n, "fb")
        locking = ""
        if r["converged"] and f and f["converged"]:
            locking = prose(
                "_issue11_rows",
                "p1_locks_the_contact",
                pct_r_a_error=pct(r["a_error"]),
                pct_r_p0_error=pct(r["p0_error"]),
                pct_f_a_error=pct(f["a_error"]),
                pct_f_p0_error=pct(f["p0_error"]),
            )
        kry = ""
        if (
            r.get("krylov_iterations") not in (None, "")
            and f
            and f.get("krylov_iterations") not in (None, "")
        ):
            kry = prose(
                "_issue11_rows",
                "the_linear_algebra_suffers",
                r_krylov_iterations=r["krylov_iterations"],
                f_krylov_iterations=f["krylov_iterations"],
            )
        out.append(
            prose(
                "_issue11_rows",
                "n_nearly_incompressible_hertz",
                cells_n=cells(n),
                cells_f_elastic_hertz=cells("(f) elastic Hertz"),
                locking=locking,
                kry=kry,
            )
        )
    o = "(o) 3D Hertz kappa=100 gamg"
    if got(o, "fb"):
        out.append(
            prose(
                "_issue11_rows",
                "o_d_hertz_configs",
                got_o_fb_dofs=got(o, "fb")["dofs"],
                cells_o=cells(o),
                if_got=""
                if got(o, "vinewtonssls")["converged"]
                else prose("_issue11_rows", "vinewtonssls_fails_see_the"),
            )
        )
    out.append(_newton_min_cycle())
    return out


def _newton_min_cycle() -> str:
    """Case (p): plain Newton-min on a P-matrix LCP (demos/bench/bench_newton_min_cycle.py)."""
    data = rows(RES / "newton_min_cycle.csv")
    if not data:
        return "* **(p) Newton-min cycling**: " + missing(
            prose("_newton_min_cycle", "newton_min_cycle_csv")
        )
    p = [r for r in data if r["matrix"].startswith("P-matrix")]
    plain = next(r for r in p if r["method"] == "min" and r["line_search"] == "basic")
    others = ", ".join(
        f"{r['method']}{'' if r['line_search'] == 'basic' else ' + ' + r['line_search']} "
        f"{r['iterations'] if r['converged'] else 'fails'}"
        for r in p
        if r is not plain
    )
    ctrl = next((r for r in data if r["matrix"].startswith("M-matrix")), None)
    return prose(
        "_newton_min_cycle",
        "p_newton_min_cycling",
        plain_x0_replace=plain["x0"].replace(" ", ", "),
        plain_min=prose(
            "_newton_min_cycle",
            "returns_to_x0_every",
            plain_period=plain["period"],
            plain_iterations=plain["iterations"],
            g_plain_residual=g(plain["residual"]),
        )
        if not plain["converged"]
        else f"converges in {plain['iterations']}",
        others=others,
        m_matrix_steps=f": {ctrl['iterations']} on the 1D Laplacian from the same x0"
        if ctrl
        else "",
    )


def stability() -> str:
    runs, _, out = _open(prose("stability", "stability_map_where_the"), "stability", "stability")
    if not runs:
        return "\n".join(out)
    out += [prose("stability", "configs_studies_stability_yaml")]
    its = {(r["case"], r["method"]): r for r in runs}
    cases = list(dict.fromkeys(r["case"] for r in runs))

    def cell(case: str, method: str) -> str:
        r = its.get((case, method))
        return "–" if r is None else its_text(r) + ("" if r["converged"] else f" ({r['outcome']})")

    def span(prefix: str, method: str) -> str:
        vals = [
            solves(its[c, method]) for c in cases if c.startswith(prefix) and (c, method) in its
        ]
        return f"{min(vals)}–{max(vals)}" if len(set(vals)) > 1 else str(vals[0]) if vals else "–"

    fails = [r for r in runs if not r["converged"]]
    not_applicable = [
        r for r in fails if r["case"].startswith(FRICTION_CASES) and r["method"].startswith("vi")
    ]
    fails = [r for r in fails if r not in not_applicable]
    na = (
        (prose("stability", "friction_runs_the_solvers", len_not_applicable=len(not_applicable)))
        if not_applicable
        else ""
    )
    out += [
        prose(
            "stability",
            "runs_converge_what_each",
            n_converged=len(runs) - len(fails) - len(not_applicable),
            len_runs=len(runs),
            na=na,
        )
    ]
    out += [
        prose(
            "stability",
            "a_biactive_configs_biactive",
            biactive_iterations=", ".join(f"{m} {cell('(a) biactive', m)}" for m in METHODS),
            nearly_biactive_iterations=", ".join(
                f"{m} {cell('(a) nearly biactive', m)}" for m in METHODS
            ),
            far_guess_iterations=", ".join(f"{m} {span('(b)', m)}" for m in METHODS),
            span_c_fb=span("(c)", "fb"),
            span_c_min=span("(c)", "min"),
            span_c_blend=span("(c)", "blend"),
            cell_d_plain_newton_fb=cell("(d) plain Newton", "fb"),
            cell_d_line_search_bt_fb=cell("(d) line search bt", "fb"),
            cell_d_plain_newton_min=cell("(d) plain Newton", "min"),
            cell_d_line_search_bt_min=cell("(d) line search bt", "min"),
            line_search_verdict=_line_search_verdict(its),
            case_e_iterations=", ".join(f"{m} {span('(e)', m)}" for m in METHODS),
            case_f_iterations=", ".join(f"{m} {span('(f)', m)}" for m in METHODS),
            span_g_fb=span("(g)", "fb"),
            span_g_min=span("(g)", "min"),
            span_g_blend=span("(g)", "blend"),
            span_g_vinewtonrsls=span("(g)", "vinewtonrsls"),
            span_g_vinewtonssls=span("(g)", "vinewtonssls"),
            friction_rows=_friction_rows(its, cases),
        ),
        *_issue11_rows(its, cell, span),
    ]
    slow = [r for r in runs if r["converged"] and r["newton_iterations"] > 50]
    if slow:
        out += [
            prose(
                "stability",
                "within_petsc_s_default",
                join=", ".join(
                    f"{r['method']} on {r['case']} ({r['newton_iterations']})" for r in slow
                ),
            )
        ]
    if fails:
        out += [
            "",
            "Every failure in the map:",
            "",
            failure_table(fails, _explain),
        ]
    return "\n".join(out) + "\n"


#: why a 1024² run of case (k) fails: (method or "*", sequence or "*", smallest κ, largest κ,
# outcome) -> why
SCALE_EXPLAIN = {tuple(e[:5]): e[5] for e in DATA["explain_scale"]}


def _explain_scale(r: dict) -> str:
    for (m, seq, lo, hi, o), text in SCALE_EXPLAIN.items():
        if (
            m in (r["method"], "*")
            and seq in (str(r["sequence"]), "*")
            and lo <= float(r["kappa"]) <= hi
            and o == r["outcome"]
        ):
            return text
    return prose("_explain_scale", "not_yet_explained_new")


def stability_scale() -> str:
    """Case (k) of §3 at 1024² (configs/studies/stability_scale.yaml)."""
    runs, _, out = _open(
        prose("stability_scale", "at_scale_cold_starts"), "stability_scale", "stability"
    )
    if not runs:
        return "\n".join(out)
    import itertools
    import json

    axes = json.loads((RES / "stability_scale" / "study.json").read_text())["axes"]
    stab, _ = study("stability")
    methods = axes["method"]
    keys = [(str(seq), float(k)) for seq, k in itertools.product(axes["sequence"], axes["kappa"])]
    by = {(str(r["sequence"]), float(r["kappa"]), r["method"]): r for r in runs}
    missing = [
        f"sequence {seq}, κ = {g(k)}, {m}"
        for seq, k in keys
        for m in methods
        if (seq, k, m) not in by
    ]

    def cell(r: dict | None) -> str:
        if r is None:
            return "not run"
        what = its_text(r) if r["outcome"] != "error" else "error"
        return what + ("" if r["converged"] else f" ({r['outcome']})") + f", {g(r['seconds'])} s"

    out += [
        prose(
            "stability_scale",
            "configs_studies_stability_scale",
            runs_0_dofs=runs[0]["dofs"],
            join=", ".join(
                f"{m} {solves(r)}"
                for m in METHODS[3:]
                for r in (stab or [])
                if r["case"] == "(g) level 7" and r["method"] == m
            ),
            table=table(
                ["sequence", "κ"] + methods,
                [[seq, g(k)] + [cell(by.get((seq, k, m))) for m in methods] for seq, k in keys],
            ),
        )
    ]
    if missing:
        out += [prose("stability_scale", "not_run_the_study", join_missing="; ".join(missing))]
    ok = [r for r in runs if r["converged"]]
    odd = [r for r in ok if str(r["sequence"]) == "auto" and solves(r) > 10]

    def spread(seq: str, m: str) -> str:
        vals = [solves(r) for r in ok if str(r["sequence"]) == seq and r["method"] == m]
        return (
            "–"
            if not vals
            else f"{min(vals)}–{max(vals)}"
            if min(vals) != max(vals)
            else str(vals[0])
        )

    ratios = [
        by["off", k, m]["seconds"] / by["auto", k, m]["seconds"]
        for _, k in keys[: len(axes["kappa"])]
        for m in methods
        if ("off", k, m) in by
        and ("auto", k, m) in by
        and by["auto", k, m]["converged"]
        and by["off", k, m]["converged"]
    ]
    out += [
        prose(
            "stability_scale",
            "runs_converge_linear_solves",
            len_ok=len(ok),
            len_runs=len(runs),
            join="; ".join(
                f"{m} {spread('auto', m)} sequenced, {spread('off', m)} cold" for m in methods
            ),
            cold_over_sequenced=prose(
                "stability_scale",
                "where_both_converge_the",
                min_ratios=f"{min(ratios):.1f}",
                max_ratios=f"{max(ratios):.1f}",
            )
            if ratios
            else "",
            the_exception_join="The exception: "
            + ", ".join(
                f"{r['method']} at κ = {g(r['kappa'])} ({its_text(r)}, converged)" for r in odd
            )
            + (
                prose("stability_scale", "at_e4_b_i")
                if all(r["kappa"] >= 1e4 for r in odd)
                else prose("stability_scale", "runs_whose_iteration_history")
            )
            if odd
            else "",
            min_ending=prose("stability_scale", "until_e4_where_its")
            if any(r["method"] == "min" and not r["converged"] for r in runs)
            else ".",
        )
    ]
    fails = [r for r in runs if not r["converged"]]
    if fails:
        out += [
            "",
            "Failures:",
            "",
            table(
                ["sequence", "κ", "method", "outcome", "iterations", "SNES reason", "why"],
                [
                    [
                        r["sequence"],
                        g(r["kappa"]),
                        r["method"],
                        r["outcome"],
                        r["newton_iterations"],
                        r["reason"],
                        _explain_scale(r),
                    ]
                    for r in fails
                ],
            ),
        ]
    return "\n".join(out) + "\n"


def iterations() -> str:
    runs, levels, out = _open(
        prose("iterations", "newton_iterations_against_the"), "iterations_levels", "iterations"
    )
    if not levels:
        return "\n".join(out)
    out += [prose("iterations", "problem_a_uniform_refinement")]
    n_levels = max(r["level"] for r in levels) + 1
    dofs = {r["level"]: r["dofs"] for r in levels}
    body = []
    for r in runs:
        mine = sorted((lv for lv in levels if lv["run"] == r["run"]), key=lambda lv: lv["level"])
        body.append(
            [
                r["method"],
                "nested" if r["nested"] else "cold",
                *[its_text(lv) for lv in mine],
                g(r["seconds"]),
            ]
        )
    out += [
        table(
            ["method", "start", *[f"L{k} ({dofs.get(k, '?')})" for k in range(n_levels)], "run s"],
            body,
        ),
        "",
    ]
    seconds = {(r["method"], r["nested"]): r["seconds"] for r in runs}
    faster = sum(
        seconds[m, True] < seconds[m, False]
        for m in METHODS
        if (m, True) in seconds and (m, False) in seconds
    )

    def flat(method: str, nested: bool) -> str:
        vals = sorted(
            {
                solves(lv)
                for r in runs
                if r["method"] == method and r["nested"] == nested
                for lv in levels
                if lv["run"] == r["run"] and lv["level"] > 0
            }
        )
        return "–" if not vals else str(vals[0]) if len(vals) == 1 else f"{vals[0]}–{vals[-1]}"

    out += [
        prose(
            "iterations",
            "linear_solves_per_level",
            join=", ".join(f"{m} {flat(m, True)}" for m in METHODS),
            join_2=", ".join(f"{m} {flat(m, False)}" for m in METHODS),
            join_3=", ".join(
                f"{m} {g(seconds.get((m, True)))} s nested vs {g(seconds.get((m, False)))} s cold"
                for m in METHODS
                if (m, True) in seconds
            ),
            faster=faster,
        )
    ]
    return "\n".join(out) + "\n"


def hertz_methods() -> str:
    """Every method on the final Hertz meshes, cold and nested (demos/bench/bench_hertz.py)."""
    out = [prose("hertz_methods", "hertz_the_methods_on")]
    data = rows(RES / "hertz" / "final_mesh_methods.csv")
    if not data:
        return "\n".join(out) + "\n" + missing(prose("hertz_methods", "demos_results_hertz_final"))
    out += [
        prose(
            "hertz_methods",
            "demos_bench_bench_hertz",
            table=table(
                ["scene", "method", "start", "linear solver", "DoFs", "Newton its", "seconds"],
                [
                    [
                        r["scene"],
                        r["method"],
                        r["start"],
                        r["linear_solver"],
                        r["dofs"],
                        its_text(
                            {"newton_iterations": r["newton"], "polish_solves": r.get("polish")}
                        ),
                        g(r["seconds"]),
                    ]
                    for r in data
                ],
            ),
        )
    ]
    return "\n".join(out) + "\n"


def peers() -> str:
    out = [prose("peers", "peer_problems")]
    runs, _ = study("peer_ex9")
    if runs:
        body = []
        for r in runs:
            radius = math.sqrt(r["active_measure"] / math.pi) if r["active_measure"] != "" else ""
            body.append(
                [
                    r["method"],
                    r["level"],
                    r["dofs"],
                    g(r["error"]),
                    g(radius, 5),
                    g(radius - EX9_RADIUS if radius != "" else "", 2),
                    its_text(r),
                    g(r["seconds"]),
                ]
            )
        out += [
            prose(
                "peers",
                "configs_peers_petsc_ex9",
                ex9_radius=EX9_RADIUS,
                table=table(
                    [
                        "method",
                        "level",
                        "DoFs",
                        "energy error",
                        "r_h",
                        "r_h − r",
                        "Newton its",
                        "seconds",
                    ],
                    body,
                ),
            )
        ]
    else:
        out += [missing("demos/results/peer_ex9")]
    out += [prose("peers", "deal_ii_step_stair")]
    runs, _ = study("peer_step41")
    if runs:
        out += [
            prose(
                "peers",
                "configs_peers_dealii_step41",
                step41_solves=STEP41_SOLVES,
                table=table(
                    ["method", "Newton its (+ polishing)", "active nodes", "seconds"],
                    [
                        [
                            r["method"],
                            its_text(r),
                            round(r["active_measure"] / (2 / 128) ** 2)
                            if r["active_measure"] != ""
                            else "–",
                            g(r["seconds"]),
                        ]
                        for r in runs
                    ],
                ),
            )
        ]
    else:
        out += [missing("demos/results/peer_step41")]
    out += _step41_cold()
    return "\n".join(out) + "\n"


def _step41_cold() -> list[str]:
    """The step-41 problem from a cold start at 256² … 1024², by forcing rule
    (demos/bench/bench_cold.py, demos/results/cold/*.csv)."""
    out = ["", prose("_step41_cold", "heading"), ""]
    data = [r for path in sorted((RES / "cold").glob("step41*.csv")) for r in rows(path) or []]
    # deal.II's runs that finished, by DoFs
    peers = {
        r["dofs"]: r
        for path in sorted((RES / "cold").glob("dealii_step41*.csv"))
        for r in rows(path) or []
        if r["returncode"] == 0
    }
    # alternated pairs, deal.II's run then ours in one process (bench_cold.py --pair): where
    # there are some, deal.II's median CPU of them is the column's reference
    pairs = [
        r for path in sorted((RES / "cold").glob("pair_step41_*.csv")) for r in rows(path) or []
    ]
    pairs.sort(key=lambda r: (r["cells"], r["pair"]))
    for dofs in dict.fromkeys(r["dofs"] for r in pairs):
        mine = [r for r in pairs if r["dofs"] == dofs and r["dealii_returncode"] == 0]
        if mine:
            peers[dofs] = {
                "dofs": dofs,
                "cells": mine[0]["cells"],
                "cpu_s": statistics.median(r["dealii_cpu_s"] for r in mine),
                "newton_iterations": mine[0]["dealii_newton"],
                "cg_iterations": mine[0]["dealii_cg"],
            }
    if not data:
        return out + [missing("demos/results/cold (demos/bench/bench_cold.py)")]
    data.sort(key=lambda r: (r["cells"], r["variant"] != "new", r["variant"]))
    body = [
        [
            f"{r['cells']}²",
            r["dofs"],
            f"{r['variant']} ({r['forcing']}{', zero start' if r['variant'] == 'zero' else ''})",
            r["newton"],
            f"{r['krylov']} ({g(r['krylov_per_step'])})",
            r["gamg_setups"],
            g(r["cpu_s"]),
            g(r["ratio_cpu_vs_one_solve"]),
            g(r["cpu_s"] / peers[r["dofs"]]["cpu_s"]) if r["dofs"] in peers else "–",
            r["converged"],
        ]
        for r in data
    ]
    runs = "; ".join(
        f"{p['cells']}²: {g(p['cpu_s'])} s, {p['newton_iterations']} Newton and "
        f"{p['cg_iterations']} CG iterations"
        for p in sorted(peers.values(), key=lambda p: p["dofs"])
    )
    peer_text = prose("_step41_cold", "peer", peer_runs=runs).strip() if peers else ""
    header = ["cells", "DoFs", "rule", "Newton", "Krylov (per step)", "GAMG set-ups", "CPU s"]
    header += ["× one CG+GAMG", "× deal.II", "converged"]
    out += [prose("_step41_cold", "intro", peer_text=peer_text), "", table(header, body), ""]
    if pairs:
        out += [
            prose("_step41_cold", "pairs"),
            "",
            table(
                ["cells", "pair", "ours: Newton, Krylov, CPU s", "deal.II: Newton, CG, CPU s"]
                + ["ours / deal.II CPU"],
                [
                    [
                        f"{r['cells']}²",
                        r["pair"],
                        f"{r['newton']}, {r['krylov']}, {g(r['cpu_s'])}",
                        f"{r['dealii_newton']}, {r['dealii_cg']}, {g(r['dealii_cpu_s'])}",
                        g(r["ratio_cpu_vs_dealii"]),
                    ]
                    for r in pairs
                ],
            ),
            "",
        ]
    return out + [prose("_step41_cold", "verdict")]


def friction() -> str:
    """Section 7: the friction benchmark (demos/bench/bench_friction.py)."""
    out = [prose("friction", "friction_tresca_and_coulomb")]
    folder = RES / "friction"
    acc = rows(folder / "acceptance.csv")
    if not acc:
        return "\n".join(out) + "\n" + missing(prose("friction", "friction_acceptance_csv_demos"))
    out += [
        prose(
            "friction",
            "demos_bench_bench_friction",
            table=table(
                ["item", "value", "target", "met"],
                [
                    [r["item"], g(r["value"], 3), r["target"], "yes" if r["met"] else "**no**"]
                    for r in acc
                ],
            ),
        )
    ]
    cvf = rows(folder / "coulomb_vs_fixed_point.csv") or []
    if cvf:
        out += [
            prose(
                "friction",
                "coulomb_by_full_semismooth",
                table=table(
                    [
                        "case",
                        "DoFs",
                        "stick / slip nodes",
                        "Newton: its, s",
                        "fixed point: iterations, Newton its, s",
                        "max |Δu| / max |u|",
                    ],
                    [
                        [
                            r["case"],
                            r["dofs"],
                            f"{r['stick_nodes']} / {r['slip_nodes']}",
                            f"{r['newton_iterations']}, {g(r['newton_seconds'])}",
                            f"{r['fixed_point_iterations']}, {r['fixed_point_newton_iterations']}, "
                            f"{g(r['fixed_point_seconds'])}",
                            g(r["u_difference"], 2),
                        ]
                        for r in cvf
                    ],
                ),
            )
        ]
    forms = rows(folder / "forms.csv") or []
    if forms:
        keys = list(dict.fromkeys((r["case"], r["start"]) for r in forms))
        body = []
        for case, start in keys:
            cells = []
            for form in ("hsw", "projection"):
                for m in ("fb", "min", "blend"):
                    r = next(
                        x
                        for x in forms
                        if (x["case"], x["start"], x["form"], x["method"]) == (case, start, form, m)
                    )
                    cells.append(str(r["newton_iterations"]) if r["converged"] else "**fail**")
            body.append([case, start] + cells)
        ok = {
            f: sum(1 for r in forms if r["form"] == f and r["converged"])
            for f in ("hsw", "projection")
        }
        n = {f: sum(1 for r in forms if r["form"] == f) for f in ("hsw", "projection")}
        out += [
            prose(
                "friction",
                "the_tangential_form_the",
                table=table(
                    [
                        "scene",
                        "start",
                        "hsw fb",
                        "hsw min",
                        "hsw blend",
                        "projection fb",
                        "projection min",
                        "projection blend",
                    ],
                    body,
                ),
                ok_hsw=ok["hsw"],
                n_hsw=n["hsw"],
                ok_projection=ok["projection"],
                n_projection=n["projection"],
                projection_cycle=prose("friction_shared", "projection_cycle"),
            )
        ]
    out += _friction_line_search(folder)
    steps = rows(folder / "steps.csv") or []
    if steps:
        scenes = list(dict.fromkeys(r["scene"] for r in steps))
        ns = sorted({r["steps"] for r in steps})
        body = [
            [sc]
            + [
                next(
                    (
                        f"{r['max_step_iterations']} / {r['total_iterations']}"
                        + ("" if r["converged"] else " fail")
                        for r in steps
                        if r["scene"] == sc and r["steps"] == n
                    ),
                    "–",
                )
                for n in ns
            ]
            for sc in scenes
        ]
        out += [
            prose(
                "friction",
                "newton_iterations_per_load",
                table=table(["scene"] + [f"{n} step{'s' if n > 1 else ''}" for n in ns], body),
                cylinder_ratios=", ".join(
                    f"{g(r['friction_ratio'], 4)}"
                    for r in steps
                    if r["scene"] == "cylinder_2d" and r["steps"] in (ns[0], ns[-1])
                ),
            )
        ]
    mms = rows(folder / "manufactured.csv") or []
    if mms:
        out += [
            prose(
                "friction",
                "the_manufactured_tresca_solution",
                table=table(
                    ["refinement", "level", "DoFs", "error", "η", "η / error", "Newton its"],
                    [
                        [
                            r["strategy"],
                            r["level"],
                            r["dofs"],
                            g(r["error"]),
                            g(r["eta"]),
                            g(r["effectivity"], 3),
                            r["newton_iterations"],
                        ]
                        for r in mms
                    ],
                ),
            )
        ]
    cost = rows(folder / "cost.csv") or []
    if cost:
        out += [
            prose(
                "friction",
                "cost_of_the_block",
                table=table(
                    [
                        "scene",
                        "law",
                        "DoFs",
                        "Newton its",
                        "Φ and H, ms/step",
                        "linear solve, ms/step",
                    ],
                    [
                        [
                            r["scene"],
                            r["law"],
                            r["dofs"],
                            r["newton_iterations"],
                            r["callbacks_ms_per_step"],
                            r["linear_solve_ms_per_step"],
                        ]
                        for r in cost
                    ],
                ),
            )
        ]
    out += [prose("friction", "traction_pictures_block_results")]
    return "\n".join(out) + "\n"


def p2_table(curved: list[dict]) -> str:
    """The table of P1, P2 on straight and P2 on curved cells (bench_two_bodies.py p2 /
    p2sphere): the nodal deviations from Hertz, the peak's, the force, a and the balance."""
    return table(
        [
            "h_contact",
            "degree",
            "cells",
            "DoFs",
            "nodal max error",
            "nodal rms error",
            "peak error",
            "force",
            "a error",
            "force balance",
        ],
        [
            [
                r["h_contact"],
                f"P{r['degree']}",
                r["cells"],
                r["dofs"],
                f"{100 * r['nodal_max_error']:.2f} %",
                f"{100 * r['nodal_rms_error']:.2f} %",
                pct(r["peak_error"]),
                g(r["force"], 6),
                pct(r["a_error"]),
                g(r["balance"], 2),
            ]
            for r in curved
        ],
    )


def two_bodies() -> str:
    """Section 8: two deformable bodies, mortar coupling (demos/bench/bench_two_bodies.py)."""
    out = [prose("two_bodies", "two_bodies_in_contact")]
    folder = RES / "two_bodies"
    patch = rows(folder / "patch.csv")
    if not patch:
        return "\n".join(out) + "\n" + missing(prose("two_bodies", "two_bodies_patch_csv"))
    out += [
        prose(
            "two_bodies",
            "demos_bench_bench_two",
            table=table(
                [
                    "dim",
                    "method",
                    "DoFs",
                    "Newton its",
                    "seconds",
                    "slave max |λ + p| / p",
                    "master max |λ + p| / p",
                ],
                [
                    [
                        r["dim"],
                        r["method"],
                        r["dofs"],
                        its_text({"newton_iterations": r["newton"], "polish_solves": r["polish"]}),
                        g(r["seconds"]),
                        g(r["slave_error"], 2),
                        g(r["master_error"], 2),
                    ]
                    for r in patch
                ],
            ),
        )
    ]
    levels = rows(folder / "cylinders_levels.csv") or []
    if levels:
        out += [
            prose(
                "two_bodies",
                "two_cylinders_hertz_configs",
                table=table(
                    [
                        "level",
                        "DoFs",
                        "Newton its",
                        "solve s",
                        "η",
                        "a error",
                        "p0 error",
                        "a / R_c",
                        "force balance",
                    ],
                    [
                        [
                            r["level"],
                            r["dofs"],
                            its_text(
                                {"newton_iterations": r["newton"], "polish_solves": r["polish"]}
                            ),
                            g(r["seconds_solve"]),
                            g(r["eta"]),
                            pct(r["a_error"]),
                            pct(r["p0_error"]),
                            g(r["a_over_Rc"]),
                            g(r["balance"], 2),
                        ]
                        for r in levels
                    ],
                ),
            )
        ]
    methods = rows(folder / "cylinders_methods.csv") or []
    if methods:
        out += [
            prose(
                "two_bodies",
                "every_method_on_the",
                table=table(
                    ["method", "start", "Newton its", "seconds", "max |u − u_rsls|"],
                    [
                        [
                            r["method"],
                            r["start"],
                            its_text(
                                {"newton_iterations": r["newton"], "polish_solves": r["polish"]}
                            ),
                            g(r["seconds"]),
                            g(r["max_diff_to_vinewtonrsls"], 2),
                        ]
                        for r in methods
                    ],
                ),
            )
        ]
    swaps = (rows(folder / "slave_master.csv") or []) + (rows(folder / "slave_master_3d.csv") or [])
    if swaps:
        out += [
            prose(
                "two_bodies",
                "which_surface_is_the",
                table=table(
                    [
                        "case",
                        "slave",
                        "DoFs",
                        "force",
                        "a",
                        "p0",
                        "a error",
                        "p0 error",
                        "profiles differ by",
                    ],
                    [
                        [
                            r["case"],
                            r["slave"],
                            r["dofs"],
                            g(r["force"], 6),
                            g(r["a"], 5),
                            g(r["p0"], 5),
                            pct(r["a_error"]),
                            pct(r["p0_error"]),
                            g(r["profile_L2_difference"], 2),
                        ]
                        for r in swaps
                    ],
                ),
            )
        ]
    out += [
        speed_accuracy(
            "speed_accuracy_two_bodies",
            prose("two_bodies", "two_cylinders_speed_against"),
            "hertz_error",
            "Hertz error",
            prose("two_bodies", "the_study_configs_studies"),
        )
    ]
    sphere = rows(folder / "sphere.csv") or []
    if sphere:
        out += [
            prose(
                "two_bodies",
                "a_sphere_on_a",
                table=table(
                    [
                        "h_contact",
                        "DoFs",
                        "ranks",
                        "Newton its",
                        "seconds",
                        "radius error",
                        "p0 error",
                        "rms of p − p_Hertz (r < 0.8 a)",
                        "a / R",
                    ],
                    [
                        [
                            r["h_contact"],
                            r["dofs"],
                            r["ranks"],
                            its_text(
                                {"newton_iterations": r["newton"], "polish_solves": r["polish"]}
                            ),
                            g(r["seconds"]),
                            pct(r["a_error"]),
                            pct(r["p0_error"]),
                            f"{100 * r['pressure_rms']:.2f} %",
                            g(r["a_over_R"]),
                        ]
                        for r in sphere
                    ],
                ),
            )
        ]
    degrees = rows(folder / "sphere_degrees.csv") or []
    if degrees:
        out += [
            prose(
                "two_bodies",
                "the_sphere_with_p2",
                force=g(degrees[0]["force_reference"], 5),
                energy=g(degrees[0]["energy_reference"], 5),
                table=table(
                    [
                        "run",
                        "degree",
                        "level",
                        "DoFs",
                        "force",
                        "force error",
                        "a error",
                        "p0 error",
                        "energy error",
                        "η",
                        "η / error",
                    ],
                    [
                        [
                            r["run"] if r["run"] == "dorfler" else f"gmsh {r['h_contact']}",
                            f"P{r['degree']}",
                            r["level"],
                            r["dofs"],
                            g(r["force"], 5),
                            pct(r["force_error"]),
                            pct(r["a_error"]),
                            pct(r["p0_error"]),
                            g(r["energy_error"]),
                            g(r["eta"]) if r["run"] == "dorfler" else "–",
                            g(r["eta_over_error"]) if r["run"] == "dorfler" else "–",
                        ]
                        for r in degrees
                    ],
                ),
            )
        ]
    cylinders_p2 = rows(folder / "cylinders_p2.csv") or []
    if cylinders_p2:
        out += [prose("two_bodies", "p2_on_straight_and", table=p2_table(cylinders_p2))]
    sphere_p2 = rows(folder / "sphere_p2.csv") or []
    if sphere_p2:
        out += [prose("two_bodies", "p2_sphere", table=p2_table(sphere_p2))]
    p1_start = (rows(folder / "p1_start.csv") or []) + (
        rows(folder / "p1_start_floating.csv") or []
    )
    if p1_start:
        out += [
            prose(
                "two_bodies",
                "p2_from_the_p1",
                table=table(
                    [
                        "scene",
                        "h_contact",
                        "P2 DoFs",
                        "levels (DoFs:steps)",
                        "cold n+p",
                        "P1 start n+p",
                        "cold s",
                        "P1 start s",
                        "cold / P1 start",
                        "max difference",
                    ],
                    [
                        [
                            r["scene"],
                            r["h_contact"],
                            r["dofs"],
                            r["levels"],
                            r["cold_newton"],
                            r["p1_start_newton"],
                            g(r["cold_seconds"]),
                            g(r["p1_start_seconds"]),
                            f"{float(r['ratio']):.2f}",
                            f"{float(r['difference']):.1e}",
                        ]
                        for r in p1_start
                    ],
                ),
            )
        ]
    cm = rows(folder / "cattaneo.csv") or []
    if cm:
        out += [
            prose(
                "two_bodies",
                "cattaneo_mindlin_partial_slip",
                table=table(
                    [
                        "h_contact",
                        "DoFs",
                        "Q/(F P)",
                        "Newton its",
                        "c/a",
                        "theory",
                        "c/a error",
                        "q L² error",
                    ],
                    [
                        [
                            r["h_contact"],
                            r["dofs"],
                            g(r["Q_over_FP"], 4),
                            r["newton"],
                            g(r["c_over_a"], 4),
                            g(r["c_over_a_theory"], 4),
                            pct(r["c_error"]),
                            g(r["q_error"], 3),
                        ]
                        for r in cm
                        if r["Q_over_FP"] > 0.01
                    ],
                ),
            )
        ]
    return "\n".join(out) + "\n"


def friction_paths(path_rows: list[dict]) -> list[str]:
    """§9's rows of frictional load paths (``bench_cost.py path``): every step against one
    CG + GAMG solve of K, CPU time (and wall)."""
    body = [
        [
            r["case"],
            r["dofs"],
            r["ranks"],
            r["variant"],
            r["step"],
            g(r["t"]),
            r["linear"],
            r["levels"],
            r["newton"],
            r["krylov"],
            r["predictor"] or "",
            g(r["ref_cpu_s"]),
            g(r["step_cpu_s"]),
            g(r["ratio_cpu"]),
            g(r["ratio_wall"]),
            g(r["max_diff_vs_first"], 2),
        ]
        for r in path_rows
    ]
    return [
        prose("friction_paths", "frictional_load_paths_issue"),
        "",
        table(
            [
                "case",
                "DoFs",
                "ranks",
                "variant",
                "step",
                "t",
                "linear",
                "levels",
                "Newton",
                "Krylov",
                "predictor",
                "one CG+GAMG s (CPU)",
                "step s (CPU)",
                "ratio (CPU)",
                "ratio (wall)",
                "max |Δu|",
            ],
            body,
        ),
        "",
    ]


def _bar_levels() -> list[str]:
    """The 1M square's bar by the number of coarse levels (demos/results/cold/
    bar_levels_1024.csv, ``bench_cost.py scene --sequence auto,3,2``)."""
    bar = rows(RES / "cold" / "bar_levels_1024.csv") or []
    if not bar:
        return []
    settings = list(dict.fromkeys(r["sequence"] for r in bar))
    methods = list(dict.fromkeys(r["method"] for r in bar))
    by = {(r["method"], r["sequence"]): r for r in bar}
    levels = ", ".join(
        f"{m} " + " / ".join(g(by[m, s]["ratio_cpu"]) for s in settings if (m, s) in by)
        for m in methods
    )
    levels += " for " + " / ".join(
        f"`{s}` (coarsest {str(by[methods[0], s]['coarse_dofs']).split()[0]} DoFs)"
        for s in settings
    )
    weighted = " → ".join(g(by[methods[0], s]["weighted_solves"]) for s in settings)
    return [
        prose("cost", "the_1m_square_against", levels=levels, weighted=f"{methods[0]} {weighted}"),
        "",
    ]


def cost() -> str:
    """Section 9: a contact solve in units of one linear solve (demos/bench/bench_cost.py)."""
    out = ["## 9. Cost against one linear solve", ""]
    folder = RES / "cost"
    runs = (
        {path.stem: rows(path) or [] for path in sorted(folder.glob("*.csv"))}
        if folder.is_dir()
        else {}
    )
    if not any(runs.values()):
        return "\n".join(out) + "\n" + missing("cost/*.csv (demos/bench/bench_cost.py)")
    out += [prose("cost", "demos_bench_bench_cost")]
    every_row = [r for rs in runs.values() for r in rs]
    all_rows = [r for r in every_row if not r.get("step")]  # single solves
    path_rows = [r for r in every_row if r.get("step")]  # frictional load paths, per step
    body = [
        [
            r["case"],
            r["dofs"],
            r["ranks"],
            r["method"],
            r["sequence"],
            r["levels"],
            its_text({"newton_iterations": r["newton"], "polish_solves": r["polish"]}),
            r["coarse_solves"],
            g(r["weighted_solves"]),
            r["linear"],
            g(r["ref_wall_s"]),
            g(r["solve_wall_s"]),
            g(r["ratio_wall"]),
            g(r["max_diff_vs_before"], 2),
        ]
        for r in all_rows
    ]
    out += [
        table(
            [
                "case",
                "DoFs",
                "ranks",
                "method",
                "sequence",
                "levels",
                "fine",
                "coarse solves",
                "weighted",
                "linear",
                "one CG+GAMG s",
                "contact solve s",
                "ratio",
                "max |u − u_before|",
            ],
            body,
        ),
        "",
    ]
    square = [r for r in all_rows if r["case"] == "square" and r["sequence"] != "off"]
    if square:
        fine = sorted(
            {
                its_text({"newton_iterations": r["newton"], "polish_solves": r["polish"]})
                for r in square
            }
        )
        weighted = [r["weighted_solves"] for r in square]
        out += [
            prose(
                "cost",
                "without_sequencing_the_cold",
                or_join_fine=" or ".join(fine),
                g_min_weighted=g(min(weighted)),
                g_max_weighted=g(max(weighted)),
            )
        ]
    out += _bar_levels()
    if path_rows:
        out += friction_paths(path_rows)
    scale = rows(RES / "scale.csv") or []
    if scale:
        out += [
            prose(
                "cost",
                "adaptive_runs_end_to",
                table=table(
                    [
                        "scene",
                        "ranks",
                        "rebalance",
                        "levels",
                        "final DoFs",
                        "wall s",
                        "peak GiB",
                        "solve",
                        "assembly",
                        "estimate",
                        "error",
                        "refine",
                        "output",
                        "finest: assembly + estimate / solve",
                        "level before: + refine / solve",
                        prose("cost", "refine_into_the_finest"),
                        prose("cost", "of_which_dolfinx_mesh"),
                        "busiest rank's DoFs / mean",
                    ],
                    [
                        [
                            r["scene"],
                            r["ranks"],
                            r.get("rebalance", "false"),
                            r["levels"],
                            r["dofs"],
                            g(r["wall_s"]),
                            g(r["peak_rss_gib"]),
                            g(r["total_solve_s"]),
                            g(r["total_assembly_s"]),
                            g(r["total_estimate_s"]),
                            g(r["total_error_s"]),
                            g(r["total_refine_s"]),
                            g(r["total_output_s"]),
                            f"{g(r['last_assembly_estimate_s'])} / {g(r['last_solve_s'])}",
                            f"{g(r['prev_assembly_estimate_refine_s'])} / {g(r['prev_solve_s'])}",
                            g(r.get("finest_overhead_ratio", "")),
                            g(r.get("finest_refine_mesh_ratio", "")),
                            g(r.get("rank_imbalance", "")),
                        ]
                        for r in scale
                    ],
                ),
            )
        ]
        rebalanced = lambda r: r.get("rebalance", "false") == "true" or int(r["ranks"]) == 1  # noqa: E731
        a = {
            int(r["ranks"]): r
            for r in scale
            if r["scene"].startswith("signorini_free_boundary") and rebalanced(r)
        }
        bw = {int(r["ranks"]): r for r in rows(RES / "bandwidth.csv") or []}
        kern = {r["path"]: r for r in rows(RES / "kernels_refine_np2.csv") or []}
        if 1 in a and 2 in a:
            ceiling = ""
            if 1 in bw and 2 in bw:
                ratio = lambda k: float(bw[1][k]) / float(bw[2][k])  # noqa: E731
                ceiling = prose(
                    "cost",
                    "on_this_machine_a",
                    ratio_matvec_100_s=f"{ratio('matvec_100_s'):.2f}",
                    ratio_array_scale_20_s=f"{ratio('array_scale_20_s'):.2f}",
                    bw_1_get_repeat_1=bw[1].get("repeat", 1),
                )
            speedups = [float(r["speedup"]) for r in rows(RES / "scale_pairs.csv") or []]
            if speedups:
                speedup = prose(
                    "cost",
                    "faster_than_serial_the",
                    statistics_median_speedups=f"{statistics.median(speedups):.2f}",
                    len_speedups=len(speedups),
                    min_speedups=f"{min(speedups):.2f}",
                    max_speedups=f"{max(speedups):.2f}",
                )
            else:
                speedup = f"{float(a[1]['wall_s']) / float(a[2]['wall_s']):.2f}× faster than serial"
            out += [prose("cost", "problem_a_on_ranks", speedup=speedup, ceiling=ceiling)]
            pairs = [
                (r, k)
                for r in scale
                for k in scale
                if int(r["ranks"]) > 1
                and r["scene"] == k["scene"]
                and r["ranks"] == k["ranks"]
                and r.get("rebalance") == "true"
                and k.get("rebalance") == "false"
            ]
            if pairs:
                para = prose(
                    "cost",
                    "dolfinx_mesh_refine_creates",
                    join=", ".join(
                        f"{float(k['rank_imbalance']):.2f}× its share in {k['scene']}"
                        for _, k in pairs
                    ),
                    join_2=", ".join(f"{2 / float(k['rank_imbalance']):.2f}×" for _, k in pairs),
                    join_3="; ".join(
                        prose(
                            "cost",
                            "busiest_rank",
                            float_r_rank_imbalance=f"{float(r['rank_imbalance']):.2f}",
                            g_r_wall_s=g(r["wall_s"]),
                            g_k_wall_s=g(k["wall_s"]),
                            r_scene=r["scene"],
                        )
                        for r, k in pairs
                    ),
                )
                differ = [r["scene"] for r, k in pairs if r["dofs"] != k["dofs"]]
                if differ:
                    para += prose("cost", "the_final_meshes_differ", join_differ=", ".join(differ))
                if {"identity", "graph"} <= set(kern):
                    i, gr = kern["identity"], kern["graph"]
                    para += prose(
                        "cost",
                        "the_redistribution_costs_no",
                        i_size=i["size"],
                        g_i_seconds=g(i["seconds"]),
                        i_check=i["check"],
                        g_gr_seconds=g(gr["seconds"]),
                        gr_check=gr["check"],
                    )
                out += [para, ""]
        quad = rows(RES / "error_quadrature.csv") or []
        if quad:
            last = quad[-1]
            fine = [r for r in quad if r["dofs"] >= 10_000]
            out += [
                prose(
                    "cost",
                    "the_energy_error_per",
                    quad_0_change_q4=f"{quad[0]['change_q4']:.0e}",
                    quad_0_change_q8=f"{quad[0]['change_q8']:.0e}",
                    max_change_q4=f"{max(r['change_q4'] for r in fine):.0e}",
                    last_seconds_q4=f"{last['seconds_q4']:.2f}",
                    last_seconds_q8=f"{last['seconds_q8']:.2f}",
                    last_dofs=last["dofs"],
                )
            ]
        ghosts = (
            prose(
                "cost",
                "against_without_ghosts_the",
                g_kern_identity_seconds=g(kern["identity"]["seconds"]),
                g_kern_no_ghosts_seconds=g(kern["no_ghosts"]["seconds"]),
            )
            if {"identity", "no_ghosts"} <= set(kern)
            else ""
        )
        floor = "; ".join(
            f"{g(r['finest_refine_mesh_s'])} s = {g(r['finest_refine_mesh_ratio'])}× the "
            f"finest solve "
            f"in {r['scene']} on {r['ranks']} rank(s)"
            for r in scale
            if r.get("finest_refine_mesh_s") not in (None, "") and rebalanced(r)
        )
        floor = (prose("cost", "dolfinx_mesh_refine_alone", floor=floor)) if floor else ""
        out += [
            prose(
                "cost",
                "the_d_solves_cost",
                ghosts=ghosts,
                floor=floor,
                refine_floor_res=refine_floor(RES),
            )
        ]
    return "\n".join(out) + "\n"


def refine_floor(res: Path) -> str:
    """The sentence on the 2D floor (bench_kernels.py --only floor, serial and 2 ranks), or ''."""
    runs = [
        {r["path"]: r for r in rs}
        for rs in (rows(res / "kernels_floor.csv"), rows(res / "kernels_floor_np2.csv"))
        if rs
    ]
    if not runs:
        return ""
    ratio = lambda run, *paths: sum(float(run[p]["check"]) for p in paths)  # noqa: E731
    each = "; ".join(
        prose(
            "refine_floor",
            "rank_dolfinx_mesh_refine",
            run_solve_ranks=run["solve"]["ranks"],
            g_run_refine_seconds=g(run["refine"]["seconds"]),
            ratio_run_refine=f"{ratio(run, 'refine'):.2f}",
            g_run_solve_seconds=g(run["solve"]["seconds"]),
            g_run_create_mesh_seconds=g(run["create_mesh"]["seconds"]),
            ratio_run_create_mesh=f"{ratio(run, 'create_mesh'):.2f}",
            ratio_run_assembly=f"{ratio(run, 'assembly'):.2f}",
        )
        for run in runs
    )
    low = min(ratio(run, "refine", "assembly") for run in runs)
    outside = min(ratio(run, "create_mesh", "assembly") for run in runs)
    slower = [
        float(run["create_mesh"]["seconds"]) / float(run["refine"]["seconds"]) for run in runs
    ]
    verdict = (
        prose("refine_floor", "nor_would_a_refinement")
        if outside > 0.5
        else prose("refine_floor", "a_refinement_written_outside")
    )
    return prose(
        "refine_floor",
        "it_must_hand_its",
        verdict=verdict,
        min_slower=f"{min(slower):.1f}",
        max_slower=f"{max(slower):.1f}",
        runs_0_solve_size=runs[0]["solve"]["size"],
        each=each,
        low=f"{low:.2f}",
        outside=f"{outside:.2f}",
    )


#: (module, the choice it made, what was measured, the command that repeats it); quoted from
#: the docstrings they were measured for, not re-measured by `make bench`
DESIGN_MEASUREMENTS = [tuple(m) for m in DATA["design_measurements"]]


HYPER = "hyperelastic"
#: the strip's Euler load (configs/hyperelastic_strip.yaml): π² E/(1 − ν²) h³/12 / L²
STRIP_EULER = math.pi**2 / (1 - 0.3**2) * 0.05**3 / 12


def hyperelastic() -> str:
    """Section 11: finite deformation (issue 31) — the energy line search, the buckling strip,
    the refinement study of the neo-Hookean cylinder, the stability map."""
    out = [prose("hyperelastic", "finite_deformation_hyperelastic_bodies")]
    out += [
        _hyper_line_search(),
        _hyper_strip(),
        _hyper_refinement(),
        _hyper_stability(),
        _hyper_predictor(),
        _hyper_adaptive(),
        _hyper_ball(),
        _hyper_ironing(),
        _hyper_adaptive_curved(),
        _hyper_drag(),
        _hyper_kink(),
    ]
    return "\n".join(out)


def _hyper_open(title: str, name: str) -> tuple[list[str], list[dict] | None]:
    """A §11 subsection's heading lines and the rows of its CSV (None, and the "not
    available" line, if it is missing)."""
    data = rows(RES / HYPER / name)
    return [title, "", *([] if data else [missing(f"demos/results/{HYPER}/{name}")])], data


def _pairs(data: list[dict], key: str, a: str, b: str) -> list[tuple[str, str, dict, dict]]:
    """(case, method, row with key = a, row with key = b) for each case and method that has
    both, in the CSV's order."""
    out = []
    for case, method in dict.fromkeys((r["case"], r["method"]) for r in data):
        pair = {r[key]: r for r in data if r["case"] == case and r["method"] == method}
        if a in pair and b in pair:
            out.append((case, method, pair[a], pair[b]))
    return out


def _hyper_line_search() -> str:
    out, data = _hyper_open(
        prose("_hyper_line_search", "nonconvex_laws_and_buckling"), "line_search.csv"
    )
    if not data:
        return "\n".join(out)
    out += [prose("_hyper_line_search", "python_demos_bench_bench")]

    def what(r: dict) -> str:
        t = "" if r["converged"] else f", t = {g(r['reached_t'])}"
        return (
            f"{r['outcome']}, {r['newton_iterations']} its, det F {g(r['min_det_F'], 2)}, "
            f"{r['negative_eigenvalues']} neg.{t}"
        )

    body = []
    for case, method, b, e in _pairs(data, "line_search", "basic", "energy"):
        body.append([case, method, what(b), what(e), g(e["curvature_steps"])])
        if case.startswith("NH cylinder"):
            break  # the timing pair: shown once, its CPU times below
    out.append(
        table(["case", "method", "plain Newton (basic)", "energy search", "curvature steps"], body)
    )
    cyl = [r for r in data if r["case"].startswith("NH cylinder")]
    if cyl:
        cpu = {
            ls: min(r["cpu_seconds"] for r in cyl if r["line_search"] == ls)
            for ls in ("basic", "energy")
        }
        out += [
            prose(
                "_hyper_line_search",
                "where_k_t_stays",
                cpu_energy=f"{cpu['energy']:.2f}",
                cpu_basic=f"{cpu['basic']:.2f}",
                cpu_energy_cpu_basic=f"{cpu['energy'] / cpu['basic']:.2f}",
            )
        ]
    path = {r["line_search"]: r for r in data if r["case"].startswith("SVK arch d=0.2, 10")}
    reached = (
        prose(
            "_hyper_line_search",
            "on_the_load_path",
            path_basic_outcome=path["basic"]["outcome"],
            g_path_basic_reached_t=g(path["basic"]["reached_t"]),
            g_path_energy_reached_t=g(path["energy"]["reached_t"]),
        )
        if {"basic", "energy"} <= set(path)
        else ""
    )
    out += [prose("_hyper_line_search", "what_the_table_says", reached=reached)]
    return "\n".join(out)


def _hyper_strip() -> str:
    out, data = _hyper_open(prose("_hyper_strip", "the_buckling_strip_against"), "strip.csv")
    if not data:
        return "\n".join(out)
    out += [
        prose(
            "_hyper_strip",
            "configs_hyperelastic_strip_yaml",
            table=table(
                ["mesh", "degree", "DoFs", "critical t in", "critical force / P_E in"],
                [
                    [
                        r["cells"],
                        r["degree"],
                        r["dofs"],
                        f"({r['t_definite']}, {r['t_indefinite']}]",
                        f"({r['force_definite_over_euler']:.4f}, "
                        f"{r['force_indefinite_over_euler']:.4f}]",
                    ]
                    for r in data
                ],
            ),
        )
    ]
    p2 = [r for r in data if r["degree"] == 2]
    shipped = next((r for r in data if r["cells"] == "80x4" and r["degree"] == 1), None)
    if p2 and shipped:
        fine = p2[-1]
        out += [
            prose(
                "_hyper_strip",
                "euler_s_estimate_agrees",
                fine_force_drop=f"{100 * (1 - fine['force_indefinite_over_euler']):.1f}",
                fine_cells=fine["cells"],
                fine_force_indefinite_over_euler=f"{fine['force_indefinite_over_euler']:.4f}",
                shipped_force_rise=f"{100 * (shipped['force_indefinite_over_euler'] - 1):.1f}",
                shipped_t_definite=shipped["t_definite"],
                shipped_t_indefinite=shipped["t_indefinite"],
            )
        ]
    runs = rows(RES / HYPER / "line_search.csv") or []
    strip = {r["line_search"]: r for r in runs if r["case"].startswith("SVK strip")}
    if {"basic", "energy"} <= set(strip):
        out += [
            prose(
                "_hyper_strip",
                "with_the_default_solver",
                energy_force_over_euler=f"{strip['energy']['contact_force'] / STRIP_EULER:.4f}",
                basic_force_over_euler=f"{strip['basic']['contact_force'] / STRIP_EULER:.4f}",
                strip_basic_negative_eigenvalues=strip["basic"]["negative_eigenvalues"],
            )
        ]
    out.append("")
    return "\n".join(out)


def _refinement_table(data: list[dict]) -> tuple[str, list[float]]:
    """The per-level table of a refinement CSV at the last indentation, and the observed
    rates of the largest change of the force over δ ≤ 0.4 R."""
    steps = max(r["step"] for r in data)
    levels = sorted({r["level"] for r in data})
    last = [next(r for r in data if r["level"] == lv and r["step"] == steps) for lv in levels]
    curve = [
        [r["contact_force"] for r in data if r["level"] == lv and r["indentation"] <= 0.4 + 1e-9]
        for lv in levels
    ]
    change = [max(abs(a - b) for a, b in zip(curve[i], curve[i - 1])) for i in range(1, len(curve))]
    rates = [math.log2(change[i - 1] / change[i]) for i in range(1, len(change))]
    body = []
    for i, r in enumerate(last):
        diff = abs(r["contact_force"] - last[i - 1]["contact_force"]) if i else None
        body.append(
            [
                r["level"],
                r["dofs"],
                f"{r['contact_force']:.7f}",
                g(diff),
                g(change[i - 1]) if i else "–",
                f"{rates[i - 2]:.2f}" if i >= 2 else "–",
                max(x["newton_iterations"] for x in data if x["level"] == r["level"]),
                f"{r['vi_u_difference']:.1e}",
                f"{r['vi_force_difference']:.1e}",
                f"{r['seconds_fb']} / {r['seconds_vinewtonrsls']}",
            ]
        )
    header = [
        "level",
        "DoFs",
        "F(0.5 R)",
        "change at 0.5 R",
        "largest change, δ ≤ 0.4 R",
        "its rate",
        "Newton its / step (max)",
        "vinewtonrsls: u",
        "force",
        "seconds fb / vinewtonrsls",
    ]
    return table(header, body), rates


def _hyper_refinement() -> str:
    out = [prose("_hyper_refinement", "large_indentation_the_neo")]
    clamped = rows(RES / HYPER / "refinement_clamped.csv")
    squeezed = rows(RES / HYPER / "refinement_symmetry.csv")
    if not clamped:
        return "\n".join(out + [missing(f"demos/results/{HYPER}/refinement_clamped.csv")])
    out += [prose("_hyper_refinement", "refinement_top_held_results")]
    text, rates = _refinement_table(clamped)
    out += [text, ""]
    out += [
        prose(
            "_hyper_refinement",
            "the_force_indentation_curve",
            rates=", ".join(f"{r:.2f}" for r in rates),
        )
    ]
    steps = max(r["step"] for r in clamped)
    apart = [
        r
        for r in clamped
        if r["step"] == steps and r["vi_u_difference"] > 1e-8 and "energy_fb" in r
    ]
    if apart:
        levels = ", ".join(str(r["level"]) for r in apart)
        pairs = "; ".join(
            prose(
                "_hyper_refinement",
                "level_against_vinewtonrsls_negative",
                r_level=r["level"],
                r_energy_fb=f"{r['energy_fb']:.8f}",
                r_energy_vinewtonrsls=f"{r['energy_vinewtonrsls']:.8f}",
                r_negative_eigenvalues=r["negative_eigenvalues"],
                r_negative_eigenvalues_vinewtonr=r["negative_eigenvalues_vinewtonrsls"],
            )
            for r in apart
        )
        out += [prose("_hyper_refinement", "at_r_the_held", levels=levels, pairs=pairs)]
    if squeezed:
        text, rates_s = _refinement_table(squeezed)
        out += [
            prose(
                "_hyper_refinement",
                "refinement_between_two_plates",
                text=text,
                rates_s=", ".join(f"{r:.2f}" for r in rates_s),
            )
        ]
    return "\n".join(out)


def _hyper_predictor() -> str:
    out, data = _hyper_open(prose("_hyper_predictor", "the_tangent_predictor_of"), "predictor.csv")
    if not data:
        return "\n".join(out)
    out += [prose("_hyper_predictor", "python_demos_bench_bench")]

    def what(r: dict) -> str:
        ok = "" if r["converged"] else " (failed)"
        return (
            f"{r['steps']} steps, {r['cuts']} cuts, {r['newton_iterations']} its, "
            f"{r['cpu_seconds']:.2f} s{ok}"
        )

    body = [
        [case, method, what(a), what(b)]
        for case, method, a, b in _pairs(data, "predictor", "none", "auto")
    ]
    out += [
        prose(
            "_hyper_predictor",
            "the_predictor_saves_what",
            table=table(["case", "method", "plain start (none)", "tangent predictor (auto)"], body),
        )
    ]
    return "\n".join(out)


#: the force tolerances of §11.6 (demos/bench/bench_hyperelastic.py adaptive)
ADAPTIVE_TOLERANCES = (5e-3, 1e-3, 5e-4)


def _hyper_adaptive() -> str:
    out, data = _hyper_open(prose("_hyper_adaptive", "adaptivity_at_finite_strain"), "adaptive.csv")
    if not data:
        return "\n".join(out)
    by = {k: [r for r in data if r["strategy"] == k] for k in ("uniform", "dorfler")}
    finest = min(data, key=lambda r: r["contact_force"])
    out += [
        prose(
            "_hyper_adaptive",
            "adaptive_against_uniform_results",
            finest_contact_force=f"{finest['contact_force']:.9f}",
            finest_strategy=finest["strategy"],
            finest_dofs=finest["dofs"],
            table=table(
                ["strategy", "level", "DoFs", "η", "F", "F / F_ref − 1", "Newton its"],
                [
                    [
                        r["strategy"],
                        r["level"],
                        r["dofs"],
                        f"{r['eta']:.4e}",
                        f"{r['contact_force']:.9f}",
                        f"{r['force_above_reference']:.2e}",
                        r["newton_iterations"],
                    ]
                    for r in data
                ],
            ),
        )
    ]
    for tol in ADAPTIVE_TOLERANCES:
        first = {
            k: min((r["dofs"] for r in v if r["force_above_reference"] <= tol), default=None)
            for k, v in by.items()
        }
        if first["uniform"] and first["dorfler"]:
            ratio = first["uniform"] / first["dorfler"]
            out.append(
                prose(
                    "_hyper_adaptive",
                    "within_ref_uniform_dofs",
                    tol=f"{tol:.2%}",
                    first_uniform=first["uniform"],
                    first_dorfler=first["dorfler"],
                    ratio=f"{ratio:.1f}",
                )
            )
    top = by["uniform"][-1]
    below = [r for r in by["dorfler"] if r["contact_force"] <= top["contact_force"]]
    if below:
        out.append(
            prose(
                "_hyper_adaptive",
                "reference_free_d_rfler",
                top_dofs=top["dofs"],
                below_0_dofs=below[0]["dofs"],
                top_dofs_below_0_dofs=f"{top['dofs'] / below[0]['dofs']:.1f}",
            )
        )
    out += [prose("_hyper_adaptive", "at_both_strategies_are")]
    return "\n".join(out)


def _hyper_ball() -> str:
    out = [prose("_hyper_ball", "a_neo_hookean_ball")]
    files = sorted((RES / HYPER).glob("ball_h*_np*.csv"))
    if not files:
        return "\n".join([*out, missing(f"demos/results/{HYPER}/ball_h*_np*.csv"), ""])
    out += [prose("_hyper_ball", "mpirun_n_python_demos")]
    body = []
    for path in files:
        data = rows(path) or []
        for r in data:
            body.append(
                [
                    r["ranks"],
                    r["h"],
                    r["dofs"],
                    r["step"],
                    f"{r['indentation']:.2f}",
                    r["newton_iterations"],
                    r["krylov_iterations"],
                    f"{r['contact_force']:.6g}",
                    r["seconds"],
                    r["path_seconds"],
                    r["peak_rss_mib"],
                ]
            )
    out += [
        table(
            [
                "ranks",
                "h",
                "DoFs",
                "step",
                "δ / R",
                "Newton its",
                "CG its",
                "force (octant)",
                "step s",
                "path s",
                "peak RSS MiB",
            ],
            body,
        ),
        "",
    ]
    runs = sorted((rows(path) for path in files), key=lambda data: data[-1]["dofs"])
    if len(runs) >= 2:
        fine, coarse = runs[-1][-1], runs[-2][-1]  # the two finest meshes' final steps
        out += [
            prose(
                "_hyper_ball",
                "the_two_finest_meshes",
                fine_dofs=f"{fine['dofs']:,}",
                coarse_dofs=f"{coarse['dofs']:,}",
                change=f"{abs(fine['contact_force'] / coarse['contact_force'] - 1):.1e}",
                newton=", ".join(str(r["newton_iterations"]) for r in runs[-1]),
                path_minutes=f"{fine['path_seconds'] / 60:.0f}",
                rss=fine["peak_rss_mib"],
            ),
            "",
        ]
    return "\n".join(out)


def _hyper_drag() -> str:
    """§11.10: Coulomb friction between two neo-Hookean bodies, 2D and 3D."""
    out = [prose("_hyper_drag", "title"), ""]
    data = rows(RES / HYPER / "two_body_drag.csv")
    if not data:
        return "\n".join([*out, missing(f"demos/results/{HYPER}/two_body_drag.csv"), ""])
    body = [
        [
            f"{r['dim']}D",
            r["dofs"],
            f"{r['t']:g}",
            f"{r['slide']:.3f}",
            r["couplings"],
            r["newton"],
            f"{r['stick']}/{r['slip']}",
            f"{r['ratio']:.12f}",
            f"{r['drag_force']:.5f}",
            f"{r['press_force']:.5f}",
            f"{r['balance']:.1e}",
        ]
        for r in data
    ]
    header = ["", "DoFs", "t", "slide", "couplings", "Newton", "stick/slip", "R"]
    header += ["drag", "press", "balance"]
    full = [r for r in data if r["stick"] == 0 and r["separated"] == 0]
    dims = sorted({r["dim"] for r in data})

    def span(values) -> str:
        return f"{min(values):g}–{max(values):g}"

    per_dim = "; ".join(
        f"{d}D from t = {min(r['t'] for r in full if r['dim'] == d):g}" for d in dims
    )
    cpu = ", ".join(
        f"{d}D {next(r['path_cpu_seconds'] for r in data if r['dim'] == d):g} s" for d in dims
    )
    out += [
        prose("_hyper_drag", "intro", table=table(header, body)),
        "",
        prose(
            "_hyper_drag",
            "summary",
            full=per_dim,
            ratio_error=f"{max(r['ratio_error'] for r in data):.0e}",
            balance=f"{max(r['balance'] for r in data):.0e}",
            drag_press=span([round(r["drag_force"] / r["press_force"], 3) for r in full]),
            couplings=span([r["couplings"] for r in data]),
            newton=span([r["newton"] for r in data]),
            cpu=cpu,
        ),
        "",
    ]
    return "\n".join(out)


def _hyper_kink() -> str:
    """§11.11: a neo-Hookean tube kinked by end rotations until its inner walls touch."""
    out = [prose("_hyper_kink", "title"), ""]
    data = rows(RES / HYPER / "kink.csv")
    if not data:
        return "\n".join([*out, missing(f"demos/results/{HYPER}/kink.csv"), ""])
    fine_n = max(r["path_steps"] for r in data)
    coarse_n = min(r["path_steps"] for r in data)
    fine = [r for r in data if r["path_steps"] == fine_n]
    body = [
        [
            f"{r['phi']:.3f}",
            f"{r['moment']:.5f}",
            f"{r['beam_moment']:.5f}",
            f"{r['axial_reaction']:+.5f}",
            r["pressed"],
            f"{r['contact_force']:.2e}",
            r["couplings"],
            r["newton"],
            f"{r['min_det_F']:.3f}",
        ]
        for r in fine
    ]
    header = ["φ", "M", "E I φ / a", "N", "pressed", "contact force", "couplings", "Newton"]
    header += ["min det F"]
    k = max(range(len(fine)), key=lambda i: fine[i]["moment"])
    peak, after = fine[k], fine[min(k + 1, len(fine) - 1)]
    touch = next((r["phi"] for r in fine if r["pressed"] > 0), float("nan"))

    def span(values) -> str:
        return f"{min(values):g}–{max(values):g}"

    cpu = ", ".join(
        f"{n} steps {next(r['path_cpu_seconds'] for r in data if r['path_steps'] == n):g} s"
        for n in (fine_n, coarse_n)
    )
    first = next(r for r in fine if r["phi"] >= 0.1 - 1e-12)
    out += [
        prose(
            "_hyper_kink",
            "intro",
            dofs=DOFS_KINK,
            fine=fine_n,
            coarse=coarse_n,
            table=table(header, body),
        ),
        "",
        prose(
            "_hyper_kink",
            "summary",
            beam=f"{abs(first['moment'] / first['beam_moment'] - 1):.1%}",
            first=f"{first['phi']:g}",
            peak_phi=f"{peak['phi']:g}",
            peak=f"{peak['moment']:.5f}",
            peak_ratio=f"{peak['moment'] / peak['beam_moment']:.2f}",
            drop=f"{after['phi'] - peak['phi']:.3g} rad",
            drop_ratio=f"{1 - after['moment'] / peak['moment']:.0%}",
            last=f"{fine[-1]['moment']:.1e}",
            touch=f"{touch:g}",
            pressed=fine[-1]["pressed"],
            couplings=span([r["couplings"] for r in data]),
            newton=span([r["newton"] for r in data]),
            det=f"{min(r['min_det_F'] for r in data):.2f}",
            cpu=cpu,
        ),
        "",
    ]
    return "\n".join(out)


#: the DoFs of configs/hyperelastic_self_contact_kink.yaml (3 × 3 × 25 × 13 nodes)
DOFS_KINK = 2925


#: the cases of §11.9 (demos/bench/bench_hyperelastic.py adaptive --case ...) and their titles
ADAPTIVE_CURVED = {
    "indenter": "A rigid cylinder R = 0.05 lowered 0.2 R into the unit half block on rollers, "
    "from 8 × 8 (tests/test_hyperelastic_adapt.py::indenter)",
    "indentation": "configs/hyperelastic_indentation.yaml: R = 0.5 lowered 0.4 R into the "
    "clamped block [−1, 1] × [−1, 0], from 20 × 10",
}


def _hyper_adaptive_curved() -> str:
    """§11.9: Dörfler against uniform refinement against a rigid cylinder."""
    out = [prose("_hyper_adaptive_curved", "title"), ""]
    found = [c for c in ADAPTIVE_CURVED if rows(RES / HYPER / f"adaptive_{c}.csv")]
    if not found:
        return "\n".join([*out, missing(f"demos/results/{HYPER}/adaptive_<case>.csv"), ""])
    out += [prose("_hyper_adaptive_curved", "intro"), ""]
    for case in found:
        data = rows(RES / HYPER / f"adaptive_{case}.csv") or []
        summary = rows(RES / HYPER / f"adaptive_{case}_summary.csv") or []
        lines = []
        for r in summary:
            u, d, tol = r["uniform_dofs"], r["dorfler_dofs"], f"{r['tolerance']:.2%}"
            if r["ratio"] in ("", None):
                which = "uniform refinement" if u in ("", None) else "Dörfler"
                line = prose(
                    "_hyper_adaptive_curved",
                    "summary_none",
                    tol=tol,
                    uniform=g(u),
                    dorfler=g(d),
                    which=which,
                )
            else:
                fit = f"{r['uniform_interpolated']:.0f}", f"{r['dorfler_interpolated']:.0f}"
                line = prose(
                    "_hyper_adaptive_curved",
                    "summary_row",
                    tol=tol,
                    uniform=u,
                    dorfler=d,
                    ratio=f"{r['ratio']:.1f}",
                    uniform_fit=fit[0],
                    dorfler_fit=fit[1],
                    ratio_fit=f"{r['ratio_interpolated']:.1f}",
                )
            lines.append(line)
        body = [
            [
                r["strategy"],
                r["level"],
                r["dofs"],
                f"{r['eta']:.4e}",
                f"{r['contact_force']:.9f}",
                f"{r['force_above_reference']:+.2e}",
                r["newton_iterations"],
            ]
            for r in data
        ]
        header = ["strategy", "level", "DoFs", "η", "F", "F / F_ref − 1", "Newton its"]
        out += [
            prose(
                "_hyper_adaptive_curved",
                "case",
                title=ADAPTIVE_CURVED[case],
                case=case,
                reference=f"{data[0]['reference_force']:.9f}",
                table=table(header, body),
                summary="\n".join(lines),
            ),
            "",
        ]
    out += [prose("_hyper_adaptive_curved", "closing"), ""]
    return "\n".join(out)


def _hyper_ironing() -> str:
    """§11.8: the ironing benchmark on three meshes (demos/bench/bench_ironing.py)."""
    out, data = _hyper_open(prose("_hyper_ironing", "the_ironing_benchmark"), "ironing_meshes.csv")
    if not data:
        return "\n".join(out)

    def pct(x) -> str:
        return "–" if x in ("", None) else f"{100 * x:.2g} %"

    body = [
        [
            r["cells"],
            r["dofs"],
            r["steady_steps"],
            f"{r['max_rel_dev_Ft_Fn']:.1e}",
            f"{r['min_Fx_over_Fy']:.3f}–{r['max_Fx_over_Fy']:.3f}",
            f"{r['max_balance']:.0e}",
            r["newton_per_step"],
            f"{r['press_force_y_at_2']:.4f}",
            pct(r.get("press_force_y_diff_at_2")),
            f"{r['drag_force_x_at_2']:.4f}",
            pct(r.get("drag_force_x_diff_at_2")),
            r["run_seconds"],
        ]
        for r in data
    ]
    header = [
        "mesh",
        "DoFs",
        "steady steps",
        "max |F_t/F_n − μ| / μ",
        "F_x / F_y steady",
        "balance",
        "Newton its / step",
        "F_y at s = 2",
        "to finer",
        "F_x at s = 2",
        "to finer",
        "wall s",
    ]
    out += [prose("_hyper_ironing", "python_demos_bench", table=table(header, body)), ""]
    if len(data) >= 3 and "press_force_y_order" in data[0]:
        first, second = data[0], data[1]
        out += [
            prose(
                "_hyper_ironing",
                "in_steady_sliding",
                worst_dev=f"{max(r['max_rel_dev_Ft_Fn'] for r in data):.0e}",
                fx_fy=f"{min(r['min_Fx_over_Fy'] for r in data):.3f}–"
                f"{max(r['max_Fx_over_Fy'] for r in data):.3f}",
                dfy=pct(first["press_force_y_diff_at_2"]),
                dfx=pct(first["drag_force_x_diff_at_2"]),
                dfy2=pct(second["press_force_y_diff_at_2"]),
                dfx2=pct(second["drag_force_x_diff_at_2"]),
                order_y=f"{first['press_force_y_order']:.2f}",
                order_x=f"{first['drag_force_x_order']:.2f}",
                pressure_share=pct(
                    data[-1]["drag_by_pressure_at_2"] / data[-1]["drag_force_x_at_2"]
                ),
            ),
            "",
        ]
    return "\n".join(out)


def _hyper_stability() -> str:
    runs, _, out = _open(
        "### 11.4 Stability map at finite strain", "stability_hyperelastic", "stability"
    )
    if not runs:
        return "\n".join(out)
    out += [prose("_hyper_stability", "configs_studies_stability_hyperelastic")]
    cases = list(dict.fromkeys(r["case"] for r in runs))
    methods = list(dict.fromkeys(r["method"] for r in runs))
    body = []
    for case in cases:
        line = [case]
        for m in methods:
            cell = [r for r in runs if r["case"] == case and r["method"] == m]
            ok = [r for r in cell if r["outcome"] == "converged"]
            fewest = min((r["steps"] for r in ok), default=None)
            others = Counter(r["outcome"] for r in cell if r["outcome"] != "converged")
            text = f"from {fewest} step(s)" if fewest is not None else "never"
            if others:
                text += "; " + ", ".join(f"{n}× {o}" for o, n in others.items())
            line.append(text)
        body.append(line)
    out += [
        prose("_hyper_stability", "each_cell_the_fewest", table=table(["case", *methods], body))
    ]
    ten = {r["method"]: r for r in runs if r["case"].startswith("(a)") and r["steps"] == 10}
    if ten:
        its = ", ".join(f"{m} {r['newton_iterations_total']}" for m, r in ten.items())
        out += [prose("_hyper_stability", "why_the_neo_hookean", its=its)]
    return "\n".join(out)


def effectivity_chart(levels: list[dict], out: Path) -> Path:
    """effectivity.png: η / error per level against the DoFs, one colour per problem and
    rank count, solid the equilibrated bound, dashed the residual estimator."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    keys = list(dict.fromkeys((r["problem"], r["ranks"]) for r in levels))
    for i, (problem, ranks) in enumerate(keys):
        rs = sorted(
            (r for r in levels if (r["problem"], r["ranks"]) == (problem, ranks)),
            key=lambda r: r["level"],
        )
        dofs = [r["dofs"] for r in rs]
        colour = f"C{i % 10}"
        tag = f"{problem}" + (f" ({ranks} ranks)" if ranks != 1 else "")
        ax.plot(dofs, [r["effectivity"] for r in rs], "o-", color=colour, ms=3, label=tag)
        ax.plot(dofs, [r["residual_effectivity"] for r in rs], "s--", color=colour, ms=3)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.axhline(1.5, color="grey", lw=0.8, ls=":")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("DoFs")
    ax.set_ylabel("effectivity η / ‖u − u_h‖_E")
    ax.set_title(prose("effectivity_chart", "effectivity_per_level_equilibrated"))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def _span(values: list) -> str:
    """'min–max' of numbers (one value when they are equal)."""
    if not values:
        return "–"
    lo, hi = min(values), max(values)
    text = [str(v) if isinstance(v, int) else f"{v:.3g}" for v in (lo, hi)]
    return text[0] if text[0] == text[1] else f"{text[0]}–{text[1]}"


def _stopping_table(runs: list[dict], estimate: bool = False) -> list[str]:
    """The table of bench_stopping.py's runs per mode (``estimate``: with the estimate's CPU
    seconds), and where both modes ran: the Krylov iterations saved, the final errors, and in
    how many pairs of runs (run i of each mode, in turn in one process) adaptive stopping
    took less CPU and less wall time than fixed tolerances."""
    body = []
    for mode in dict.fromkeys(r["mode"] for r in runs):
        rs = [r for r in runs if r["mode"] == mode]
        cpu = sorted(r["cpu"] for r in rs)
        body.append(
            [
                mode,
                len(rs),
                _span([r["krylov_iterations"] for r in rs]),
                _span([r["cpu_solve"] for r in rs]),
                *([_span([r["cpu_estimate"] for r in rs])] if estimate else []),
                f"{cpu[0]:.3g} / {statistics.median(cpu):.3g} / {cpu[-1]:.3g}",
                _span([r["dofs"] for r in rs]),
                _span([r["error"] for r in rs]),
            ]
        )
    head = ["mode", "runs", "Krylov iterations", "solve CPU s"]
    head += ["estimate CPU s"] if estimate else []
    head += ["loop CPU s min / median / max", "final DoFs", "final error"]
    out = [table(head, body), ""]
    by = {m: {r["run"]: r for r in runs if r["mode"] == m} for m in ("fixed", "adaptive")}
    pairs = [(by["fixed"][i], by["adaptive"][i]) for i in by["fixed"] if i in by["adaptive"]]
    if pairs and "cpu_estimate" in pairs[0][0]:
        fixed, adaptive = pairs[0]
        won = sum(a["cpu"] < f["cpu"] for f, a in pairs)
        won_wall = sum(a["wall"] < f["wall"] for f, a in pairs)
        wall = {m: statistics.median(r["wall"] for r in by[m].values()) for m in by}
        share = statistics.median(r["cpu_estimate"] / r["cpu"] for pair in pairs for r in pair)
        fewer = fixed["krylov_iterations"] / adaptive["krylov_iterations"]
        change = adaptive["error"] / fixed["error"] - 1
        out += [
            prose(
                "_stopping_table",
                "adaptive_stopping",
                fewer=f"{fewer:.2g}",
                change=f"{change:+.1%}",
                won=won,
                len_pairs=len(pairs),
                won_wall=won_wall,
                wall_fixed=f"{wall['fixed']:.3g}",
                wall_adaptive=f"{wall['adaptive']:.3g}",
                share=f"{share:.0%}",
            ),
            "",
        ]
    return out


def _cost_elastic(rs: list[dict]) -> list[str]:
    """The elastic estimate's cost against one CG + GAMG solve of K, compiled and NumPy
    patch backends (``bench_equilibrated.py --cost-elastic``), with its phases."""
    by = {r["backend"]: r for r in rs}
    c, n = by.get("compiled"), by.get("numpy")
    if c is None:
        return []
    numpy_text = ""
    if n is not None:
        same = abs(c["eta"] - n["eta"]) / abs(c["eta"])
        numpy_text = prose(
            "_cost_elastic",
            "with_the_numpy_patch",
            g_n_estimate_cpu=g(n["estimate_cpu"]),
            g_n_ratio_cpu=g(n["ratio_cpu"]),
            same=f"{same:.0e}",
        )
    return [
        prose(
            "_cost_elastic",
            "cost_of_the_elastic",
            c_dofs=c["dofs"],
            c_scene=c["scene"],
            c_refinements=c["refinements"],
            c_ranks=c["ranks"],
            c_repeat=c["repeat"],
            c_cg_iterations=c["cg_iterations"],
            g_c_solve_cpu=g(c["solve_cpu"]),
            g_c_estimate_cpu=g(c["estimate_cpu"]),
            g_c_ratio_cpu=g(c["ratio_cpu"]),
            numpy_text=numpy_text,
            g_c_seconds_korn=g(c["seconds_korn"]),
            g_c_seconds_patches=g(c["seconds_patches"]),
            g_c_seconds_rotations=g(c["seconds_rotations"]),
            g_c_seconds_terms=g(c["seconds_terms"]),
        ),
        "",
    ]


def guaranteed() -> str:
    """Section 12: the equilibrated bound against the residual estimator per level
    (demos/bench/bench_equilibrated.py), the reconstruction's cost, adaptive stopping
    (demos/bench/bench_stopping.py) and the default estimator that follows."""
    out = [prose("guaranteed", "guaranteed_error_bounds_the")]
    folder = RES / "equilibrated"
    levels = [
        r
        for path in sorted(folder.glob("effectivity*.csv"))
        if not any(tag in path.stem for tag in ("uniform", "_3d", "_flow", "_lowest"))
        for r in rows(path) or []
    ]
    if not levels:
        return (
            "\n".join(out)
            + "\n"
            + missing(prose("guaranteed", "equilibrated_effectivity_csv_demos"))
        )
    chart = effectivity_chart(levels, folder / "effectivity.png")
    out += [prose("guaranteed", "demos_bench_bench_equilibrated", chart_name=chart.name)]
    body, late_eq, late_res, all_res = [], [], [], []
    for problem, ranks in dict.fromkeys((r["problem"], r["ranks"]) for r in levels):
        rs = [r for r in levels if (r["problem"], r["ranks"]) == (problem, ranks)]
        late = [r for r in rs if r["level"] >= 3]
        late_eq += [r["effectivity"] for r in late]
        late_res += [r["residual_effectivity"] for r in late]
        all_res += [r["residual_effectivity"] for r in rs]
        below = [r["level"] for r in rs if r["eta"] < r["error"]]
        body.append(
            [
                problem,
                ranks,
                len(rs),
                max(r["dofs"] for r in rs),
                _span([r["effectivity"] for r in rs]),
                _span([r["effectivity"] for r in late]),
                "yes" if not below else f"no (levels {below})",
                _span([r["residual_effectivity"] for r in rs]),
                _span([r["residual_effectivity"] for r in late]),
            ]
        )
    out += [
        table(
            [
                "problem",
                "ranks",
                "levels",
                "final DoFs",
                "equilibrated η/error",
                "from level 3",
                "η ≥ error on every level",
                "residual η/error",
                "from level 3",
            ],
            body,
        ),
        "",
    ]
    all_cost = [r for name in ("cost.csv", "cost_3d.csv") for r in rows(folder / name) or []]
    cost_rows = [r for r in all_cost if r["backend"] == "compiled"]
    for r in cost_rows:
        line = prose(
            "guaranteed",
            "cost_dofs_rank_bench",
            r_dim=r["dim"],
            r_dofs=r["dofs"],
            r_ranks=r["ranks"],
            if_r_dim_2_else_3d="" if r["dim"] == 2 else "3d",
            g_r_solve_cpu=g(r["solve_cpu"]),
            g_r_reconstruction_cpu=g(r["reconstruction_cpu"]),
            g_r_ratio_cpu=g(r["ratio_cpu"]),
            v_1_if_r_dim_2_else_2=1 if r["dim"] == 2 else 2,
            g_r_estimate_cpu=g(r["estimate_cpu"]),
            g_r_estimate_ratio_cpu=g(r["estimate_ratio_cpu"]),
        )
        if r.get("residual_cpu") not in (None, ""):
            line += (
                f"; the residual estimate {g(r['residual_cpu'])} s = {g(r['residual_ratio_cpu'])}×"
            )
        variants = {
            "flow": prose("guaranteed", "the_cheaper_p1_fit"),
            "lowest": prose("guaranteed", "the_lowest_order_flux"),
        }
        for f in (f for f in all_cost if f["backend"] in variants and f["dim"] == r["dim"]):
            fastest = f.get("ratio_cpu_min")
            line += prose(
                "guaranteed",
                "with_the_reconstruction_the",
                variants_f_backend=variants[f["backend"]],
                g_f_reconstruction_cpu=g(f["reconstruction_cpu"]),
                g_f_ratio_cpu=g(f["ratio_cpu"]),
                f=f" (the fastest runs' {g(fastest)}×)" if fastest not in (None, "") else "",
                g_f_estimate_cpu=g(f["estimate_cpu"]),
                g_f_estimate_ratio_cpu=g(f["estimate_ratio_cpu"]),
            )
        out += [line + ".", ""]
    eff3d = rows(folder / "effectivity_3d.csv") or []
    if eff3d:
        cells = [
            f"{r['dofs']} DoFs: "
            + ", ".join(
                f"{b['backend']} {b['effectivity']:.3f}"
                for b in eff3d
                if (b["n"], b["ranks"]) == (r["n"], r["ranks"])
            )
            for r in eff3d
            if r["backend"] == eff3d[0]["backend"]
        ]
        out += [prose("guaranteed", "effectivity_d_problem_a", join="; ".join(cells))]
    cheaper = {
        "flow": prose("guaranteed", "the_cheaper_p1_fit_2"),
        "lowest": prose("guaranteed", "the_lowest_order_flux_2"),
    }
    for variant, what in cheaper.items():
        fit = rows(folder / f"effectivity_{variant}.csv") or []
        if not fit:
            continue
        parts = []
        for problem in dict.fromkeys(r["problem"] for r in fit):
            rs = [r for r in fit if r["problem"] == problem]
            below = [r["level"] for r in rs if r["eta"] < r["error"]]
            late = _span([r["effectivity"] for r in rs if r["level"] >= 3])
            parts.append(
                f"{problem} {late}" + ("" if not below else f" (η < error on levels {below})")
            )
        out += [
            prose("guaranteed", "effectivity_of", what=what, variant=variant, join="; ".join(parts))
        ]
    out += _cost_elastic(rows(folder / "cost_elastic.csv") or [])
    stop = rows(RES / "stopping" / "stopping.csv") or []
    if stop:
        out += [
            prose("guaranteed", "adaptive_stopping_demos_bench", g_stop_0_tol=g(stop[0]["tol"])),
            *_stopping_table(stop),
        ]
    hertz = rows(RES / "stopping" / "stopping_hertz_2d.csv") or []
    if hertz:
        out += [
            prose(
                "guaranteed",
                "hertz_d_to",
                g_hertz_0_tol=g(hertz[0]["tol"]),
                hertz_0_reference_dofs=hertz[0]["reference_dofs"],
            ),
            *_stopping_table(hertz, estimate=True),
        ]
    certify = rows(folder / "estimators.csv") or []
    medians = {}
    if certify:
        body = []
        for est in dict.fromkeys(r["estimator"] for r in certify):
            rs = [r for r in certify if r["estimator"] == est]
            cpu = sorted(r["cpu"] for r in rs)
            medians[est] = (rs[0], statistics.median(cpu))
            body.append(
                [
                    est,
                    len(rs),
                    _span([r["levels"] for r in rs]),
                    _span([r["dofs"] for r in rs]),
                    _span([r["eta"] for r in rs]),
                    _span([r["error"] for r in rs]),
                    f"{cpu[0]:.3g} / {statistics.median(cpu):.3g} / {cpu[-1]:.3g}",
                ]
            )
        out += [
            prose(
                "guaranteed",
                "to_certify_a_tolerance",
                certify_0_scene=certify[0]["scene"],
                g_certify_0_tol=g(certify[0]["tol"]),
                table=table(
                    [
                        "estimator",
                        "runs",
                        "levels",
                        "final DoFs",
                        "final η",
                        "final error",
                        "loop CPU s min / median / max",
                    ],
                    body,
                ),
            )
        ]
    text = prose(
        "guaranteed",
        "the_default_estimator_for",
        span_late_eq=_span(late_eq),
        span_all_res=_span(all_res),
        span_late_res=_span(late_res),
    )
    if {"residual", "equilibrated"} <= set(medians):
        (res, res_cpu), (eq, eq_cpu) = medians["residual"], medians["equilibrated"]
        text += prose(
            "guaranteed",
            "cost_one_equilibrated_estimate",
            g_res_tol=g(res["tol"]),
            eq_dofs=eq["dofs"],
            eq_cpu=f"{eq_cpu:.3g}",
            res_effectivity=f"{res['effectivity']:.2f}",
            res_dofs=res["dofs"],
            res_cpu=f"{res_cpu:.3g}",
        )
    out += [prose("guaranteed", "estimator_therefore_defaults_to", text=text)]
    return "\n".join(out)


def hp_chart(levels: list[dict], out: Path) -> Path:
    """hp.png: the energy error per level against the unknowns (top) and the process's CPU
    seconds (bottom: wall seconds scatter on a shared machine), one column per problem, one
    curve per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    problems = list(dict.fromkeys(r["problem"] for r in levels))
    fig, axes = plt.subplots(2, len(problems), figsize=(5.2 * len(problems), 7.5), squeeze=False)
    for j, problem in enumerate(problems):
        methods = list(dict.fromkeys(r["method"] for r in levels if r["problem"] == problem))
        for i, method in enumerate(methods):
            rs = [r for r in levels if (r["problem"], r["method"]) == (problem, method)]
            for k, key in enumerate(("unknowns", "cpu_seconds")):
                axes[k][j].plot(
                    [r[key] for r in rs],
                    [r["error"] for r in rs],
                    "o-",
                    ms=3,
                    color=f"C{i}",
                    label=method,
                )
        for k, key in enumerate(("unknowns (hp: of V_hp; h: DoFs)", "CPU seconds (cumulative)")):
            ax = axes[k][j]
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel(key)
            ax.set_ylabel("energy error")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
        axes[0][j].set_title(f"Problem {problem}")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _rate(levels: list[dict]) -> float:
    """r of error ≈ c N^−r, least squares over ``levels`` (unknowns, error)."""
    x = [math.log(r["unknowns"]) for r in levels]
    y = [math.log(r["error"]) for r in levels]
    return -statistics.linear_regression(x, y).slope


def hp_section() -> str:
    """§15: hp against h-adaptive P1 and P2 (demos/bench/bench_hp.py)."""
    head = [
        "## 15. hp-adaptivity",
        "",
        prose("hp_section", "adapt_strategy_hp_docs"),
        "",
    ]
    summary = rows(RES / "hp" / "summary.csv")
    levels = rows(RES / "hp" / "levels.csv")
    if not summary or not levels:
        return "\n".join([*head, missing(prose("hp_section", "demos_results_hp_summary"))])
    body = []
    for r in summary:
        body.append(
            [
                r["problem"],
                r["method"],
                g(r["target"]),
                "yes" if r["reached"] else "no (budget)",
                r["unknowns"],
                g(r["error"]),
                f"{r['seconds']:.2f}",
                f"{r['cpu_seconds']:.2f}",
                f"{r['unknowns_ratio_P2']:.1f}",
                f"{r['seconds_ratio_P2']:.2f}",
                f"{r['cpu_ratio_P2']:.2f}",
                g(r["effectivity_max_past_3"]),
                "yes" if r["bound_holds"] else "**no**",
                r["levels"],
            ]
        )
    lines = [
        *head,
        prose(
            "hp_section",
            "n_and_seconds_are",
            table=table(
                [
                    "problem",
                    "method",
                    "target",
                    "reached",
                    "N",
                    "error",
                    "seconds",
                    "CPU s",
                    "N(P2) / N",
                    "s(P2) / s",
                    "CPU(P2) / CPU",
                    "η / error max past level 3",
                    "η ≥ error on every level",
                    "levels",
                ],
                body,
            ),
        ),
    ]
    for r in summary:
        if r["method"].startswith("hp") and r["exp_rate_b"] != "":
            lines.append(
                prose(
                    "hp_section",
                    "log_error_over_the",
                    r_problem=r["problem"],
                    r_method=r["method"],
                    r_exp_rate_b=f"{r['exp_rate_b']:.3f}",
                    r_exp_fit_r2=f"{r['exp_fit_r2']:.3f}",
                )
            )
    robust = rows(RES / "hp" / "p_robust.csv")
    if robust:
        lines += [
            prose(
                "hp_section",
                "p_robustness_of_the",
                table=table(
                    [
                        "problem",
                        "p_max",
                        "levels",
                        "N",
                        "error",
                        "η / error max past level 3",
                        "median",
                        "η ≥ error on every level",
                    ],
                    [
                        [
                            r["problem"],
                            r["p_max"],
                            r["levels"],
                            r["unknowns"],
                            g(r["error"]),
                            g(r["effectivity_max_past_3"]),
                            g(r["effectivity_median_past_3"]),
                            "yes" if r["bound_holds"] else "**no**",
                        ]
                        for r in robust
                    ],
                ),
            )
        ]
    hertz = rows(RES / "hp" / "hertz_summary.csv")
    if hertz:
        lines += [
            prose(
                "hp_section",
                "hertz_hp",
                table=table(
                    [
                        "method",
                        "reached",
                        "level",
                        "N",
                        "a / a_H − 1",
                        "p0 / p0_H − 1",
                        "CPU s",
                        "N(P1) / N",
                        "CPU(P1) / CPU",
                    ],
                    [
                        [
                            r["method"],
                            "yes" if r["reached"] else "no",
                            r["level"],
                            r["unknowns"],
                            f"{100 * r['a_error']:+.2f} %",
                            f"{100 * r['p0_error']:+.2f} %",
                            f"{r['cpu_seconds']:.2f}",
                            f"{r['unknowns_ratio_P1']:.2f}",
                            f"{r['cpu_ratio_P1']:.2f}",
                        ]
                        for r in hertz
                    ],
                ),
            )
        ]
    solvers = (rows(RES / "hp" / "solvers.csv") or []) + (
        rows(RES / "hp" / "solvers_refined.csv") or []
    )
    if solvers:
        lines += [
            prose(
                "hp_section",
                "hp_solvers",
                table=table(
                    [
                        "cells",
                        "p",
                        "N",
                        "solver",
                        "iterations",
                        "setup CPU s",
                        "solve CPU s",
                        "CPU / direct",
                    ],
                    [
                        [
                            r["cells"],
                            r["p"],
                            r["unknowns"],
                            r["solver"],
                            r["iterations"]
                            if r["converged"]
                            else f"{r['iterations']} (**not converged**)",
                            f"{r['setup_cpu']:.3f}",
                            f"{r['solve_cpu']:.3f}",
                            f"{r['cpu_ratio_direct']:.2f}",
                        ]
                        for r in solvers
                    ],
                ),
            )
        ]
    compared = ("hp", "hp-theta0.7", "hp-theta0.85", "hp-theta0.9", "hp-theta0.85-pmax-space")
    theta = [r for r in levels if r["method"] in (*compared, "h-P2")]
    if theta:
        methods = list(dict.fromkeys(r["method"] for r in theta))
        body = []
        for problem, targets in (("C", (1e-3, 1e-4, 1.2e-5, 1e-6)), ("A", (1e-3, 3e-4, 1e-4))):
            for target in targets:
                cells = []
                for method in methods:
                    hit = next(
                        (
                            r
                            for r in theta
                            if r["problem"] == problem
                            and r["method"] == method
                            and r["error"] <= target
                        ),
                        None,
                    )
                    cells.append(f"{hit['cpu_seconds']:.2f} ({hit['unknowns']})" if hit else "–")
                body.append([problem, g(target), *cells])
        lines += [
            prose(
                "hp_section",
                "equal_error",
                table=table(["problem", "error ≤", *methods], body),
            )
        ]
    cube = rows(RES / "hp" / "three_d.csv")
    if cube:
        lines += [
            prose(
                "hp_section",
                "three_d_hp",
                table=table(
                    ["level", "N", "cells", "degrees", "error", "η", "η / error", "CPU s"],
                    [
                        [
                            r["level"],
                            r["unknowns"],
                            r["cells"],
                            f"{r['p_min']}–{r['p_max']}",
                            g(r["error"]),
                            g(r["eta"]),
                            f"{r['effectivity']:.3f}",
                            f"{r['cpu_seconds']:.1f}",
                        ]
                        for r in cube
                    ],
                ),
                bound="yes" if all(r["eta"] >= r["error"] for r in cube) else "**no**",
                rate=f"{_rate(cube[3:]):.2f}",
            )
        ]
    try:
        chart = hp_chart(levels, RES / "hp" / "hp.png")
        lines += ["", f"![hp against h]({chart.relative_to(RES.parent)})", ""]
    except Exception as exc:  # a failed picture costs a warning, never the results
        lines += ["", f"*The chart failed: {exc}*", ""]
    return "\n".join(lines)


def design_measurements() -> str:
    """Timings behind design choices of the code, quoted here instead of in its docstrings."""
    return "\n".join(
        [
            prose(
                "design_measurements",
                "measurements_behind_design_choices",
                table=table(
                    ["module", "choice", "measured", "reproduce"],
                    [list(m) for m in DESIGN_MEASUREMENTS],
                ),
            )
        ]
    )


# ------------------------------------------------------------------- baseline enforcements
BASELINE_PROBLEMS = DATA["baseline_problems"]
BASELINE_VARIANTS = (
    ("penalty", ""),
    ("augmented_lagrangian", ""),
    ("nitsche", 1.0),
    ("nitsche", -1.0),
)
BASELINE_DEFAULTS = {"penalty": 1e3, "augmented_lagrangian": 1e2, "nitsche": 10.0}
BASELINE_SYMBOL = {"penalty": "ε₀", "augmented_lagrangian": "r₀", "nitsche": "γ₀"}
EQUAL = 0.01  # fb's accuracy: |||u − u_fb||| ≤ EQUAL · fb's error (bench_baselines.TOLERANCE)


def _variant(method: str, theta) -> str:
    return method if theta == "" else f"nitsche θ = {theta:g}"


def _runs_of(data: list[dict], method: str, theta, dofs=None) -> list[dict]:
    return [
        r
        for r in data
        if r["method"] == method
        and (theta == "" or r["theta"] == theta)
        and (dofs is None or r["dofs"] == dofs)
    ]


def _log_slope(x: list[float], y: list[float]) -> float:
    lx, ly = [math.log(v) for v in x], [math.log(v) for v in y]
    mx, my = sum(lx) / len(lx), sum(ly) / len(ly)
    return sum((a - mx) * (b - my) for a, b in zip(lx, ly)) / sum((a - mx) ** 2 for a in lx)


def _reaches_fb(r: dict) -> bool:
    """Converged and within EQUAL of fb's error from fb's solution (energy norms)."""
    return r["converged"] is True and r["dist_fb"] * r["norm_fb"] <= EQUAL * r["error_fb"]


def _equal_accuracy(runs: list[dict], method: str) -> dict | None:
    """The run of fb's accuracy with the smallest parameter (the augmented Lagrangian: the
    fastest, its accuracy does not depend on r)."""
    ok = [r for r in runs if _reaches_fb(r)]
    if not ok:
        return None
    key = (lambda r: r["seconds"]) if method == "augmented_lagrangian" else (lambda r: r["value"])
    return min(ok, key=key)


def _its_outer(r: dict) -> str:
    """'n' Newton iterations, 'n (k)' with k Uzawa iterations."""
    n = r["newton_iterations"]
    return f"{n} ({r['outer_iterations']})" if r["method"] == "augmented_lagrangian" else str(n)


def _default_run(data: list[dict], method: str, theta, dofs) -> dict | None:
    return next(
        (r for r in _runs_of(data, method, theta, dofs) if r["value"] == BASELINE_DEFAULTS[method]),
        None,
    )


def _baseline_orders(data: list[dict]) -> list[str]:
    """Penalty: |||u − u_fb||| and the penetration against ε₀ (10 ≤ ε₀ ≤ 1e5: beyond, the
    distance meets the floor of the Krylov tolerance on a system ε₀ times stiffer) on the
    finest mesh;
    every variant: the error against the DoFs at its default parameter, fb's beside."""
    finest = max(r["dofs"] for r in data)
    lines = []
    pen = [
        r
        for r in _runs_of(data, "penalty", "", finest)
        if r["converged"] is True and 10 <= r["value"] <= 1e5 and r["dist_fb"] > 1e-12
    ]
    if len(pen) >= 3:
        eps = [r["value"] for r in pen]
        lines.append(
            prose(
                "_baseline_orders",
                "penalty_dofs_penetration",
                g_eps_0=g(eps[0]),
                g_eps_1=g(eps[-1]),
                finest=finest,
                distance_order=f"{_log_slope(eps, [r['dist_fb'] for r in pen]):.2f}",
                penetration_order=f"{_log_slope(eps, [r['penetration'] for r in pen]):.2f}",
            )
        )
    for method, theta in (("fb", ""), *BASELINE_VARIANTS):
        runs = sorted(
            (
                r
                for r in _runs_of(data, method, theta)
                if r["converged"] is True
                and (method == "fb" or r["value"] == BASELINE_DEFAULTS[method])
            ),
            key=lambda r: r["dofs"],
        )
        if len(runs) >= 2:
            rate = _log_slope([r["dofs"] for r in runs], [r["error"] for r in runs])
            default = "" if method == "fb" else " (default)"
            lines.append(f"{_variant(method, theta)}{default}: error ∝ N^{rate:.2f}")
    return lines


def _failures(data: list[dict]) -> str:
    """The swept runs that did not converge, by variant: their parameters and reasons."""
    parts = []
    for method, theta in BASELINE_VARIANTS:
        failed = [r for r in _runs_of(data, method, theta) if r["converged"] is not True]
        by_reason: dict[str, list[str]] = {}
        for r in failed:
            by_reason.setdefault(r["reason"], []).append(f"{g(r['value'])} ({r['dofs']})")
        for reason, where in by_reason.items():
            parts.append(
                f"{_variant(method, theta)} {reason} at {BASELINE_SYMBOL[method]} = "
                + ", ".join(where)
            )
    return "; ".join(parts) if parts else "none"


def baselines() -> str:
    out = [prose("baselines", "penalty_augmented_lagrangian_and", equal=f"{EQUAL:g}")]
    found: dict[str, list[dict]] = {}
    for problem in BASELINE_PROBLEMS:
        data = rows(RES / "baselines" / f"{problem}.csv")
        if data:
            found[problem] = data
    if not found:
        return "\n".join([*out, missing("demos/results/baselines/")])
    summary = []
    for problem, title in BASELINE_PROBLEMS.items():
        out += [f"### {title}", ""]
        data = found.get(problem)
        if data is None:
            out.append(missing(f"demos/results/baselines/{problem}.csv"))
            continue
        out += [f"![{problem}](results/baselines/{problem}.png)", ""]
        meshes = sorted({r["dofs"] for r in data})
        body = []
        for dofs in meshes:
            for method, theta in BASELINE_VARIANTS:
                if not _runs_of(data, method, theta):  # two bodies: no Nitsche
                    continue
                best = _equal_accuracy(_runs_of(data, method, theta, dofs), method)
                d = _default_run(data, method, theta, dofs)
                body.append(
                    [
                        dofs,
                        _variant(method, theta),
                        "not in the sweep"
                        if best is None
                        else f"{BASELINE_SYMBOL[method]} = {g(best['value'])}",
                        "–" if best is None else f"{best['ratio']:.2f}",
                        "–" if best is None else _its_outer(best),
                        "–" if d is None else f"{d['ratio']:.2f}",
                        "–"
                        if d is None or d["converged"] is not True
                        else pct(d["error"] / d["error_fb"] - 1),
                        "–" if d is None else g(d["dist_fb"]),
                        "–" if d is None or d["converged"] is not True else g(d["penetration_rel"]),
                    ]
                )
                if dofs == meshes[-1]:
                    summary.append([problem, dofs, *body[-1][1:5]])
        fb = [r for r in data if r["method"] == "fb"]
        out += [
            prose(
                "baselines",
                "observed_orders_runs_that",
                join=", ".join(
                    prose(
                        "baselines",
                        "dofs_error",
                        r_dofs=r["dofs"],
                        g_r_error=g(r["error"]),
                        g_r_seconds=g(r["seconds"]),
                        r_newton_iterations=r["newton_iterations"],
                        r_coarse_iterations=r["coarse_iterations"],
                    )
                    for r in fb
                ),
                table=table(
                    [
                        "DoFs",
                        "method",
                        "parameter for fb's accuracy",
                        "ratio then",
                        "Newton (Uzawa) its",
                        "ratio at the default",
                        "error vs fb's at the default",
                        prose("baselines", "u_u_fb_u"),
                        "penetration / max|u| at the default",
                    ],
                    body,
                ),
                join_2="; ".join(_baseline_orders(data)),
                failures=_failures(data),
            )
        ]
    out += [
        prose(
            "baselines",
            "summary_the_parameter_each",
            equal=f"{EQUAL:g}",
            table=table(
                ["problem", "DoFs", "method", "parameter", "time / fb", "Newton (Uzawa) its"],
                summary,
            ),
        )
    ]
    return "\n".join(out)


STABILITY_BASELINES = ("fb", "penalty", "augmented_lagrangian", "nitsche", "nitsche-skew")
EXPLAIN_BASELINES = {tuple(e[:3]): e[3] for e in DATA["explain_baselines"]}
#: the cases of two bodies (mortar pairs), where Nitsche refuses to run (its cells `error`)
TWO_BODY_CASES = ("(u)", "(v)")


def _refused(r: dict) -> bool:
    """Nitsche's cells of a two-body case: refused by design, not a failure."""
    return (
        r["outcome"] == "error"
        and str(r["method"]).startswith("nitsche")
        and str(r["case"]).startswith(TWO_BODY_CASES)
    )


def _explain_baseline(case: str, method: str, what: str) -> str:
    for (prefix, m, o), text in EXPLAIN_BASELINES.items():
        if case.startswith(prefix) and m in (method, "*") and o == what:
            return text
    return prose("_explain_baseline", "not_yet_explained_new")


def stability_baselines() -> str:
    runs, _, out = _open("### Stability map of the baselines", "stability_baselines", "stability")
    if not runs:
        return "\n".join(out)
    ok = [r for r in runs if r["converged"] is True]
    refused = sum(_refused(r) for r in runs)
    out += [
        prose(
            "stability_baselines",
            "configs_studies_stability_baselines",
            len_ok=len(ok),
            len_runs=len(runs),
            refusals=f"; {refused} of the others are Nitsche's refusals of two bodies"
            if refused
            else "",
        )
    ]
    by = {(r["case"], r["method"]): r for r in runs}
    cases = list(dict.fromkeys(r["case"] for r in runs))

    def span(prefix: str, method: str) -> str:
        vals = [
            by[c, method]["newton_iterations"]
            for c in cases
            if c.startswith(prefix) and (c, method) in by and by[c, method]["converged"] is True
        ]
        return (
            f"{min(vals)}–{max(vals)}"
            if vals and min(vals) != max(vals)
            else (str(vals[0]) if vals else "–")
        )

    groups = [
        ("(a)", "biactive"),
        ("(b)", "far initial guess"),
        ("(d) plain", "plain Newton"),
        ("(d) line", "backtracking"),
        ("(e)", "obtuse mesh"),
        ("(f)", "elastic Hertz"),
        ("(g)", "mesh levels 4² … 256², cold"),
        ("(h)", "friction block, Coulomb F = 0.3"),
        ("(i)", "friction cylinder"),
        ("(j)", "3D friction box"),
        ("(t)", "Tresca manufactured"),
        ("(k)", "128², CG + GAMG"),
        ("(l)", "semi-coercive"),
        ("(m)", "coefficient jump 1 : 1e6"),
        ("(n)", "ν = 0.499"),
        ("(o)", "3D Hertz, CG / GMRES + GAMG"),
        ("(u) two-body Hertz 2D", "two bodies (mortar), 2D Hertz"),
        ("(u) two-body Hertz 3D", "two bodies (mortar), 3D Hertz"),
        ("(u) two-body stack", "two blocks on a rigid floor"),
        ("(v)", "Cattaneo–Mindlin, Coulomb (4 steps)"),
    ]
    out += [
        prose(
            "stability_baselines",
            "newton_iterations_where_the",
            table=table(
                ["cases", *STABILITY_BASELINES],
                [
                    [f"{p.split()[0]} {what}", *(span(p, m) for m in STABILITY_BASELINES)]
                    for p, what in groups
                ],
            ),
        )
    ]
    # the parameter rows: iterations and accuracy against fb's in the same case
    for prefix, what, key in (
        ("(r)", "problem A at 128 × 64", "error"),
        ("(s)", "3D Hertz", "hertz_error"),
        ("(u) two-body Hertz 2D, parameter", "two-body Hertz 2D", "hertz_error"),
    ):
        rows_ = [c for c in cases if c.startswith(prefix)]
        if not rows_:
            continue
        body = []
        for c in rows_:
            fb = by.get((c, "fb"))
            line = [c.rsplit("parameter", 1)[-1].strip()]
            for m in STABILITY_BASELINES[1:]:
                r = by.get((c, m))
                if r is None:
                    line.append("–")
                elif r["converged"] is not True:
                    line.append(f"{r['outcome']}")
                else:
                    rel = (
                        abs(r[key]) / abs(fb[key])
                        if fb and fb.get(key) not in ("", None) and fb[key] != 0
                        else float("nan")
                    )
                    line.append(f"{r['newton_iterations']}, ×{rel:.3g}")
            body.append(line)
        out += [
            prose(
                "stability_baselines",
                "parameter_sweep_on",
                what=what,
                error_name="energy error"
                if key == "error"
                else "Hertz error max(|a_error|, |p0_error|)",
                table=table(["parameter", *STABILITY_BASELINES[1:]], body),
            )
        ]
    out += [prose("stability_baselines", "nitsche_s_hertz_error")]
    if any(str(c).startswith(TWO_BODY_CASES) for c in cases):
        out += [prose("stability_baselines", "two_bodies_u_and_v", refused=refused)]
    fails = [r for r in runs if r["converged"] is not True and not _refused(r)]
    if fails:
        out += [
            "Every failure in the map:",
            "",
            failure_table(fails, _explain_baseline),
            "",
        ]
    return "\n".join(out)


def time_to_accuracy_chart(data: list[dict], out: Path) -> Path:
    """time_to_accuracy.png: the energy error against the CPU seconds to reach it, one panel
    per scene, the uniform meshes and each variant of the adaptive loop."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(r["scene"] for r in data if r["run"] != "ratio"))
    colours = {name: f"C{i}" for i, name in enumerate(TTA_VARIANTS)}  # one per variant
    colours.update(TTA_UNIFORM)
    fig, axes = plt.subplots(1, len(scenes), figsize=(5.2 * len(scenes), 4.3), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        mine = [r for r in data if r["scene"] == scene and r["run"] != "ratio"]
        for run in dict.fromkeys(r["run"] for r in mine):
            rs = [r for r in mine if r["run"] == run]
            ax.plot(
                [r["cpu"] for r in rs],
                [r["error"] for r in rs],
                "s-" if run in TTA_UNIFORM else "o-",
                ms=3,
                color=colours.get(run, "grey"),
                label=run,
            )
        ratio = next((r for r in data if r["scene"] == scene and r["run"] == "ratio"), None)
        if ratio is not None:
            ax.axhline(ratio["target"], color="grey", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("CPU seconds to reach it (cumulative)")
        ax.set_ylabel("energy error")
        ax.set_title(scene)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


#: what each variant of bench_time_to_accuracy.py is (its --variant name)
TTA_VARIANTS = {
    "adaptive": "`adapt.growth=2` (Dörfler θ = 0.5, equilibrated estimator)",
    "dorfler": "`adapt.growth=1` (Dörfler's set alone, the default)",
    "rt0": "`estimator=equilibrated_rt0` (growth 2)",
    "g4rt0": "`adapt.growth=4 estimator=equilibrated_rt0`",
    "residual": "`estimator=residual` (growth 2)",
    "indicators": "`adapt.indicators=residual` (growth 2: the residual indicators mark, the "
    "equilibrated bound is computed on the level that reaches the target only, and charged to it)",
    "indicators_g1": "`adapt.indicators=residual` (growth 1)",
    "p2": "`mesh.degree=2 adapt.growth=2` (h-adaptive P2)",
    "hp": "`adapt.strategy=hp adapt.p_max=6 adapt.theta=0.85` (hp, degrees 1 … 6)",
}
#: the variants of bench_time_to_accuracy.py of a degree above 1
TTA_HIGHER = ("p2", "hp")
#: the uniform references of bench_time_to_accuracy.py in words
TTA_UNIFORM_NAMES = {"uniform": "uniform P1", "uniform_p2": "uniform P2"}
#: the uniform references of bench_time_to_accuracy.py (its --uniform names) and their
#: colours in the chart
TTA_UNIFORM = {"uniform": "black", "uniform_p2": "dimgrey"}


def _tta_reference(ratio: dict) -> str:
    """The uniform reference of a ratio row (CSVs from before the P2 reference: P1)."""
    return ratio.get("reference") or "uniform"


def _tta_speedups(ratio: dict | None) -> str:
    """A variant's CPU speed-up at the target against uniform P1 and against the fastest
    uniform reference (its name), "—" where the CSV has none."""
    if ratio is None or not ratio.get("speedup_cpu"):
        return "—"
    text = f"{ratio['speedup_cpu']:.2f}×"
    if ratio.get("best_reference") and ratio["best_reference"] != "uniform":
        text += f" / {ratio['speedup_vs_best_cpu']:.2f}× ({ratio['best_reference']})"
    return text


def _tta_higher_order(ratios: list[dict]) -> list[str]:
    """The verdict on problem A and the L-shape with degree > 1: per scene the fastest of
    the variants ``p2`` and ``hp`` against uniform P1 and against the fastest uniform
    reference (an empty list if the CSV has neither)."""
    found = []
    for scene in ("A", "lshape"):
        mine = [
            r
            for r in ratios
            if r["scene"] == scene
            and r["variant"] in TTA_HIGHER
            and _tta_reference(r) == "uniform"
            and r.get("speedup_cpu")
        ]
        if mine:
            found.append(max(mine, key=lambda r: r["speedup_cpu"]))
    if not found:
        return []
    # the fastest P1 variant's speed-up per scene
    p1 = {
        r["scene"]: max(
            (
                q["speedup_cpu"]
                for q in ratios
                if q["scene"] == r["scene"]
                and _tta_reference(q) == "uniform"
                and q["variant"] not in TTA_HIGHER
                and q.get("speedup_cpu")
            ),
            default=None,
        )
        for r in found
    }
    return [
        "",
        prose(
            "time_to_accuracy",
            "higher_order",
            rows="; ".join(
                f"{r['scene']} to {r['target']:.0e}: `{r['variant']}` "
                f"{r['speedup_cpu']:.1f}× faster than uniform P1"
                + (" (extrapolated)" if r.get("extrapolated_cpu") else "")
                + (
                    f", {r['speedup_vs_best_cpu']:.2f}× the fastest uniform run "
                    f"({r['best_reference']})"
                    if r.get("best_reference") not in (None, "uniform")
                    else ""
                )
                + (
                    f"; the fastest P1 variant {p1[r['scene']]:.2f}×"
                    if p1[r["scene"]] is not None
                    else ""
                )
                for r in found
            ),
        ),
        *_tta_recommendation(found, p1),
    ]


def _tta_recommendation(found: list[dict], p1: dict[str, float | None]) -> list[str]:
    """The recommendation for problem A: the fastest of p2 and hp where it is at least 5×
    faster than uniform P1 at the target, with its speed-up against the fastest uniform
    run; else the sentence that no variant is."""
    a = next((r for r in found if r["scene"] == "A"), None)
    if a is None:
        return []
    if a["speedup_cpu"] < 5:
        return [prose("time_to_accuracy", "no_fivefold_a", speedup=f"{a['speedup_cpu']:.1f}")]
    vs_best = a.get("speedup_vs_best_cpu") or a["speedup_cpu"]
    return [
        prose(
            "time_to_accuracy",
            "recommend_a",
            variant=a["variant"],
            how=TTA_VARIANTS[a["variant"]],
            speedup=f"{a['speedup_cpu']:.1f}",
            target=f"{a['target']:.0e}",
            p1="–" if p1["A"] is None else f"{p1['A']:.2f}×",
            best=a.get("best_reference") or "uniform",
            vs_best=f"{vs_best:.2f}",
        )
    ]


def _tta_last_level() -> str:
    """The cost of the last level of the ex9 loop with residual indicators (growth 2), from
    demos/results/adaptive_cost/profile_ex9_res2.csv: its estimate (the residual indicators
    and the guaranteed bound) against its nested solve and its assembly."""
    data = rows(RES / "adaptive_cost" / "profile_ex9_res2.csv")
    if not data:
        return "demos/results/adaptive_cost/profile_ex9_res2.csv is missing"
    last = data[-1]
    return (
        f"ex9 at {last['dofs']:,} DoFs, `python demos/bench/bench_adaptive_profile.py ex9 "
        f"--max-dofs 600000 --set adapt.growth=2 adapt.indicators=residual`: its estimate "
        f"{last['cpu_estimate']:.2f} s CPU against its nested solve's {last['cpu_solve']:.2f} s "
        f"and its assembly's {last['cpu_assembly']:.2f} s, "
        "demos/results/adaptive_cost/profile_ex9_res2.csv"
    )


#: the phases of a level whose peaks bench_adaptive_profile.py writes (peak_<phase>_mib)
PHASES = {
    "assembly": "assembly",
    "solve": "solve",
    "estimate": "estimate",
    "error": "error computation",
    "mark": "marking",
    "refine": "refinement",
}


def _tta_ex9_growth() -> list[str]:
    """ex9 to 4e-3 with the residual indicators at growth 2, 3 and 4
    (demos/results/adaptive_cost/time_to_accuracy_ex9_growth.csv) and what bounds the loop's
    time: its phases summed over the levels of a profile to 1.1M DoFs
    (demos/results/adaptive_cost/profile_ex9_res2_1M.csv) against the uniform run."""
    data = rows(RES / "adaptive_cost" / "time_to_accuracy_ex9_growth.csv")
    prof = rows(RES / "adaptive_cost" / "profile_ex9_res2_1M.csv")
    if not data or not prof:
        return [missing("demos/results/adaptive_cost/time_to_accuracy_ex9_growth.csv")]
    uni = [r for r in data if r["run"] == "uniform"]
    ratio = {
        r["variant"]: r for r in data if r["run"] == "ratio" and _tta_reference(r) == "uniform"
    }
    body, uniform_like = [], []
    runs = dict.fromkeys(r["run"] for r in data if r["run"] != "ratio")
    for run in [r for r in runs if not r.startswith("uniform")]:
        rs = [r for r in data if r["run"] == run]
        last = rs[-1]
        if [r["dofs"] for r in rs] == [r["dofs"] for r in uni[: len(rs)]]:
            uniform_like.append(f"`{run}`")  # every cell marked: the uniform meshes
        body.append(
            [
                f"`{run}`",
                len(rs),
                f"{last['dofs']:,}",
                f"{last['error']:.3e}",
                f"{last['cpu']:.1f}",
                f"{ratio[run]['first_reaching_cpu']:.2f}" if run in ratio else "not reached",
                f"{ratio[run]['interpolated_cpu']:.2f}" if run in ratio else "–",
            ]
        )
    last_dofs = max(
        (r["dofs"] for r in data if r["run"] in (u[1:-1] for u in uniform_like)), default=0
    )
    target = next(iter(ratio.values()))["target"]
    u = next(r for r in uni if r["error"] <= target)
    last, before = prof[-1], prof[-2]
    total = prof[-1]["cpu_total"]

    def summed(phase: str) -> float:
        return sum(r[f"cpu_{phase}"] for r in prof)

    floor = last["cpu_solve"] + last["cpu_assembly"] + before["cpu_refine"]
    return [
        prose(
            "time_to_accuracy",
            "ex9_growth",
            table=table(
                [
                    "variant",
                    "levels",
                    "final DoFs",
                    "error",
                    "loop CPU s",
                    "adaptive/uniform CPU (first reaching)",
                    "(interpolated)",
                ],
                body,
            ),
            uniform_dofs=f"{u['dofs']:,}",
            uniform_cpu=f"{u['cpu']:.1f}",
            dofs=f"{last['dofs']:,}",
            total=f"{total:.1f}",
            refine=f"{summed('refine'):.1f}",
            solve=f"{summed('solve'):.1f}",
            assembly=f"{summed('assembly'):.1f}",
            estimate=f"{summed('estimate'):.1f}",
            last_estimate=f"{last['cpu_estimate']:.1f}",
            last_solve=f"{last['cpu_solve']:.1f}",
            floor=f"{floor:.1f}",
            floor_share=f"{floor / u['cpu']:.2f}",
            peak=f"{last['peak_mib']:,.0f}",
            per_dof=f"{last['peak_mib'] * 2**20 / last['dofs']:,.0f}",
            peak_phase=PHASES[max(PHASES, key=lambda k: last.get(f"peak_{k}_mib") or 0.0)],
            bound_peak=f"{last['peak_bound_mib']:,.0f}" if last.get("peak_bound_mib") else "–",
            uniform_like=" and ".join(uniform_like) or "none",
            next_uniform=next(
                (f"{r['dofs']:,} DoFs, {r['error']:.2e}" for r in uni if r["dofs"] > last_dofs), "–"
            ),
        )
    ]


def _tta_ex9_certified() -> list[str]:
    """ex9 to 4e-3 at equal certification (``--uniform-bound``,
    demos/results/adaptive_cost/time_to_accuracy_ex9_certified.csv): per variant, its CPU
    seconds against uniform P1 stopped on the exact error, against uniform P1 on the mesh
    whose bound certifies the variant's η (solve and bound) and against a user who bounds
    every uniform mesh until one certifies."""
    data = rows(RES / "adaptive_cost" / "time_to_accuracy_ex9_certified.csv") or []
    ratios = [r for r in data if r["run"] == "ratio" and r.get("certified_last_cpu")]
    if not ratios:
        return [missing("demos/results/adaptive_cost/time_to_accuracy_ex9_certified.csv")]
    body = []
    for r in ratios:
        levels = [x for x in data if x["run"] == r["variant"]]
        body.append(
            [
                f"`{r['variant']}`",
                TTA_UNIFORM_NAMES.get(_tta_reference(r), _tta_reference(r)),
                len(levels),
                f"{r['adaptive_certified_dofs']:,}",
                f"{r['adaptive_certified_error']:.3e}",
                f"{r['certified_eta']:.3e}",
                f"{r['adaptive_certified_cpu']:.2f}",
                f"{r['first_reaching_cpu']:.2f} / {r['interpolated_cpu']:.2f}",
                f"{r['budget_first_reaching_cpu']:.2f} / {r['budget_interpolated_cpu']:.2f}"
                if r.get("budget_first_reaching_cpu")
                else "–",
                f"{r['uniform_certified_dofs']:,}"
                if r.get("uniform_certified_dofs")
                else "past the last mesh (s extrapolated)",
                f"{r['uniform_bound_last_cpu']:.2f}",
                f"{r['certified_last_cpu']:.2f} / {r['certified_last_interp_cpu']:.2f}",
                f"{r['uniform_bound_every_cpu']:.2f}",
                f"{r['certified_every_cpu']:.2f}",
            ]
        )
    uni = [x for x in data if x["run"] == "uniform"]
    stop = next((x for x in uni if x["error"] <= ratios[0]["target"]), uni[-1])
    return [
        prose(
            "time_to_accuracy",
            "ex9_certified",
            table=table(
                [
                    "variant",
                    "against",
                    "levels",
                    "certified DoFs",
                    "error",
                    "certified η",
                    "CPU s",
                    "/ uniform, exact stop (first / interpolated)",
                    "… on a level budget",
                    "uniform DoFs certifying η",
                    "its solve + bound CPU s",
                    "/ it (first / interpolated)",
                    "uniform bounding every mesh CPU s",
                    "/ it",
                ],
                body,
            ),
            stop_dofs=f"{stop['dofs']:,}",
            stop_error=f"{stop['error']:.3e}",
            stop_eta=f"{stop['eta']:.3e}",
            stop_cpu=f"{stop['cpu']:.2f}",
            stop_bound=f"{stop['bound_cpu']:.2f}",
            stop_verdict="does not certify the target yet"
            if stop["eta"] > ratios[0]["target"]
            else "certifies it already",
        )
    ]


def _tta_ex9_budget() -> list[str]:
    """ex9 to 4e-3 on a level budget (demos/results/adaptive_cost/
    time_to_accuracy_ex9_certified.csv, its variant without a certified level: the last
    level not estimated): the loop's wall and CPU seconds to its last level against uniform
    P1's at the exact stop."""
    data = rows(RES / "adaptive_cost" / "time_to_accuracy_ex9_certified.csv") or []
    ratio = next(
        (
            r
            for r in data
            if r["run"] == "ratio"
            and _tta_reference(r) == "uniform"
            and not r.get("certified_last_cpu")
            and any(x["run"] == r["variant"] and x.get("estimator") == "none" for x in data)
        ),
        None,
    )
    if ratio is None:
        return []
    levels = [x for x in data if x["run"] == ratio["variant"]]
    uni = [x for x in data if x["run"] == "uniform"]
    reach = next(x for x in uni if x["error"] <= ratio["error"])
    last = next(x for x in levels if x["error"] <= ratio["error"])
    return [
        prose(
            "time_to_accuracy",
            "ex9_budget",
            variant=ratio["variant"],
            levels=len(levels),
            dofs=f"{last['dofs']:,}",
            error=f"{last['error']:.3e}",
            wall=f"{last['seconds']:.2f}",
            cpu=f"{last['cpu']:.2f}",
            call_wall=f"{levels[-1]['call_seconds']:.2f}"
            if levels[-1].get("call_seconds")
            else "–",
            uni_wall=f"{reach['seconds']:.2f}",
            uni_cpu=f"{reach['cpu']:.2f}",
            uni_dofs=f"{reach['dofs']:,}",
            uni_error=f"{reach['error']:.3e}",
            ratio_wall=f"{ratio['first_reaching_seconds']:.3f}",
            ratio_cpu=f"{ratio['first_reaching_cpu']:.3f}",
            interp_wall=f"{ratio['interpolated_seconds']:.3f}",
            interp_cpu=f"{ratio['interpolated_cpu']:.3f}",
        )
    ]


def _tta_ex9_run_wall() -> list[str]:
    """``contact run`` of ex9 on a level budget against the uniform run, whole processes in
    turn (demos/bench/bench_run_wall.py, demos/results/adaptive_cost/run_wall_ex9.csv)."""
    data = rows(RES / "adaptive_cost" / "run_wall_ex9.csv") or []
    m = next((r for r in data if r["run"] == "median"), None)
    if m is None:
        return [missing("demos/results/adaptive_cost/run_wall_ex9.csv")]

    def side(name: str) -> dict[str, str]:
        """Command ``name``'s medians as the paragraph writes them."""
        return {
            "wall": f"{m[f'{name}_wall']:.2f}",
            "cpu": f"{m[f'{name}_cpu']:.2f}",
            "peak": f"{m[f'{name}_peak_mib']:,.0f}",
            "per_dof": f"{m[f'{name}_peak_b_per_dof']:,}",
            "dofs": f"{m[f'{name}_dofs']:,}",
            "error": f"{m[f'{name}_error']:.3e}",
        }

    a, b = side("A"), side("B")
    return [
        prose(
            "time_to_accuracy",
            "ex9_run_wall",
            pairs=m["pairs"],
            a_sets=m["a_sets"],
            b_sets=m["b_sets"],
            a_wall=a["wall"],
            a_cpu=a["cpu"],
            a_peak=a["peak"],
            a_per_dof=a["per_dof"],
            a_dofs=a["dofs"],
            a_error=a["error"],
            b_wall=b["wall"],
            b_cpu=b["cpu"],
            b_peak=b["peak"],
            b_per_dof=b["per_dof"],
            b_dofs=b["dofs"],
            b_error=b["error"],
            ratio_wall=f"{m['ratio_wall']:.3f}",
            ratio_min=f"{m['ratio_wall_min']:.3f}",
            ratio_max=f"{m['ratio_wall_max']:.3f}",
            ratio_cpu=f"{m['ratio_cpu']:.3f}",
            ratio_peak=f"{m['ratio_peak_mib']:.2f}",
        )
    ]


def time_to_accuracy() -> str:
    """Section 14: the adaptive loop against uniform meshes at equal error
    (demos/bench/bench_time_to_accuracy.py, with its chart), the loop's memory with earlier
    levels kept or released (demos/bench/bench_adaptive_profile.py), and start-up
    (demos/bench/bench_startup.py)."""
    out = [prose("time_to_accuracy", "time_to_accuracy_the")]
    data = rows(RES / "time_to_accuracy.csv")
    if not data:
        out.append(missing("demos/results/time_to_accuracy.csv"))
    else:
        time_to_accuracy_chart(data, RES / "time_to_accuracy.png")
        out += [prose("time_to_accuracy", "python_demos_bench_bench")]
        every_ratio = [r for r in data if r["run"] == "ratio"]
        # the tables' ratios and the summary's: against uniform P1; the speed-ups against
        # the fastest uniform reference are a column of their own
        ratios = [r for r in every_ratio if _tta_reference(r) == "uniform"]
        for scene in dict.fromkeys(r["scene"] for r in ratios):
            mine = [r for r in data if r["scene"] == scene and r["run"] != "ratio"]
            theirs = [r for r in ratios if r["scene"] == scene]
            body = []
            for run in dict.fromkeys(r["run"] for r in mine):
                rs = [r for r in mine if r["run"] == run]
                ratio = next((r for r in theirs if r["variant"] == run), None)
                extrapolated = None if ratio is None else ratio.get("extrapolated_cpu") or None
                body.append(
                    [
                        run,
                        len(rs),
                        rs[-1]["dofs"],
                        f"{rs[-1]['error']:.3e}",
                        f"{rs[-1]['cpu']:.2f}",
                        "—"
                        if ratio is None
                        else f"{ratio['first_reaching_cpu']:.2f} / {ratio['interpolated_cpu']:.2f}"
                        + (
                            f" (at {ratio['error']:.2e})"
                            if ratio["error"] != theirs[0]["error"]
                            else ""
                        ),
                        "—"
                        if extrapolated is None
                        else f"{extrapolated:.4f} ({1 / extrapolated:.0f}× faster)",
                        _tta_speedups(ratio),
                    ]
                )
            target, error = theirs[0]["target"], theirs[0]["error"]
            out += [
                prose(
                    "time_to_accuracy",
                    "scene_table",
                    scene=scene,
                    target=f"{target:.1e}",
                    short=""
                    if error == target
                    else prose("time_to_accuracy", "short_of_target", error=f"{error:.2e}"),
                    table=table(
                        [
                            "run",
                            "levels / meshes",
                            "last DoFs",
                            "last error",
                            "CPU s to it",
                            "adaptive / uniform CPU (first reaching / interpolated)",
                            "at the target, extrapolated",
                            "speed-up at the target: × uniform P1 / × fastest uniform",
                        ],
                        body,
                    ),
                )
            ]

        def ratio_of(scene: str, variant: str) -> float | None:
            found = [
                r["interpolated_cpu"]
                for r in ratios
                if (r["scene"], r["variant"]) == (scene, variant) and r["error"] == r["target"]
            ]
            return found[0] if found else None

        smooth = [
            f"{scene} {ratio_of(scene, 'dorfler'):.2f} → {ratio_of(scene, 'adaptive'):.2f}"
            for scene in ("ex9", "A")
            if ratio_of(scene, "dorfler") is not None and ratio_of(scene, "adaptive") is not None
        ]
        # the summary is of the P1 loop; degree 2 and hp have their own paragraph
        p1_ratios = [r for r in ratios if r["variant"] not in TTA_HIGHER]
        fastest = [
            min(
                (r["interpolated_cpu"], r["variant"], scene)
                for r in p1_ratios
                if r["scene"] == scene and r["error"] == r["target"]
            )
            for scene in ("ex9", "A")
            if any(r["scene"] == scene and r["error"] == r["target"] for r in p1_ratios)
        ]
        singular = [r for r in p1_ratios if r["scene"] == "lshape" and r.get("extrapolated_cpu")]
        speedups = sorted(1 / r["extrapolated_cpu"] for r in singular)
        out += [
            prose(
                "time_to_accuracy",
                "honest_summary",
                smooth=", ".join(smooth) or "—",
                fastest=", ".join(f"{scene} {v:.2f} (`{name}`)" for v, name, scene in fastest),
                cheap=", ".join(
                    f"{scene} {ratio_of(scene, 'indicators'):.2f}"
                    for scene in ("ex9", "A")
                    if ratio_of(scene, "indicators") is not None
                )
                or "—",
                last_level=_tta_last_level(),
                singular=""
                if not singular
                else prose(
                    "time_to_accuracy",
                    "singular_clause",
                    seconds=f"{singular[0]['uniform_extrapolated_cpu']:.0f}",
                    speedups=f"{speedups[0]:.0f}× to {speedups[-1]:.0f}×",
                ),
            ),
            *_tta_higher_order(every_ratio),
            prose(
                "time_to_accuracy",
                "variants_line",
                variants="; ".join(
                    f"`{k}` {v}"
                    for k, v in TTA_VARIANTS.items()
                    if any(r.get("variant") == k for r in ratios)
                ),
            ),
        ]
        out += _tta_ex9_growth()
        out += _tta_ex9_certified()
        out += _tta_ex9_budget()
        out += _tta_ex9_run_wall()
    keep = {
        mode: rows(RES / "adaptive_cost" / f"profile_ex9_keep_{mode}.csv")
        for mode in ("all", "last_notrim", "last")
    }
    if all(keep.values()):
        a, n, b = (keep[m][-1] for m in ("all", "last_notrim", "last"))  # type: ignore[index]

        def per_dof(r: dict) -> str:
            return f"{r['peak_mib'] * 2**20 / r['dofs']:.0f}"

        out += [
            prose(
                "time_to_accuracy",
                "memory_of_the_adaptive",
                a_dofs=a["dofs"],
                a_rss_mib=f"{a['rss_mib']:.0f}",
                a_peak_mib=f"{a['peak_mib']:.0f}",
                per_dof_a=per_dof(a),
                a_petsc_vector=a["petsc_Vector"],
                n_rss_mib=f"{n['rss_mib']:.0f}",
                n_peak_mib=f"{n['peak_mib']:.0f}",
                per_dof_n=per_dof(n),
                n_petsc_vector=n["petsc_Vector"],
                b_rss_mib=f"{b['rss_mib']:.0f}",
                b_peak_mib=f"{b['peak_mib']:.0f}",
                per_dof_b=per_dof(b),
                b_meshes=b["meshes"],
                a_meshes=a["meshes"],
                table=table(
                    [
                        "level",
                        "DoFs",
                        "solve",
                        "estimate",
                        "refine",
                        "CPU s",
                        "peak MiB (all)",
                        "(released)",
                        "(released, trimmed)",
                    ],
                    [
                        [
                            r["level"],
                            r["dofs"],
                            f"{r['cpu_solve']:.2f}",
                            f"{r['cpu_estimate']:.2f}",
                            f"{r['cpu_refine']:.2f}",
                            f"{r['cpu_level']:.2f}",
                            f"{r['peak_mib']:.0f}",
                            f"{q['peak_mib']:.0f}",
                            f"{t['peak_mib']:.0f}",
                        ]
                        for r, q, t in zip(*keep.values())  # type: ignore[arg-type]
                        if r["dofs"] >= 10_000
                    ],
                ),
            )
        ]
    grown = rows(RES / "adaptive_cost" / "profile_ex9_growth2.csv")
    if grown:
        last = grown[-1]
        phases = ("solve", "estimate", "refine", "assembly")
        out += [
            prose(
                "time_to_accuracy",
                "growth_profile",
                levels=len(grown),
                dofs=last["dofs"],
                error=f"{last['error']:.2e}",
                cpu_total=f"{last['cpu_total']:.1f}",
                cpu_level=f"{last['cpu_level']:.1f}",
                shares=", ".join(
                    f"{k} {100 * last[f'cpu_{k}'] / last['cpu_level']:.0f} %" for k in phases
                ),
                peak_mib=f"{last['peak_mib']:.0f}",
                per_dof=f"{last['peak_mib'] * 2**20 / last['dofs']:.0f}",
                meshes=last["meshes"],
            )
        ]
    start = rows(RES / "startup.csv")
    if start:
        cases = list(dict.fromkeys(r["case"] for r in start))

        def med(case: str, key: str) -> float:
            return statistics.median(r[key] for r in start if r["case"] == case)

        tiny = med("tiny run", "cpu")
        bare, floor = "tiny run, output.png=false", "libraries only"
        inline = "tiny run, pictures in-process (old)"

        out += [
            prose(
                "time_to_accuracy",
                "start_up_python_demos",
                table=table(
                    ["case", "CPU s", "wall s"],
                    [[c, f"{med(c, 'cpu'):.3f}", f"{med(c, 'wall'):.3f}"] for c in cases],
                ),
                import_seconds=f"{med('import contact', 'importtime_cumulative_s'):.3f}",
                import_self_seconds=f"{med('import contact', 'importtime_self_s'):.4f}",
                tiny_cpu=f"{tiny:.2f}",
                pictures_cpu=f"{tiny - med(bare, 'cpu'):.2f}" if bare in cases else "–",
                libraries_cpu=f"{med(floor, 'cpu'):.2f}" if floor in cases else "–",
                libraries_share=f"{100 * med(floor, 'cpu') / tiny:.0f} %"
                if floor in cases
                else "–",
                old_ratios=", ".join(
                    f"{tiny / med(c, 'cpu'):.2f} × that of the {c.split(', ', 1)[1][:-6]}"
                    for c in cases
                    if c.endswith(" (old)") and c != inline
                )
                or "–",
                process_ratios=(
                    f"{tiny / med(inline, 'cpu'):.2f} × the CPU seconds and "
                    f"{med('tiny run', 'wall') / med(inline, 'wall'):.2f} × the wall seconds"
                    if inline in cases
                    else "–"
                ),
            )
        ]
    return "\n".join(out)


def long_paths() -> str:
    """Section 16: the time and the memory of a step along a long load path written by
    `contact run` with its default outputs (demos/bench/bench_long_path.py --cli)."""
    out = [prose("long_paths", "long_load_paths_time")]
    runs = []
    for ranks in (2,):  # the acceptance run (other CSVs there: earlier runs, other modes)
        data = rows(RES / "long_path" / f"friction_block_2d_cli_np{ranks}.csv")
        if data and "step_wall_median_first" in data[0]:
            runs.append((ranks, data))
    if not runs:
        return "\n".join([*out, missing("long_path/friction_block_2d_cli_np2.csv")])
    out += [prose("long_paths", "contact_run_configs_friction")]
    body = []
    for ranks, data in runs:
        r = data[0]
        last = data[-1]
        for label, key, mean in (
            ("wall", "step_wall", "seconds"),
            ("CPU", "step_cpu", "cpu_seconds"),
            ("writing files, CPU", "output_cpu", "output_cpu_seconds"),
        ):
            first, late = r[f"{mean}_per_step_first"], r[f"{mean}_per_step_last"]
            body.append(
                [
                    ranks,
                    int(last["step"]),
                    label,
                    f"{1000 * first:.0f} / {1000 * late:.0f}",
                    f"{r[f'{mean}_ratio']:.2f}",
                    f"{1000 * r[f'{key}_median_first']:.0f} / {1000 * r[f'{key}_median_last']:.0f}",
                    f"{r[f'{key}_median_ratio']:.2f}",
                    f"{1000 * r[f'{key}_min_first']:.0f} / {1000 * r[f'{key}_min_last']:.0f}",
                    f"{r[f'{key}_min_ratio']:.2f}",
                    f"{r['rss_kib_per_step']:.2f}" if label == "wall" else "",
                ]
            )
    out += [
        prose(
            "long_paths",
            "wall_seconds_count_a",
            table=table(
                [
                    "ranks",
                    "steps",
                    "seconds of a step",
                    "mean first / last (ms)",
                    "ratio",
                    "median first / last (ms)",
                    "ratio",
                    "fastest first / last (ms)",
                    "ratio",
                    "RSS KiB per step",
                ],
                body,
            ),
        )
    ]
    return "\n".join(out)


def main() -> None:
    global RES
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--results", type=Path, default=RES, help="folder of the CSVs (default demos/results)"
    )
    ap.add_argument("--out", type=Path, default=ROOT / "demos" / "RESULTS.md")
    args = ap.parse_args()
    RES = args.results.resolve()
    parts = [
        prose(
            "report",
            "sections",
            header=header(),
            newton_512=newton_512(),
            speed_accuracy_A=speed_accuracy(
                "speed_accuracy_A", "Problem A (free boundary, r^{3/2})", "error", "energy error"
            ),
            speed_accuracy_D=speed_accuracy(
                "speed_accuracy_D",
                "Problem D (L-shape corner, full contact)",
                "error",
                "energy error",
            ),
            speed_accuracy_hertz=speed_accuracy(
                "speed_accuracy_hertz",
                "2D Hertz (cylinder on a plane)",
                "hertz_error",
                "Hertz error",
                prose("report", "hertz_note"),
            ),
            stability=stability(),
            stability_scale=stability_scale(),
            iterations=iterations(),
            peers=peers(),
            hertz_methods=hertz_methods(),
            friction=friction(),
            two_bodies=two_bodies(),
            cost=cost(),
            design_measurements=design_measurements(),
            hyperelastic=hyperelastic(),
            guaranteed=guaranteed(),
            baselines=baselines(),
            stability_baselines=stability_baselines(),
            time_to_accuracy=time_to_accuracy(),
            hp_section=hp_section(),
            long_paths=long_paths(),
        )
    ]
    args.out.write_text("\n".join(parts))
    print(f"make_results: wrote {args.out}")


if __name__ == "__main__":
    main()
