"""The charts of a parameter study (matplotlib, PNG), drawn from its rows (the pictures of
one run are :mod:`.plots`).

* :func:`speed_accuracy` — accuracy against wall time and against DoFs, one curve per
  combination of the study's non-numeric axes (and case); the points of a curve are the
  levels of an adaptive run, or the runs along a numeric axis such as ``level``.  The
  Pareto front (points no other point beats in both time and accuracy) is circled.
* :func:`stability` — the stability map: cases (or combinations of the other axes) ×
  methods, each cell coloured by the run's outcome and labelled with its Newton iterations.
* :func:`iterations` — linear solves against the refinement level, one colour per
  method, solid for nested iteration and dashed for cold starts (adaptive runs from u0 on
  every level, or single solves along a ``level`` axis).

Every function has the signature ``(path, study, rows, level_rows)`` (see :data:`DRAW`)
and is called on one rank.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from ..solvers import solves_text
from .figures import new_figure, save_figure


class Study(Protocol):
    """What the charts read of a study (``contact.app.study.Study`` is one): its name, axes
    (axis -> values), adaptive options, whether its cases are named, the accuracy column,
    and the plan of a run (its raw scene, uniform refinements and adaptive options)."""

    name: str
    axes: dict[str, list]
    adapt: dict[str, Any]

    @property
    def named_cases(self) -> bool: ...

    @property
    def accuracy(self) -> str: ...

    def plan(self, params: Mapping[str, Any]) -> tuple[dict, int, dict | None]: ...


ACCURACY_LABELS = {
    "error": "energy error ‖u − u_h‖_E",
    "hertz_error": "Hertz error max(|a/a_H − 1|, |p0/p0_H − 1|)",
    "eta": "estimator η",
}
#: outcome classes of a run, in the order of the stability map's legend
OUTCOMES = ("converged", "max iterations", "stalled", "diverged", "error")
#: classes of converged hyperelastic runs whose answer is no stable state (study.outcome)
STATE_OUTCOMES = ("unstable", "inverted")
OUTCOME_COLOURS = {
    "converged": "#4daf4a",
    "max iterations": "#ff7f00",
    "stalled": "#ffd92f",
    "diverged": "#e41a1c",
    "error": "#999999",
    "unstable": "#80b1d3",
    "inverted": "#984ea3",
}
MARKERS = "osD^v<>pPX*h"


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _categorical(study: Study) -> list[str]:
    """The axes whose values label curves (not numbers), with ``case`` first."""
    names = [a for a, vals in study.axes.items() if not all(_is_number(v) for v in vals)]
    return (["case"] if study.named_cases else []) + names


def _numeric(study: Study) -> list[str]:
    return [a for a, vals in study.axes.items() if all(_is_number(v) for v in vals)]


def _groups(rows: Iterable[dict], keys: list[str]) -> dict[tuple, list[dict]]:
    out: dict[tuple, list[dict]] = {}
    for r in rows:
        out.setdefault(tuple(r[k] for k in keys), []).append(r)
    return out


def _label(keys: list[str], values: tuple) -> str:
    return ", ".join(str(v) if k == "case" else f"{k}={v}" for k, v in zip(keys, values)) or "runs"


def _encodings(study: Study, cat: list[str]):
    """Colour by method (when ``method`` is an axis), line style and marker by the
    combination of the other non-numeric axes; otherwise colour by the whole combination."""
    styles = [("-", "o"), ("--", "s"), (":", "^"), ("-.", "D"), ("-", "v"), ("--", "P"), (":", "X")]
    if "method" in cat:
        k = cat.index("method")
        methods = list(study.axes["method"])
        others: list[tuple] = []

        def colour_of(gkey: tuple) -> str:
            return f"C{methods.index(gkey[k]) % 10}"

        def style_of(gkey: tuple) -> tuple[str, str]:
            rest = gkey[:k] + gkey[k + 1 :]
            if rest not in others:
                others.append(rest)
            return styles[others.index(rest) % len(styles)]

        return colour_of, style_of
    seen: list[tuple] = []

    def index(gkey: tuple) -> int:
        if gkey not in seen:
            seen.append(gkey)
        return seen.index(gkey)

    return (lambda g: f"C{index(g) % 10}"), (lambda g: ("-", MARKERS[index(g) % len(MARKERS)]))


def speed_accuracy(
    path: str | Path, study: Study, rows: list[dict], level_rows: list[dict]
) -> None:
    """Accuracy (``study.accuracy``) against wall time (left) and DoFs (right), log–log."""
    key = study.accuracy
    good = [
        r
        for r in level_rows
        if r["converged"] and r.get(key, "") != "" and float(r[key]) > 0 and float(r["seconds"]) > 0
    ]
    cat, num = _categorical(study), _numeric(study)
    colour_of, style_of = _encodings(study, cat)
    fig, (ax_t, ax_n) = new_figure(1, 2, figsize=(13, 6.5), sharey=True)
    for gkey, members in _groups(good, cat).items():
        members.sort(key=lambda r: (tuple(r[a] for a in num), r["run"], r["level"]))
        ls, marker = style_of(gkey)
        style = dict(
            marker=marker,
            color=colour_of(gkey),
            lw=1.1,
            ms=5,
            ls=ls if len(members) > 1 else "none",
        )
        for ax, x in ((ax_t, "seconds"), (ax_n, "dofs")):
            # one polyline per run (levels) or along the numeric axes (single solves)
            runs = _groups(members, ["run"]) if any(r["level"] for r in members) else {(): members}
            for j, part in enumerate(runs.values()):
                ax.loglog(
                    [float(r[x]) for r in part],
                    [float(r[key]) for r in part],
                    label=" / ".join(map(str, gkey)) if (ax is ax_t and j == 0) else None,
                    **style,
                )
    front = sorted((float(r["seconds"]), float(r[key])) for r in good if r.get("pareto"))
    if front:
        ft, fe = zip(*front)
        ax_t.loglog(ft, fe, "o", ms=12, mfc="none", mec="k", mew=1.2, label="Pareto front")
        ax_t.step(ft, fe, where="post", color="k", ls="--", lw=0.8)
    for ax, xlabel in ((ax_t, "wall time since the start of the run [s]"), (ax_n, "DoFs")):
        ax.set_xlabel(xlabel)
        ax.grid(True, which="both", alpha=0.3)
        if not good:
            ax.text(0.5, 0.5, "no converged run", transform=ax.transAxes, ha="center", va="center")
    ax_t.set_ylabel(ACCURACY_LABELS[key])
    failed = sum(1 for r in rows if not r["converged"])
    fig.suptitle(
        f"study {study.name}: accuracy against time and DoFs, {len(rows)} runs"
        + (f" ({failed} failed, not shown)" if failed else "")
    )
    handles, labels = ax_t.get_legend_handles_labels()
    rows_of_legend = math.ceil(len(labels) / 5)
    bottom = min(0.06 + 0.035 * rows_of_legend, 0.5) if handles else 0.0
    if handles:
        fig.legend(
            handles,
            labels,
            loc="lower center",
            ncol=5,
            fontsize=8,
            frameon=False,
            title=" / ".join(cat) if cat else None,
            title_fontsize=8,
        )
    fig.tight_layout(rect=(0, bottom, 1, 1))
    save_figure(fig, path, dpi=120)


def stability(path: str | Path, study: Study, rows: list[dict], level_rows: list[dict]) -> None:
    """Rows: the cases (or combinations of the axes other than ``method``); columns: the
    methods.  Colour: :func:`contact.app.study.outcome`; label: Newton iterations (summed over
    the levels of an adaptive run), ``+p`` for p active-set polishing solves."""
    from matplotlib.patches import Patch, Rectangle

    methods = study.axes.get("method", [None])
    row_keys = (["case"] if study.named_cases else []) + [a for a in study.axes if a != "method"]
    labels: list[tuple] = []
    for r in rows:
        k = tuple(r[a] for a in row_keys)
        if k not in labels:
            labels.append(k)
    cells = {(tuple(r[a] for a in row_keys), r.get("method")): r for r in rows if r["repeat"] == 1}
    fig, ax = new_figure(figsize=(1.6 * len(methods) + 4.5, 0.42 * len(labels) + 1.8))
    for i, lk in enumerate(labels):
        for j, m in enumerate(methods):
            cell = cells.get((lk, m))
            what = cell["outcome"] if cell else "error"
            ax.add_patch(
                Rectangle((j, i), 1, 1, facecolor=OUTCOME_COLOURS[what], edgecolor="white", lw=2)
            )
            text = "—" if cell is None else _solves_label(cell)
            ax.text(j + 0.5, i + 0.5, text, ha="center", va="center", fontsize=9)
    ax.set_xlim(0, len(methods))
    ax.set_ylim(len(labels), 0)
    ax.set_xticks(np.arange(len(methods)) + 0.5, [str(m) for m in methods])
    ax.xaxis.tick_top()
    ax.set_yticks(np.arange(len(labels)) + 0.5, [_label(row_keys, lk) for lk in labels], fontsize=8)
    ax.tick_params(length=0)
    for side in ax.spines.values():
        side.set_visible(False)
    shown = [*OUTCOMES, *(o for o in STATE_OUTCOMES if any(r["outcome"] == o for r in rows))]
    ax.legend(
        handles=[Patch(color=OUTCOME_COLOURS[o], label=o) for o in shown],
        loc="upper center",
        bbox_to_anchor=(0.5, -0.01),
        ncol=len(shown),
        fontsize=8,
        frameon=False,
    )
    ax.set_title(f"study {study.name}: outcome and Newton iterations (+ polishing solves)", pad=22)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def _solves_label(r: dict) -> str:
    """'n' Newton iterations, or 'n+p' with p polishing solves; 'err' if the run raised."""
    if r["newton_iterations_total"] == "":
        return "err"
    return solves_text(r["newton_iterations_total"], int(r.get("polish_solves_total") or 0))


def _linear_solves(r: dict) -> int:
    return int(r["newton_iterations"]) + int(r.get("polish_solves") or 0)


def _iteration_curves(
    study: Study, rows: list[dict], level_rows: list[dict]
) -> dict[str, list[dict]]:
    """The curves of :func:`iterations`: label -> points ``{x, y, converged, method,
    nested, marker_key}`` sorted by x.

    x is the refinement level of the mesh solved on: the ``level`` axis value (uniform
    refinements of the base mesh) plus the level of the adaptive loop.  An adaptive run is
    one curve, nested or cold start as it was run; single solves (one per value of a
    ``level`` axis) are joined along that axis into one curve per combination of the other
    axes, each solve a cold start from u0."""
    keys = (["case"] if study.named_cases else []) + list(study.axes)
    plans = {r["run"]: study.plan({k: r[k] for k in keys if k in r}) for r in rows}
    other = [a for a in _categorical(study) if a not in ("method", "nested")]
    curves: dict[str, list[dict]] = {}
    for (run,), members in _groups(level_rows, ["run"]).items():
        r0 = members[0]
        _, base, adapt_opts = plans[run]
        adaptive = adapt_opts is not None
        nested = bool(r0.get("nested", study.adapt.get("nested", True))) if adaptive else False
        kind = ("nested" if nested else "cold start") if adaptive else "single solves (cold)"
        label = ", ".join([str(r0.get("method", "runs")), kind, *(f"{a}={r0[a]}" for a in other)])
        if adaptive and any(c.get("run") != run for c in curves.get(label, [])):
            label += f", run {run}"  # repeats of one adaptive combination stay separate curves
        for r in members:
            if r["newton_iterations"] != "":
                curves.setdefault(label, []).append(
                    {
                        "x": base + int(r["level"]),
                        "y": _linear_solves(r),
                        "run": run,
                        "converged": bool(r["converged"]),
                        "method": r0.get("method"),
                        "nested": nested,
                        "marker_key": tuple(r0[a] for a in other),
                    }
                )
    return {k: sorted(v, key=lambda p: p["x"]) for k, v in curves.items()}


def iterations(
    path: str | Path, study: Study, rows: list[dict], level_rows: list[dict]
) -> dict[str, list[dict]]:
    """Linear solves per refinement level (Newton steps + active-set polishing solves):
    colour = method, solid = nested iteration, dashed = cold start (an adaptive run from
    u0 on every level, or single solves along a ``level`` axis); other non-numeric axes
    get their own marker.  Returns the curves drawn (:func:`_iteration_curves`)."""
    from matplotlib.ticker import MaxNLocator

    methods = study.axes.get("method", [None])
    curves = _iteration_curves(study, rows, level_rows)
    combos = sorted({p["marker_key"] for pts in curves.values() for p in pts}, key=str)
    fig, ax = new_figure(figsize=(8, 5.5))
    for label, pts in curves.items():
        m = methods.index(pts[0]["method"]) if pts[0]["method"] in methods else 0
        marker = MARKERS[combos.index(pts[0]["marker_key"]) % len(MARKERS)]
        shift = 0.06 * (m - (len(methods) - 1) / 2)  # side by side where counts coincide
        xs = [p["x"] + shift for p in pts]
        ax.plot(
            xs,
            [p["y"] for p in pts],
            color=f"C{m % 10}",
            ls="-" if pts[0]["nested"] else "--",
            marker=marker,
            ms=5,
            lw=1.2,
            label=label,
        )
        for x, p in zip(xs, pts):
            if not p["converged"]:
                ax.plot(x, p["y"], "x", color="k", ms=9)
    levels = sorted({p["x"] for pts in curves.values() for p in pts})
    ax.set_xlabel("refinement level (uniform refinements of the base mesh + adaptive level)")
    ax.set_ylabel("linear solves on the level (Newton steps + polishing)")
    ax.set_ylim(bottom=0)
    if levels:
        ax.set_xlim(levels[0] - 0.4, levels[-1] + 0.4)
        ax.set_xticks(levels)
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", ncol=2)
    ax.set_title(f"study {study.name}: iterations per level (× = not converged)")
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    return curves


DRAW: dict[str, Callable[[Path, Any, list, list], object]] = {
    "speed_accuracy": speed_accuracy,
    "stability": stability,
    "iterations": iterations,
}
