"""The batch's tables: results.csv, results.md (mean and std per metric), results.png, and batch.json.

One row per scene: its status, the seconds of each step, and every number ``eval`` wrote into the scene's
eval.json (flattened to dotted names, e.g. ``novel_view.psnr``, ``novel_view.per_view.train02.ssim``), exactly as
written. Mean and standard deviation (population) are over the scenes that finished.
"""
from __future__ import annotations

import csv
import io
import math
import platform
import time
from pathlib import Path

import numpy as np

from ..atomic import atomic_file, read_json, write_json
from .runner import SceneState
from .steps import PREPARE, STEPS, Layout

MAIN_METRIC = "novel_view.psnr"
NOT_METRICS = {"frames", "resolution", "grid", "start_frame"}  # settings eval records beside its scores


def flatten_metrics(scores: dict, prefix: str = "") -> dict[str, float | None]:
    """Every number of an eval JSON by dotted name (None where eval could not compute one)."""
    out = {}
    for key, value in scores.items():
        if key in NOT_METRICS:
            continue
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten_metrics(value, f"{name}."))
        elif value is None or isinstance(value, (int, float)) and not isinstance(value, bool):
            out[name] = value
    return out


def scene_rows(states: list[SceneState], out: Path) -> tuple[list[dict], list[str]]:
    """(rows, metric names in first-seen order)."""
    rows, metrics = [], []
    for state in states:
        row = {"scene": state.job.name, "status": state.status, "error": state.error or ""}
        for step in (PREPARE, *STEPS):
            row[f"seconds.{step}"] = state.seconds.get(step)
        scores = Layout(out / "scenes" / state.job.name).eval_json
        if "eval" in state.seconds and scores.is_file():
            for name, value in flatten_metrics(read_json(scores, "eval JSON")).items():
                row[name] = value
                if name not in metrics:
                    metrics.append(name)
        rows.append(row)
    return rows, metrics


def summary(rows: list[dict], metrics: list[str]) -> dict[str, tuple[float, float, int]]:
    """Per metric: (mean, std, number of scenes) over the finished scenes that have it."""
    out = {}
    for name in metrics:
        values = [r[name] for r in rows if r["status"] == "ok" and r.get(name) is not None]
        if values:
            out[name] = (float(np.mean(values)), float(np.std(values)), len(values))
    return out


def write_results(states: list[SceneState], out: Path) -> dict:
    """Write results.csv, results.md and results.png into ``out``; return the summary per metric."""
    rows, metrics = scene_rows(states, out)
    steps = [f"seconds.{s}" for s in (PREPARE, *STEPS) if any(r[f"seconds.{s}"] is not None for r in rows)]
    columns = ["scene", "status", "error", *steps, *metrics]
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow(["" if row.get(c) is None else repr(row[c]) if isinstance(row.get(c), float) else row[c]
                         for c in columns])
    with atomic_file(out / "results.csv") as tmp:
        tmp.write_text(text.getvalue())
    stats = summary(rows, metrics)
    with atomic_file(out / "results.md") as tmp:
        tmp.write_text(_markdown(rows, columns, stats))
    _chart(rows, out / "results.png")
    return stats


def _cell(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.4g}" if abs(value) < 1e-3 or abs(value) >= 1e5 else f"{value:.4f}".rstrip("0").rstrip(".")
    return str(value).replace("|", "\\|")


def _markdown(rows: list[dict], columns: list[str], stats: dict) -> str:
    ok = sum(r["status"] == "ok" for r in rows)
    lines = [f"# Batch results\n\n{len(rows)} scenes: {ok} finished, {len(rows) - ok} not "
             f"(main metric: {MAIN_METRIC}, chart in results.png).\n",
             "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(_cell(r.get(c)) for c in columns) + " |" for r in rows]
    if stats:
        lines += ["", "## Over the finished scenes", "", "| metric | mean | std | scenes |", "|---|---|---|---|"]
        lines += [f"| {name} | {_cell(m)} | {_cell(s)} | {n} |" for name, (m, s, n) in stats.items()]
    return "\n".join(lines) + "\n"


def _chart(rows: list[dict], dest: Path) -> None:
    """A bar per scene of the main metric (failed scenes and scenes without eval get no bar, but a label)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [r["scene"] for r in rows]
    values = [r.get(MAIN_METRIC) if r["status"] == "ok" and r.get(MAIN_METRIC) is not None else math.nan
              for r in rows]
    fig, ax = plt.subplots(figsize=(max(4.0, 0.6 * len(rows) + 2), 3.5))
    ax.bar(range(len(rows)), [0 if math.isnan(v) else v for v in values],
           color=["#888888" if math.isnan(v) else "#3b6ea8" for v in values])
    ax.set_xticks(range(len(rows)), [n + ("" if not math.isnan(v) else "\n(no score)") for n, v in
                                     zip(names, values)], rotation=45 if len(rows) > 8 else 0, ha="right"
                  if len(rows) > 8 else "center", fontsize=8)
    ax.set_ylabel(f"{MAIN_METRIC} [dB]")
    finite = [v for v in values if not math.isnan(v)]
    if finite:
        ax.axhline(float(np.mean(finite)), color="#c0504d", lw=1, label=f"mean {np.mean(finite):.2f} dB")
        ax.legend(fontsize=8)
    fig.tight_layout()
    with atomic_file(dest) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)


def write_record(out: Path, manifest, cluster: dict, options: dict, states: list[SceneState], started: float,
                 stats: dict) -> None:
    """batch.json: the manifest, the versions, the Ray cluster, the options, each scene's outcome."""
    write_json(out / "batch.json", {
        "manifest": {"path": str(manifest.path), "content": manifest.data,
                     "scenes": [s.to_dict() for s in manifest.scenes]},
        "versions": versions(), "cluster": cluster, "options": options,
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(started)),
        "elapsed_s": round(time.time() - started, 3),
        "scenes": {s.job.name: {"status": s.status, "error": s.error, "seconds": s.seconds,
                                "skipped": s.skipped} for s in states},
        "summary": {k: {"mean": m, "std": sd, "scenes": n} for k, (m, sd, n) in stats.items()},
    })


def versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    out = {"python": platform.python_version(), "platform": platform.platform()}
    for name in ("fluidnexus", "ray", "taichi", "torch", "numpy"):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = None
    return out

