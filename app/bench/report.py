"""Benchmark output: per suite a CSV, a Markdown table and a PNG plot; one summary with the targets.

Tables and plots are made from the rows alone (the CSV), so ``python -m app.bench --replot DIR`` can
redraw them without measuring again.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from .. import units
from . import grooms, looks
from .suites import SUITES, thesis_table_2
from .timing import Machine, crossover, fit_power_law

Row = dict[str, Any]


# --------------------------------------------------------------------------------------------------
# CSV and Markdown
# --------------------------------------------------------------------------------------------------
def write_csv(rows: list[Row], path: Path) -> None:
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in keys})


def read_csv(path: Path) -> list[Row]:
    with open(path, newline="") as f:
        return [{k: _parse(v) for k, v in r.items()} for r in csv.DictReader(f)]


def _parse(v: str) -> Any:
    if v == "":
        return None
    for kind in (int, float):
        try:
            return kind(v)
        except ValueError:
            pass
    return v


def human_bytes(n: float | None) -> str:
    if n is None or (isinstance(n, float) and math.isnan(n)):
        return ""
    return units.human_bytes(float(n))


def fmt(key: str, v: Any) -> str:
    if v is None or v == "":
        return ""
    if key in ("gpu_bytes", "rss_peak", "rss_base", "needed_bytes", "scene_gpu_bytes"):
        return human_bytes(v)
    if key in ("cv",) or key.endswith("_cv"):
        return f"{100 * float(v):.1f}%"
    if key in ("coverage_agree", "id_agree", "covered_iou", "covered"):
        return f"{100 * float(v):.2f}%"
    if key in ("fibers", "x", "containers", "fibers_per_container", "segments") and isinstance(v, (int, float)):
        return f"{int(v):,}"
    if isinstance(v, float):
        if key.endswith("ms"):
            return f"{v:,.1f}" if v >= 10 else f"{v:.2f}"
        return f"{v:,.2f}" if abs(v) >= 1 else f"{v:.3g}"
    return str(v)


def markdown_table(rows: list[Row], columns: list[tuple[str, str]]) -> str:
    cols = [(k, h) for k, h in columns if any(r.get(k) not in (None, "") for r in rows)]
    lines = ["| " + " | ".join(h for _, h in cols) + " |",
             "|" + "|".join("---:" if _numeric(rows, k) else "---" for k, _ in cols) + "|"]
    for r in rows:
        lines.append("| " + " | ".join(fmt(k, r.get(k)) for k, _ in cols) + " |")
    return "\n".join(lines)


def _numeric(rows: list[Row], key: str) -> bool:
    return any(isinstance(r.get(key), (int, float)) for r in rows)


# --------------------------------------------------------------------------------------------------
# Derived numbers: exponents, cross-over, targets
# --------------------------------------------------------------------------------------------------
def _ok(rows: Iterable[Row], **match) -> list[Row]:
    return [r for r in rows if all(r.get(k) == v for k, v in match.items())
            and r.get("status", "ok") == "ok" and isinstance(r.get("ms"), (int, float))]


def scaling_fits(rows: list[Row]) -> list[Row]:
    out = []
    for axis in ("resolution", "containers", "rings"):
        for method in sorted({r["method"] for r in rows if r.get("axis") == axis and r.get("method")}):
            pts = sorted(_ok(rows, axis=axis, method=method), key=lambda r: r["x"])
            if len(pts) < 2:
                continue
            b, a, r2 = fit_power_law([r["x"] for r in pts], [r["ms"] for r in pts])
            out.append({"axis": axis, "method": method, "exponent": round(b, 3), "r2": round(r2, 4),
                        "points": len(pts), "x_range": f"{pts[0]['x']:,}-{pts[-1]['x']:,}"})
    return out


def memory_crossover(rows: list[Row]) -> float | None:
    v = {r["fibers"]: r["ms"] for r in _ok(rows, method="virtual")}
    e = {r["fibers"]: r["ms"] for r in _ok(rows, method="explicit")}
    xs = sorted(set(v) & set(e))
    if len(xs) < 2:
        return None
    return crossover(xs, [e[x] for x in xs], [v[x] for x in xs])


def targets(results: dict[str, list[Row]]) -> list[Row]:
    """The issue's targets, each with what was measured and whether it is met (None: not measured)."""
    out: list[Row] = []
    mem = results.get("memory") or []
    virt = _ok(mem, method="virtual")
    if virt:
        b = [r["gpu_bytes"] for r in virt]
        lo, hi = min(virt, key=lambda r: r["fibers"]), max(virt, key=lambda r: r["fibers"])
        out.append({"target": "virtual GPU bytes flat from the fewest to the most fibers",
                    "measured": f"{human_bytes(min(b))} .. {human_bytes(max(b))} over "
                                f"{lo['fibers']:,} .. {hi['fibers']:,} fibers", "met": min(b) == max(b)})
    at = _near(mem, 10**6)
    if at:
        v, e = at
        if e.get("status") == "ok":
            ratio = e["gpu_bytes"] / v["gpu_bytes"]
            out.append({"target": ">= 100x GPU bytes, explicit over virtual, at 1M fibers",
                        "measured": f"{ratio:,.0f}x ({human_bytes(e['gpu_bytes'])} vs "
                                    f"{human_bytes(v['gpu_bytes'])}, {v['fibers']:,} fibers)",
                        "met": ratio >= 100})
            out.append({"target": "virtual at least as fast as explicit at 1M fibers",
                        "measured": f"virtual {v['ms']:,.1f} ms (fast mode {v.get('fast_ms', float('nan')):,.1f}) "
                                    f"vs explicit {e['ms']:,.1f} ms per frame",
                        "met": v["ms"] <= e["ms"]})
    x = memory_crossover(mem)
    if mem:
        out.append({"target": "cross-over fiber count (explicit frame time = virtual)",
                    "measured": f"~{x:,.0f} fibers" if x else "none inside the measured range", "met": None})
    acc = results.get("accuracy") or []
    exact = [r for r in acc if r.get("mode") == "exact" and r.get("fibers_per_container") == 3600]
    for r in exact:
        out.append({"target": f"exact >= 50x fewer fiber tests than brute, 0 px differ ({r['shape']}, 3,600 "
                              f"fibers/container)",
                    "measured": f"{r['tests_vs_brute']:,.0f}x fewer ({r['tests_per_px']:.1f} vs "
                                f"{r['tests_per_px'] * r['tests_vs_brute']:,.0f} tests/px), "
                                f"{r['differ_brute_px']} px differ",
                    "met": r["tests_vs_brute"] >= 50 and r["differ_brute_px"] == 0})
    out += grooms.targets(results.get("grooms") or [])
    out += looks.targets(results.get("looks") or [])
    return out


