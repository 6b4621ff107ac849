"""Outputs of diagnose: report.json (fixed keys), report.md (plain language), plots (PNG), model.json."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fluidnexus.atomic import write_json

from .emission import EMPTY
from .observe import observables
from .plots import line_plot
from .plume import AIR_SPACING
from .search import FOOTAGE_HINTS, MAX_P_VALUE, MIN_RELATIVE_GAIN, SPREAD_TOLERANCE, indistinct

MODEL_FORMAT = "fluidnexus-model/1"


def _jsonable(params: dict) -> dict:
    out = {}
    for k, v in params.items():
        v = np.asarray(v, float)
        out[k] = [float(x) for x in v] if v.ndim else (float(v) if np.isfinite(v) else None)
    return out


def structure_params(params) -> dict:
    """report.json's ``structure.params``: what the base model of the structure fitted."""
    if params.structure == "ambient_air":
        air = params.model().air
        return {"alpha": params.alpha, "viscosity_c": params.c, "inflow": params.inflow, "margin": air.margin,
                "below": air.below}
    return {"alpha": params.alpha, "drag_k": params.k, "layers_per_second": params.layers}


def model_dict(fit, setup, emission, source_from: str) -> dict:
    """model.json: the engine model (``ModelConfig.to_dict``, its structure included), the appearance and source
    extensions, the source's emission window (``emission``: emission.Emission; predict and interact emit only
    inside it when the run's scene declares none) and where the source came from (``run.plume_source``)."""
    p = fit.params
    spacing = setup.spacing * (AIR_SPACING if p.structure == "ambient_air" else 1.0)
    return {"format": MODEL_FORMAT, "model": p.model().to_dict(), "solver": setup.solver_for(p.structure).to_dict(),
            "source": {"center": list(setup.source_center), "radius": setup.source_radius,
                       "spacing": spacing, "swirl_omega": float(p.ext("swirl", "omega")), "from": source_from,
                       "window": [emission.start, emission.stop], "window_from": emission.source},
            "appearance": {"gain": p.gain, "dissipation_rate": float(p.ext("dissipation", "rate"))},
            "extensions": {k: _jsonable(v) for k, v in p.extensions.items()}}


def width_slope(q) -> float | None:
    """The least-squares slope of the width against the front height (observe.Observables) over the frames where
    both are known, or None (fewer than three)."""
    ok = np.isfinite(q.front) & np.isfinite(q.width)
    if ok.sum() < 3 or np.ptp(q.front[ok]) <= 0:
        return None
    return float(np.polyfit(q.front[ok], q.width[ok], 1)[0])


def write_outputs(out_dir: Path, observed, bases: dict, structure: str, fits: dict, judged: dict, finding: str,
                  train, validate, fitter, spread: tuple[int, float], emission, seconds: float,
                  explanations: list, source_from: str, confirmation: dict | None) -> dict:
    """``bases``: the control fit of each structure; ``structure``: the chosen one; ``fits`` and ``judged``: the
    candidates on it; ``emission``: the source's emission window (emission.Emission); ``explanations``: every
    explanation that passes and holds after the longer search, (structure, term, validation error), the chosen
    first (run.explain, run.confirm); ``source_from``: where the simulated plume's source came from
    (run.plume_source); ``confirmation``: the terms' refits with the longer search (run.confirm), None where no
    term passed."""
    out_dir.mkdir(parents=True, exist_ok=True)
    a = train[0]
    va = np.arange(validate[0] - a, validate[1] - a)
    base = bases[structure]
    chosen = fits[finding] if finding != "none" else base
    unclear = indistinct(judged, spread)
    candidates = [{"effect": n, "params": _jsonable(fits[n].params.extensions[n]),
                   "train_before": judged[n].train_before, "train_after": judged[n].train_after,
                   "validate_before": judged[n].before, "validate_after": judged[n].after,
                   "validate_without_term": None if judged[n].ablated is None else judged[n].ablated.before,
                   "selected": n == finding, "within_spread": n in unclear} for n in fits]
    plots = _plots(out_dir, observed, bases, chosen, finding, train, validate)
    b_err = float(base.errors[va].mean())
    report = {"finding": {"effect": finding,
                          "params": _jsonable(chosen.params.extensions[finding]) if finding != "none" else {},
                          "gain": {"metric": "validation_image_error", "before": b_err,
                                   "after": float(chosen.errors[va].mean())}},
              "candidates": candidates,
              "windows": {"train": list(train), "validate": list(validate)},
              "views": list(observed.names),
              "emission": emission.to_dict(),
              "explanations": [{"structure": st, "effect": name, "validate_error": err}
                               for st, name, err in explanations],
              "confirmation": confirmation,
              "width_slope": {"observed": width_slope(plots["observed"]),
                              "base": width_slope(plots["models"][structure]),
                              "chosen": width_slope(plots["chosen"])},
              "structure": {"name": structure, "params": structure_params(base.params),
                            "gain": {"metric": "validation_image_error",
                                     "before": float(bases["paper_gas"].errors[va].mean()), "after": b_err}}}
    write_json(out_dir / "report.json", report)
    write_json(out_dir / "model.json", model_dict(chosen, fitter.sim.setup, emission, source_from))
    text = _markdown(report, observed, bases, structure, fits, judged, finding, va, plots, fitter, spread, emission,
                     seconds)
    (out_dir / "report.md").write_text(text)
    return report


