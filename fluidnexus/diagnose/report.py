"""Outputs of diagnose: report.json (fixed keys), report.md (plain language), plots (PNG), model.json."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fluidnexus.atomic import write_json

from .observe import observables
from .plots import line_plot
from .search import MAX_P_VALUE, MIN_RELATIVE_GAIN, SPREAD_TOLERANCE

MODEL_FORMAT = "fluidnexus-model/1"


def _jsonable(params: dict) -> dict:
    out = {}
    for k, v in params.items():
        v = np.asarray(v, float)
        out[k] = [float(x) for x in v] if v.ndim else (float(v) if np.isfinite(v) else None)
    return out


def model_dict(fit, setup) -> dict:
    """model.json: the engine model (``ModelConfig.to_dict``), the appearance and source extensions."""
    p = fit.params
    return {"format": MODEL_FORMAT, "model": p.model().to_dict(), "solver": setup.solver.to_dict(),
            "source": {"center": list(setup.source_center), "radius": setup.source_radius,
                       "spacing": setup.spacing, "swirl_omega": float(p.ext("swirl", "omega"))},
            "appearance": {"gain": p.gain, "dissipation_rate": float(p.ext("dissipation", "rate"))},
            "extensions": {k: _jsonable(v) for k, v in p.extensions.items()}}


def write_outputs(out_dir: Path, observed, base, fits: dict, judged: dict, finding: str, train, validate,
                  fitter, spread: tuple[int, float], seconds: float) -> dict:
    out_dir.mkdir(parents=True, exist_ok=True)
    a = train[0]
    va = np.arange(validate[0] - a, validate[1] - a)
    chosen = fits[finding] if finding != "none" else base
    candidates = [{"effect": n, "params": _jsonable(fits[n].params.extensions[n]),
                   "validate_before": judged[n].before, "validate_after": judged[n].after,
                   "selected": n == finding} for n in fits]
    b_err = float(base.errors[va].mean())
    report = {"finding": {"effect": finding,
                          "params": _jsonable(chosen.params.extensions[finding]) if finding != "none" else {},
                          "gain": {"metric": "validation_image_error", "before": b_err,
                                   "after": float(chosen.errors[va].mean())}},
              "candidates": candidates,
              "windows": {"train": list(train), "validate": list(validate)},
              "views": list(observed.names)}
    write_json(out_dir / "report.json", report)
    write_json(out_dir / "model.json", model_dict(chosen, fitter.sim.setup))
    plots = _plots(out_dir, observed, base, chosen, finding, train, validate)
    text = _markdown(report, observed, base, fits, judged, finding, va, plots, fitter, spread, seconds)
    (out_dir / "report.md").write_text(text)
    return report


def _plots(out_dir, observed, base, chosen, finding, train, validate) -> dict:
    cams, fps = observed.cameras, observed.fps
    o, s0, s1 = (observables(x, cams, fps) for x in (observed.images, base.images, chosen.images))
    frames = np.arange(observed.first, observed.first + observed.images.shape[1])
    label = "extended model" if finding != "none" else "base model"
    runs = {"observed": o, "base model": s0}
    if finding != "none":
        runs[label] = s1
    marks = (train[1], validate[0])
    items = {
        "centroid_height.png": ("centroid height y [m]", lambda q: q.centroid[:, 1]),
        "centroid_x.png": ("centroid lateral x [m]", lambda q: q.centroid[:, 0]),
        "centroid_z.png": ("centroid lateral z [m]", lambda q: q.centroid[:, 2]),
        "rise_speed.png": ("rise speed of the front [m/s]", lambda q: q.rise_speed),
        "width.png": ("width (horizontal std) [m]", lambda q: q.width),
        "intensity.png": ("visible intensity (total smoke)", lambda q: q.intensity),
        "rotation.png": ("rotation signature: principal-axis tilt [deg]", lambda q: q.tilt),
    }
    written = {}
    for fname, (title, get) in items.items():
        line_plot(out_dir / fname, title, frames, {k: get(q) for k, q in runs.items()}, "frame", "", marks)
        written[fname] = title
    line_plot(out_dir / "width_vs_height.png", "width [m] versus front height [m] (x axis: height x 100)",
              o.front * 100, {"observed": o.width}, "front height [cm]", "width")
    errs = {"base model": base.errors}
    if finding != "none":
        errs[label] = chosen.errors
    line_plot(out_dir / "image_error.png", "image error per frame (relative)", frames, errs, "frame", "", marks)
    written["image_error.png"] = "image error per frame"
    written["width_vs_height.png"] = "width versus height (observed)"
    return {"observed": o, "base": s0, "chosen": s1, "files": written}


def _markdown(report, observed, base, fits, judged, finding, va, plots, fitter, spread, seconds) -> str:
    o, s0, s1 = plots["observed"], plots["base"], plots["chosen"]
    last = observed.first + observed.images.shape[1] - 1
    dx = o.centroid[-1] - s0.centroid[-1]
    di = (s0.intensity[-1] - o.intensity[-1]) / max(o.intensity[-1], 1e-12)
    lines = ["# diagnose report", "",
             f"Views used ({len(observed.names)}): {', '.join(observed.names)}. Training frames "
             f"{report['windows']['train'][0]}:{report['windows']['train'][1]}, validation frames "
             f"{report['windows']['validate'][0]}:{report['windows']['validate'][1]} (half-open). "
             f"{fitter.evaluations} rollouts, {seconds:.0f} s.", "",
             "## What the base model gets wrong", "",
             f"Base model (buoyancy alpha {base.params.alpha:.3g}, drag k {base.params.k:.2f} 1/s, source "
             f"{base.params.layers:.1f} layers/s) fitted on the "
             f"training frames. By frame {last} the real plume's centroid is "
             f"{100 * dx[0]:+.1f} cm in x, {100 * dx[1]:+.1f} cm in y and {100 * dx[2]:+.1f} cm in z from the "
             f"simulated one; the simulated plume shows {abs(100 * di):.0f} % {'more' if di > 0 else 'less'} "
             f"smoke than the real one; front height real {o.front[-1]:.3f} m, simulated {s0.front[-1]:.3f} m; "
             f"width real {o.width[-1]:.3f} m, simulated {s0.width[-1]:.3f} m.", ""]
    g = report["finding"]["gain"]
    if finding == "none":
        lines += ["## Finding: none", "",
                  "No candidate extension lowers the validation image error clearly beyond the noise "
                  f"(test: relative gain >= {100 * MIN_RELATIVE_GAIN:.0f} % and one-sided Wilcoxon signed-rank "
                  f"p < {MAX_P_VALUE} over the "
                  f"{len(va)} validation frames).", ""]
    else:
        params = ", ".join(f"{k} = {v}" for k, v in report["finding"]["params"].items())
        lines += [f"## Finding: {finding}", "",
                  f"The extension `{finding}` ({params}) explains it: refitted on the training frames, it cuts "
                  f"the validation image error from {g['before']:.4f} to {g['after']:.4f} "
                  f"({100 * judged[finding].relative_gain:.0f} % lower, paired Wilcoxon p = "
                  f"{judged[finding].p_value:.2g}). With it, the centroid at frame {last} is "
                  f"{100 * (o.centroid[-1] - s1.centroid[-1])[0]:+.1f} / "
                  f"{100 * (o.centroid[-1] - s1.centroid[-1])[1]:+.1f} / "
                  f"{100 * (o.centroid[-1] - s1.centroid[-1])[2]:+.1f} cm (x / y / z) from the real one.", ""]
    lines += ["## Candidates (judged on the validation frames only)", "",
              "| effect | fitted parameters | training error before | after | validation error before | after | "
              "gain | p | selected |", "|---|---|---|---|---|---|---|---|---|"]
    t0 = fitter.train_error(base)
    for c in report["candidates"]:
        j = judged[c["effect"]]
        lines.append(f"| {c['effect']} | {c['params']} | {t0:.4f} | {fitter.train_error(fits[c['effect']]):.4f} | "
                     f"{j.before:.4f} | {j.after:.4f} | {100 * j.relative_gain:.1f} % | {j.p_value:.2g} | "
                     f"{'yes' if c['selected'] else 'no'} |")
    same = (f"the best of them has a validation error {100 * spread[1]:.1f} % below the control's. A candidate's "
            "gain of that size could come from where its search stopped rather than from its term; read such a "
            "finding with care." if spread[1] > 0 else "none of them has a lower validation error than the control.")
    lines += ["", f"How far the training frames pin the base model: {spread[0]} fits of the base model alone "
              f"(no extension, from the base and control searches) come within {100 * SPREAD_TOLERANCE:.0f} % of "
              f"the control's training error; {same}"]
    lines += ["", f"Metric: {report['finding']['gain']['metric']} = the {_METRIC_TEXT}.", "", "## Plots", ""]
    lines += [f"- {title}: ![{title}]({name})" for name, title in plots["files"].items()]
    return "\n".join(lines) + "\n"


_METRIC_TEXT = "mean over validation frames and views of the squared difference between real and simulated " \
               "low-resolution images, relative to the mean squared real intensity (1.0 = predicting no smoke)"