def _near(mem: list[Row], fibers: int) -> tuple[Row, Row] | None:
    pairs = {}
    for r in mem:
        if isinstance(r.get("fibers"), (int, float)) and r["fibers"] > 0 and abs(math.log(r["fibers"] / fibers)) < 0.05:
            pairs[r["method"]] = r
    if "virtual" in pairs and "explicit" in pairs and pairs["virtual"].get("status") == "ok":
        return pairs["virtual"], pairs["explicit"]
    return None


def targets_markdown(rows: list[Row]) -> str:
    lines = ["| target | measured | met |", "|---|---|:---:|"]
    for r in rows:
        met = {True: "yes", False: "**no**", None: "-"}[r["met"]]
        lines.append(f"| {r['target']} | {r['measured']} | {met} |")
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------------
# Plots
# --------------------------------------------------------------------------------------------------
def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


COLORS = {"virtual": "tab:blue", "virtual-exact": "tab:blue", "virtual-fast": "tab:cyan",
          "explicit": "tab:red", "brute": "tab:gray", "fast": "tab:cyan", "exact": "tab:blue"}


def plot_memory(rows: list[Row], path: Path, machine: Machine | None) -> None:
    plt = _plt()
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.6))
    for method in ("virtual", "explicit"):
        ok = sorted(_ok(rows, method=method), key=lambda r: r["fibers"])
        if ok:
            x = [r["fibers"] for r in ok]
            a.loglog(x, [r["gpu_bytes"] / 2**20 for r in ok], "o-", color=COLORS[method],
                     label=f"{method}: GPU buffers")
            a.loglog(x, [r["rss_peak"] / 2**20 for r in ok], "s--", color=COLORS[method], alpha=0.6,
                     label=f"{method}: peak RSS (process)")
            b.loglog(x, [r["ms"] for r in ok], "o-", color=COLORS[method],
                     label=f"{method}" + (" (exact mode)" if method == "virtual" else ""))
        if method == "virtual" and ok and ok[0].get("fast_ms"):
            b.loglog(x, [r["fast_ms"] for r in ok], "o:", color=COLORS["virtual-fast"], label="virtual (fast mode)")
    refused = [r for r in rows if r.get("status") == "refused"]
    if refused:
        a.loglog([r["fibers"] for r in refused], [r["needed_bytes"] / 2**20 for r in refused], "x",
                 color=COLORS["explicit"], ms=10, mew=2, label="explicit: refused (would need)")
    t2 = thesis_table_2()
    a.loglog([t[0] for t in t2], [t[1] for t in t2], "^:", color="tab:blue", alpha=0.35,
             label="thesis proposed RAM (Blender)")
    a.loglog([t[0] for t in t2 if t[3]], [t[3] for t in t2 if t[3]], "v:", color="tab:red", alpha=0.35,
             label="thesis Blender fibers RAM")
    x = memory_crossover(rows)
    if x:
        b.axvline(x, color="k", lw=0.8, ls="--")
        b.annotate(f"cross-over ~{x:,.0f}", (x, b.get_ylim()[0]), rotation=90, va="bottom", ha="right", fontsize=8)
    a.set(xlabel="fibers", ylabel="MiB", title="Memory (thesis Figure 37)")
    b.set(xlabel="fibers", ylabel="ms per frame", title="Frame time (thesis Figure 38)")
    for ax in (a, b):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    _save(fig, path, machine)