STRUCTURE_LABELS = {"paper_gas": "paper's gas", "ambient_air": "gas in ambient air"}


def _plots(out_dir, observed, bases, chosen, finding, train, validate) -> dict:
    cams, fps = observed.cameras, observed.fps
    o, s1 = (observables(x, cams, fps) for x in (observed.images, chosen.images))
    models = {name: observables(fit.images, cams, fps) for name, fit in bases.items()}
    frames = np.arange(observed.first, observed.first + observed.images.shape[1])
    label = "extended model"
    runs = {"observed": o, **{STRUCTURE_LABELS[name]: q for name, q in models.items()}}
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
              {k: q.front * 100 for k, q in runs.items()}, {k: q.width for k, q in runs.items()},
              "front height [cm]", "width")
    errs = {STRUCTURE_LABELS[name]: fit.errors for name, fit in bases.items()}
    if finding != "none":
        errs[label] = chosen.errors
    line_plot(out_dir / "image_error.png", "image error per frame (relative)", frames, errs, "frame", "", marks)
    written["image_error.png"] = "image error per frame"
    written["width_vs_height.png"] = "width versus front height"
    return {"observed": o, "models": models, "chosen": s1, "files": written}


def _structure_text(report, observed, bases, structure, plots, va) -> list[str]:
    """The structure section of report.md: widths and validation errors of both structures, in plain words."""
    o, models = plots["observed"], plots["models"]
    pg, aa = models["paper_gas"], models["ambient_air"]
    ok = np.isfinite(o.width) & np.isfinite(pg.width) & np.isfinite(aa.width)
    start = np.flatnonzero(ok & (np.arange(len(ok)) >= min(5, len(ok) - 1)))
    e_pg, e_aa = (float(bases[n].errors[va].mean()) for n in ("paper_gas", "ambient_air"))
    gain = (e_pg - e_aa) / max(e_pg, 1e-12)
    if not len(start) or not ok[-1]:
        widths = "The plume widths cannot be compared (a model shows no smoke in some frames)."
        narrow = ""
    else:
        k0, k1 = observed.first + start[0], observed.first + len(ok) - 1
        w = {name: (q.width[start[0]], q.width[-1]) for name, q in (("o", o), ("pg", pg), ("aa", aa))}
        grow_o, grow_pg = w["o"][1] - w["o"][0], w["pg"][1] - w["pg"][0]
        narrow = ("stays too narrow: it has no air to entrain. " if grow_pg < 0.5 * grow_o and w["pg"][1] < w["o"][1]
                  else "is too wide. " if w["pg"][1] > 1.1 * w["o"][1] else "widens about as the real one. ")
        widths = (f"From frame {k0} to {k1} the paper's gas widens from {w['pg'][0]:.3f} to {w['pg'][1]:.3f} m where "
                  f"the real plume widens from {w['o'][0]:.3f} to {w['o'][1]:.3f} m; in ambient air the simulated "
                  f"plume widens from {w['aa'][0]:.3f} to {w['aa'][1]:.3f} m.")
    if structure == "ambient_air":
        verdict = (f"In ambient air the validation error falls from {e_pg:.4f} to {e_aa:.4f} "
                   f"({100 * gain:.0f} % lower): the candidates below extend the gas in ambient air.")
    else:
        change = f"{100 * gain:.0f} % lower" if gain > 0 else f"{-100 * gain:.0f} % higher"
        verdict = (f"In ambient air the validation error is {e_aa:.4f} against the paper's gas {e_pg:.4f} "
                   f"({change}), not clearly lower: the candidates below extend the paper's gas.")
    p = report["structure"]["params"]
    text = ", ".join(f"{k} {v:.3g}" for k, v in p.items())
    return [f"## Structure: {structure}", "",
            f"The simulated plume of the paper's gas {narrow}{widths} {verdict} (Chosen like a term: relative gain "
            f">= {100 * MIN_RELATIVE_GAIN:.0f} % and one-sided Wilcoxon p < {MAX_P_VALUE} over the validation "
            f"frames; each structure's base model refitted on the training frames. Base model: {text}.)", ""]


def _emission_text(emission, first: int, last: int) -> str:
    """report.md's sentence on when the source emits (emission.Emission; ``first``, ``last``: the first and last
    frames diagnosed)."""
    if emission.source == "scene":
        until = "to the end" if emission.stop is None else f"until frame {emission.stop - 1}"
        return (f"The source emits from frame {emission.start} {until}, as the scene declares "
                "(`source.window`); the simulated plumes emit only then.")
    text = "The scene declares no emission window. "
    if emission.start > first:
        text += (f"In the footage new smoke first appears at the source at frame {emission.start}: before it the "
                 f"smoke around the source stays below {100 * EMPTY:.0f} % of its peak. ")
    if emission.stop is None:
        if emission.start > first:
            return text + (f"From then on it is replenished up to frame {last}; the simulated plumes emit from "
                           f"frame {emission.start} on.")
        return text + (f"In the footage the smoke at the source is replenished up to frame {last}, so the source is "
                       f"taken to emit throughout (frames {emission.start}-{last}).")
    return text + (f"In the footage new smoke stops appearing at the source after frame {emission.stop - 1}: the "
                   f"smoke around it falls below {100 * EMPTY:.0f} % of its peak and stays there to frame {last}. "
                   f"The simulated plumes emit from frame {emission.start} to frame {emission.stop - 1} only.")