def plot_rings(rows: list[Row], path: Path, machine: Machine | None) -> None:
    plt = _plt()
    methods = [m for m in ("virtual-fast", "virtual-exact", "explicit") if any(r.get("method") == m for r in rows)]
    fig, axes = plt.subplots(1, len(methods), figsize=(4.4 * len(methods), 4.2), sharey=True, squeeze=False)
    rings = sorted({r["rings"] for r in rows if r.get("rings") is not None})
    cmap = plt.get_cmap("viridis")
    for ax, m in zip(axes[0], methods):
        for i, k in enumerate(rings):
            pts = sorted(_ok(rows, method=m, rings=k), key=lambda r: r["per_ring"])
            ax.semilogx([r["per_ring"] for r in pts], [r["ms"] for r in pts], "o-",
                        color=cmap(i / max(1, len(rings) - 1)), label=f"{k} rings")
        ax.set(xlabel="fibers per ring", title=m)
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("ms per frame")
    axes[0][0].legend(fontsize=7)
    fig.suptitle("One container: rings x fibers per ring (thesis Table 3, Figure 41)", fontsize=10)
    _save(fig, path, machine)


def plot_containers(rows: list[Row], path: Path, machine: Machine | None) -> None:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.4))
    for m in ("virtual-fast", "virtual-exact", "explicit"):
        for fill, style in (("empty", "o--"), ("full", "s-")):
            pts = sorted(_ok(rows, method=m, fill=fill), key=lambda r: r["containers"])
            if pts:
                ax.loglog([r["containers"] for r in pts], [r["ms"] for r in pts], style, color=COLORS[m],
                          label=f"{m}, {fill}")
    ax.set(xlabel="overlapping containers", ylabel="ms per frame",
           title="Overlapping containers, 10 rings, empty (2/ring) and full (360/ring) (thesis Table 4)")
    ax.title.set_fontsize(9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    _save(fig, path, machine, bottom=0.05)


def plot_accuracy(rows: list[Row], path: Path, machine: Machine | None) -> None:
    plt = _plt()
    rows = [r for r in rows if r.get("mode") and isinstance(r.get("ms"), (int, float))]
    shapes = list(dict.fromkeys(r["shape"] for r in rows))
    modes = ("fast", "exact", "brute")
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    width = 0.8 / len(modes)
    for i, m in enumerate(modes):
        pts = [next((r for r in rows if r["shape"] == s and r["mode"] == m), None) for s in shapes]
        xs = np.arange(len(shapes)) + (i - 1) * width
        a.bar(xs, [p["tests_per_px"] if p else 0 for p in pts], width, color=COLORS[m], label=m)
        b.bar(xs, [p["ms"] if p else 0 for p in pts], width, color=COLORS[m], label=m)
        for x, p in zip(xs, pts):
            if p:
                a.annotate(f"{p['differ_brute_px']} px", (x, p["tests_per_px"]), ha="center", va="bottom",
                           fontsize=7)
    for ax, label in ((a, "fiber tests per covered pixel (labels: px differing from brute)"),
                      (b, "ms per frame")):
        ax.set_yscale("log")
        ax.set_xticks(np.arange(len(shapes)), shapes)
        ax.set_title(label, fontsize=9)
        ax.grid(True, axis="y", which="both", alpha=0.3)
        ax.legend(fontsize=7)
    _save(fig, path, machine, bottom=0.05)


def plot_scaling(rows: list[Row], path: Path, machine: Machine | None) -> None:
    plt = _plt()
    fits = {(f["axis"], f["method"]): f for f in scaling_fits(rows)}
    axes_names = [a for a in ("resolution", "containers", "rings") if any(r.get("axis") == a for r in rows)]
    fig, axes = plt.subplots(1, max(1, len(axes_names)), figsize=(4.6 * len(axes_names), 4.2), squeeze=False)
    labels = {"resolution": "pixels", "containers": "visible containers", "rings": "rings (100 fibers each)"}
    for ax, axis in zip(axes[0], axes_names):
        for m in ("virtual-fast", "virtual-exact", "explicit"):
            pts = sorted(_ok(rows, axis=axis, method=m), key=lambda r: r["x"])
            if not pts:
                continue
            x = np.array([r["x"] for r in pts], float)
            f = fits.get((axis, m))
            label = m + (f" (exponent {f['exponent']:.2f})" if f else "")
            ax.loglog(x, [r["ms"] for r in pts], "o", color=COLORS[m], label=label)
            if f:
                _, a_, _ = fit_power_law(x, [r["ms"] for r in pts])
                ax.loglog(x, a_ * x ** f["exponent"], "-", color=COLORS[m], alpha=0.6)
        ax.set(xlabel=labels[axis], ylabel="ms per frame", title=f"time vs {labels[axis]}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    _save(fig, path, machine, bottom=0.05)


def plot_grooms(rows: list[Row], path: Path, machine: Machine | None) -> None:
    grooms.plot(rows, path, machine, _plt(), _save)


def plot_looks(rows: list[Row], path: Path, machine: Machine | None) -> None:
    looks.plot(rows, path, machine, _plt(), _save)


PLOTS = {"memory": plot_memory, "rings": plot_rings, "containers": plot_containers,
         "accuracy": plot_accuracy, "scaling": plot_scaling, "grooms": plot_grooms, "looks": plot_looks}


def _tidy(fig) -> None:
    """Log axes over less than a decade label their minor ticks on top of each other: drop those."""
    from matplotlib.ticker import NullFormatter

    for ax in fig.axes:
        for axis, scale in ((ax.xaxis, ax.get_xscale()), (ax.yaxis, ax.get_yscale())):
            if scale == "log":
                axis.set_minor_formatter(NullFormatter())


def _caption(fig, machine: Machine | None) -> None:
    _tidy(fig)
    if machine:
        fig.text(0.01, 0.005, f"{machine.gl_renderer}, Mesa {machine.mesa}; {machine.cpu}, "
                 f"{machine.cores_usable} cores; {machine.date}; {machine.commit[:10]}", fontsize=6.5,
                 color="0.4")


def _save(fig, path: Path, machine: Machine | None, bottom: float = 0.04) -> None:
    """Caption the figure with the machine, lay it out above the caption, write it and free it."""
    _caption(fig, machine)
    fig.tight_layout(rect=(0, bottom, 1, 1))
    fig.savefig(path, dpi=110)
    _plt().close(fig)


# --------------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------------
def write_suite(name: str, rows: list[Row], out: Path, machine: Machine | None, level: str) -> dict[str, Path]:
    suite = SUITES[name]
    paths = {"csv": out / f"{name}.csv", "md": out / f"{name}.md", "png": out / f"{name}.png"}
    write_csv(rows, paths["csv"])
    parts = [f"## {name}: {suite.title}", "", f"Thesis: {suite.thesis}. Level: {level}.", ""]
    if machine:
        parts += [machine.markdown(), ""]
    parts.append(markdown_table(rows, suite.columns))
    if name == "scaling":
        fits = scaling_fits(rows)
        parts += ["", "Fitted exponents (time ~ x^b, least squares in log-log):", "",
                  markdown_table(fits, [("axis", "axis"), ("method", "method"), ("exponent", "exponent b"),
                                        ("r2", "R^2"), ("x_range", "range")])
                  if fits else "(fewer than two points per axis: nothing to fit)"]
    if name == "grooms":
        parts += ["", grooms.NOTES, "", targets_markdown(grooms.targets(rows))]
    if name == "looks":
        parts += ["", looks.NOTES, "", targets_markdown(looks.targets(rows))]
    if name == "memory":
        x = memory_crossover(rows)
        parts += ["", "Cross-over (explicit frame time = virtual, exact mode): "
                      + (f"~{x:,.0f} fibers." if x else "none inside the measured range.")]
    paths["md"].write_text("\n".join(parts) + "\n")
    PLOTS[name](rows, paths["png"], machine)
    return paths


def write_summary(results: dict[str, list[Row]], out: Path, machine: Machine, level: str, command: str,
                  seconds: float) -> Path:
    (out / "machine.json").write_text(json.dumps(machine.as_dict(), indent=2) + "\n")
    parts = [f"# vfiber bench ({level})", "", machine.markdown(), f"- command: `{command}`",
             f"- wall clock: {seconds / 60:.1f} min", "", "## Targets", "", targets_markdown(targets(results)), ""]
    for name in results:
        parts += [f"- [{name}]({name}.md): {SUITES[name].title} -- {name}.csv, {name}.png"]
    path = out / "summary.md"
    path.write_text("\n".join(parts) + "\n")
    return path