def _markdown(report, observed, bases, structure, fits, judged, finding, va, plots, fitter, spread, emission,
              seconds) -> str:
    o, s0, s1 = plots["observed"], plots["models"][structure], plots["chosen"]
    base = bases[structure]
    last = observed.first + observed.images.shape[1] - 1
    dx = o.centroid[-1] - s0.centroid[-1]
    di = (s0.intensity[-1] - o.intensity[-1]) / max(o.intensity[-1], 1e-12)
    lines = ["# diagnose report", "",
             f"Views used ({len(observed.names)}): {', '.join(observed.names)}. Training frames "
             f"{report['windows']['train'][0]}:{report['windows']['train'][1]}, validation frames "
             f"{report['windows']['validate'][0]}:{report['windows']['validate'][1]} (half-open). "
             f"{fitter.evaluations} rollouts, {seconds:.0f} s.", "",
             _emission_text(emission, observed.first, last), ""]
    lines += _structure_text(report, observed, bases, structure, plots, va)
    lines += ["## What the base model gets wrong", "",
              f"Base model ({_base_text(base.params)}) fitted on the "
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
        if finding == "entrainment":
            lines += _entrainment_text(report)
    lines += ["## Candidates (judged on the validation frames only)", "",
              "| effect | fitted parameters | training error before | after | validation error before | after | "
              "gain | p | without its term | selected |", "|---|---|---|---|---|---|---|---|---|---|"]
    for c in report["candidates"]:
        j = judged[c["effect"]]
        lines.append(f"| {c['effect']} | {c['params']} | {j.train_before:.4f} | {j.train_after:.4f} | "
                     f"{j.before:.4f} | {j.after:.4f} | {100 * j.relative_gain:.1f} % | {j.p_value:.2g} | "
                     f"{'-' if j.ablated is None else f'{j.ablated.before:.4f}'} | "
                     f"{'yes' if c['selected'] else 'no'} |")
    same = (f"the best of them has a validation error {100 * spread[1]:.1f} % below the control's. A candidate's "
            "gain of that size could come from where its search stopped rather than from its term; read such a "
            "finding with care." if spread[1] > 0 else "none of them has a lower validation error than the control.")
    lines += ["", "A candidate counts only if its term carries the gain (with the term switched off and every other "
              "parameter as fitted, the validation error is clearly higher: the column \"without its term\", "
              "measured for the candidates with a clear gain) and, "
              "where its search starts at the base model (every candidate but entrainment), it also lowers the "
              "training error: one that does not has not found its effect on the frames it was fitted to."]
    lines += _explanations_text(report["explanations"])
    lines += _confirmation_text(report["confirmation"])
    lines += ["", f"How far the training frames pin the base model: {spread[0]} fits of the base model alone "
              f"(no extension, from the base and control searches) come within {100 * SPREAD_TOLERANCE:.0f} % of "
              f"the control's training error; {same}"]
    for name in (c["effect"] for c in report["candidates"] if c["within_spread"]):
        lines += ["", f"This footage cannot tell `{name}` apart from the base model: its gain "
                      f"({100 * judged[name].relative_gain:.1f} %) is within that spread. To tell them apart, "
                      f"{FOOTAGE_HINTS[name]}."]
    lines += ["", f"Metric: {report['finding']['gain']['metric']} = the {_METRIC_TEXT}.", "", "## Plots", ""]
    lines += [f"- {title}: ![{title}]({name})" for name, title in plots["files"].items()]
    return "\n".join(lines) + "\n"


def _confirmation_text(confirmation: dict | None) -> list[str]:
    """report.md's paragraph on the longer refits of the terms that passed (run.confirm)."""
    if confirmation is None:
        return []
    lines = ["", f"Every term that passed was refitted from scratch, with its base model, with {confirmation['evals']} "
                 f"rollouts a fit ({confirmation['rollouts']} rolled out: a model already scored is not rolled out "
                 "again) and judged by the same rule: a short search "
                 "can stop where a term's extra parameter stands in for the base model's own, the footage's effect "
                 "passes after either."]
    for r in confirmation["explanations"]:
        verdict = "holds" if r["holds"] else "does not hold, so it is not kept"
        lines.append(f"- `{r['effect']}` on the {STRUCTURE_LABELS[r['structure']]}: validation gain "
                     f"{100 * r['gain']:.1f} % (p {r['p']:.2g}), training error {r['train_before']:.4f} -> "
                     f"{r['train_after']:.4f}; {verdict}.")
    return lines


def _explanations_text(explanations: list) -> list[str]:
    """report.md's paragraph on explanations of the same miss (more than one passing)."""
    if len(explanations) < 2:
        return []
    items = "; ".join(f"{STRUCTURE_LABELS[e['structure']]}"
                      f"{'' if e['effect'] == 'none' else ' with ' + e['effect']} (validation error "
                      f"{e['validate_error']:.4f})" for e in explanations)
    return ["", f"More than one explanation passes, and they explain the same miss: {items}. The one with the lowest "
                "validation error is reported above."]


def _entrainment_text(report) -> list[str]:
    """report.md's sentences on a fitted entrainment: alpha against plumes' range, the width slopes."""
    from fluidnexus.engine.entrainment import PLUME_RANGE

    alpha = report["finding"]["params"]["alpha"]
    ws = report["width_slope"]
    slopes = ", ".join(f"{k} {v:.3f}" for k, v in ws.items() if v is not None)
    lo, hi = PLUME_RANGE
    where = "within" if lo <= alpha <= hi else "below" if alpha < lo else "above"
    return [f"The plume entrains ambient air: the fitted entrainment coefficient alpha = {alpha:.3f} is {where} the "
            f"range reported for turbulent plumes ({lo}-{hi}). Width against front height, least-squares slope "
            f"(m per m): {slopes}.", ""]


def _base_text(p) -> str:
    if p.structure == "ambient_air":
        return (f"the gas in ambient air: buoyancy alpha {p.alpha:.3g} on smoke, XSPH viscosity c {p.c:.3f} among "
                f"smoke and air, inlet {p.inflow:.3f} m/s")
    return f"the paper's gas: buoyancy alpha {p.alpha:.3g}, drag k {p.k:.2f} 1/s, source {p.layers:.1f} layers/s"


_METRIC_TEXT = "mean over validation frames and views of the squared difference between real and simulated " \
               "low-resolution images, relative to the mean squared real intensity (1.0 = predicting no smoke)"
