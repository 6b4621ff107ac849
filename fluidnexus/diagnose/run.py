"""The diagnose procedure (docs/diagnose.md): load measured views, fit the base model of each structure on the
training window and choose the structure on the validation window, refit each candidate extension on top of it,
judge on the validation window, write the report and the extended model."""
from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from fluidnexus.errors import InputError
from fluidnexus.scene import UP, load_ground_truth, load_scene
from fluidnexus.recon.source_finder import MIN_POINTS, foot, foot_radius
from fluidnexus.scene_scale import DIAGNOSE_SPACING, PLUME_BOX_ABOVE, PLUME_BOX_BELOW, SOURCE_SLAB, scene_factor
from fluidnexus.scenery.world import scene_obstacles

from .emission import emission_window
from .footage import run_layer, smoke_images, usable
from .observe import Observed, observables
from .parallel import FitPool
from .plume import AIR_SPACING, EXTENSIONS, PAPER_GAS_ONLY, STRUCTURES, PlumeSetup, PlumeSimulator
from .report import write_outputs
from .search import SPREAD_TOLERANCE, Fitter, ablate, fit_candidate, fit_structure, judge, search_spread

log = logging.getLogger("fluidnexus")

DEFAULT_SOURCE = ((0.34, 0.0, -0.225), 0.09)  # ScalarFlow inflow (docs/simulator.md)
CONFIRM_FACTOR = 3  # a finding is refitted with this many times the rollouts per fit and must pass there too


def load_observed(scene_dir: Path, first: int, last: int, height: int, layer=None) -> Observed:
    """Every real view of the scene (input views, novel views that have footage, ground truth whose camera
    stands still) as images of the smoke (footage.py: gray frames, or the smoke's opacity over the view's plate,
    or over the static ``layer`` of a reconstruction where it has none) of ``height`` rows, frames
    [first, last)."""
    scene = load_scene(scene_dir)
    views = [(v.name, v.camera, scene.video_path(v)) for v in scene.views if v.video is not None]
    for g in load_ground_truth(scene_dir):
        if g.poses is not None:  # the fits below assume still cameras
            log.info("diagnose: ground-truth view %s left out: its camera moves (one pose per frame)", g.name)
            continue
        views.append((g.name, g.camera, scene.root / g.video))
    views = [v for v in views if usable(scene, v[0], layer)]
    if not views:
        raise InputError(scene_dir, "views", "diagnose needs at least one view with footage")
    if not 0 <= first < last <= scene.frame_count:
        raise InputError(scene_dir, "frames", f"windows {first}:{last} do not fit {scene.frame_count} frames")
    cams = [cam.resized(max(8, round(cam.width * height / cam.height)), height) for _, cam, _ in views]
    names = [name for name, _, _ in views]
    imgs = smoke_images(scene, [(name, path, small.width, small.height, cam) for (name, cam, path), small
                                in zip(views, cams)], slice(first, last), layer)
    return Observed(tuple(names), tuple(cams), np.asarray(imgs, np.float64), first, scene.fps)


def plume_source(scene, observed: Observed, spacing: float, factor: float) -> tuple[tuple, str]:
    """((centre, radius), where it came from) of the simulated plume's upward source disk: the scene's declared
    source; else, in a scene with a volume, the foot of the earliest smoke the views' hull holds (the centre of its
    lowest slab and the slab's spread, as recon's source finder takes the foot; ``recon.source_finder.foot``);
    else ScalarFlow's inflow (``DEFAULT_SOURCE``)."""
    if scene.source is not None:
        return (tuple(scene.source.center), float(scene.source.radius)), "declared"
    if scene.volume is not None:
        lo, hi = np.asarray(scene.volume.min, float), np.asarray(scene.volume.max, float)
        slab = max(SOURCE_SLAB * factor, spacing)
        for t in range(observed.images.shape[1]):
            points = visual_hull(observed, lo, hi, spacing, frame=t)
            if len(points) >= MIN_POINTS:
                center, base = foot(points, UP, slab)
                return ((tuple(float(v) for v in center), foot_radius(base, center, UP, spacing)),
                        f"found: the foot of the smoke in frame {observed.first + t}")
    return DEFAULT_SOURCE, "none declared and no smoke in a volume: ScalarFlow's inflow"


def visual_hull(observed: Observed, lo, hi, spacing: float, level: float = 0.15, frame: int = 0) -> np.ndarray:
    """Lattice points [M, 3] inside every view's smoke silhouette at ``frame`` (an index into the observed
    frames; intensity above ``level`` x that view's peak); none when a view shows no smoke."""
    axes = [np.arange(a + 0.5 * spacing, b, spacing) for a, b in zip(lo, hi)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    keep = np.ones(len(pts), bool)
    for cam, img in zip(observed.cameras, observed.images[:, frame]):
        if img.max() <= 1e-3:
            return np.zeros((0, 3))
        uv, depth = cam.project(pts)
        u, v = np.floor(uv[:, 0]).astype(int), np.floor(uv[:, 1]).astype(int)
        inside = (depth > 0) & (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height)
        hit = np.zeros(len(pts), bool)
        hit[inside] = img[v[inside], u[inside]] > level * img.max()
        keep &= hit
    return pts[keep]


def diagnose(scene_dir, out_dir, train: tuple[int, int], validate: tuple[int, int], height: int = 48,
             spacing: float | None = None, maxfev: int = 20, candidates=tuple(EXTENSIONS), jobs: int = 1,
             run_dir: Path | None = None) -> dict:
    """Run the whole procedure and write report.json, report.md, plots and model.json into ``out_dir``.

    Args:
        scene_dir: a scene folder (scene-format.md) with real footage.
        out_dir: output folder (created).
        train, validate: half-open frame windows [a, b) and [c, d) with a < b <= c < d.
        height: observation image height [px] (width follows each camera's aspect).
        spacing: physical particle spacing of the simulated plume [m]; None: 0.02 m times the scene's length
            scale (docs/scale.md), as are the margins around the source and the volume.
        maxfev: rollouts per fit (Nelder-Mead evaluations).
        candidates: names of the extensions tried (default all of :data:`EXTENSIONS`).
        jobs: fits run side by side in this many processes (parallel.py); the report does not depend on it.
        run_dir: a reconstruction of the scene: the plume flows around the obstacles it found too (scenery.py),
            and views without a plate are seen over its static layer (footage.py); None: around the scene's
            declared obstacles, and such views are left out.

    Returns:
        The report dict (report.json's content).
    """
    started = time.perf_counter()
    scene_dir, out_dir = Path(scene_dir), Path(out_dir)
    (a, b), (c, d) = train, validate
    if not (a < b <= c < d):
        raise InputError(None, "--train-frames/--validate-frames",
                         f"need train a:b before validate c:d with a < b <= c < d, got {a}:{b} and {c}:{d}")
    unknown = set(candidates) - set(EXTENSIONS)
    if unknown:
        raise InputError(None, "candidates", f"unknown extensions {sorted(unknown)}; known: {sorted(EXTENSIONS)}")
    if len(set(candidates)) != len(candidates):
        raise InputError(None, "candidates", f"each extension once, got {list(candidates)}")
    scene = load_scene(scene_dir)
    factor = scene_factor(scene)
    spacing = DIAGNOSE_SPACING * factor if spacing is None else spacing
    observed = load_observed(scene_dir, a, d, height, run_layer(run_dir))
    src, src_from = plume_source(scene, observed, spacing, factor)
    log.info("diagnose: the source at (%.4g, %.4g, %.4g), radius %.4g (%s)", *src[0], src[1], src_from)
    if scene.volume:
        lo, hi = np.asarray(scene.volume.min, float), np.asarray(scene.volume.max, float)
    else:
        lo = np.asarray(src[0]) - factor * np.array(PLUME_BOX_BELOW)
        hi = np.asarray(src[0]) + factor * np.array(PLUME_BOX_ABOVE)
    seed = visual_hull(observed, lo, hi, spacing)
    air_seed = visual_hull(observed, lo, hi, spacing * AIR_SPACING)
    obstacles, body = scene_obstacles(scene_dir, run_dir)
    if body is not None:
        log.info("diagnose: the plume flows around the %s obstacles", "run's" if run_dir else "scene's declared")
    emission = emission_window(scene.source, observed, *src)  # the scene's window, else when the footage shows it
    log.info("diagnose: the source emits in frames [%d, %s) (from the %s)", emission.start,
             "end" if emission.stop is None else emission.stop, emission.source)
    setup = PlumeSetup(tuple(src[0]), float(src[1]), spacing, observed.fps, d - a, tuple(lo - 0.1 * factor),
                       tuple(hi + 0.1 * factor), seed, air_seed,
                       emitting=np.array([emission.emits_at(a + t) for t in range(d - a)]), obstacles=obstacles)
    sim = PlumeSimulator(setup, body)
    cams = observed.cameras
    tr, va = np.arange(0, b - a), np.arange(c - a, d - a)
    fitter = _fitter(sim, observed, tr)
    log.info("diagnose: %d views (%s), %d frames at %dx%d, %d seeded particles", len(cams),
             ", ".join(observed.names), d - a, cams[0].width, cams[0].height, len(seed))
    drift = _drift(observed, tr)

    def start_candidates(pool, st: str, base, names) -> list:
        d = drift(base)
        return [((st, name), pool.submit(fit_candidate, (base, name, maxfev, d))) for name in names]

    # the two structures side by side; the paper's gas's candidates start as soon as its base is fitted (the gas in
    # ambient air takes longer), the air's once the structure is judged
    with FitPool(fitter, jobs) as pool:
        structure_tasks = [pool.submit(fit_structure, (s, maxfev)) for s in STRUCTURES]
        bases, tasks = {}, []
        for structure, task in zip(STRUCTURES, structure_tasks):
            fit, control = task.result()
            log.info("base fit (%s): %s gain %.4g, train error %.4f, validation error %.4f", structure,
                     _describe(fit.params), fit.params.gain, fitter.train_error(fit), fit.errors[va].mean())
            log.info("control refit (%s, alpha only): alpha %.4f, train error %.4f, validation error %.4f",
                     structure, control.params.alpha, fitter.train_error(control), control.errors[va].mean())
            bases[structure] = control
            if structure == "paper_gas":  # the terms are always tried on the paper's gas
                tasks += start_candidates(pool, structure, control, candidates)
        # the ambient-air structure is judged like a term against the paper's gas (search.judge)
        structure_judged = judge(bases["paper_gas"], bases["ambient_air"], tr, va)
        log.info("structure ambient_air against paper_gas: training error %.4f -> %.4f, validation error %.4f -> "
                 "%.4f (gain %.1f %%, p %.2g)", structure_judged.train_before, structure_judged.train_after,
                 structure_judged.before, structure_judged.after, 100 * structure_judged.relative_gain,
                 structure_judged.p_value)
        # and on the gas in ambient air where it passes: a term and the structure can explain the same miss, and
        # the explanation with the lower validation error wins
        tried = {"paper_gas": candidates}
        if structure_judged.clear_gain:
            tried["ambient_air"] = tuple(n for n in candidates if n not in PAPER_GAS_ONLY)
            tasks += start_candidates(pool, "ambient_air", bases["ambient_air"], tried["ambient_air"])
        results = {key: task.result() for key, task in tasks}
        ablations = _ablations(pool, bases, results, tr, va)
        fits = {st: {} for st in tried}
        judged = {st: {} for st in tried}
        for (st, name), fit in results.items():
            fits[st][name] = fit
            judged[st][name] = judge(bases[st], fit, tr, va, ablations.get((st, name)))
        for st, named in judged.items():
            for name, j in named.items():
                log.info("candidate %s on %s: %s, training error %.4f -> %.4f, validation error %.4f -> %.4f (gain "
                         "%.1f %%, p %.2g; without its term %s)", name, st, fits[st][name].params.extensions[name],
                         j.train_before, j.train_after, j.before, j.after, 100 * j.relative_gain, j.p_value,
                         "not needed" if j.ablated is None else f"{j.ablated.before:.4f}")
        explanations = explain(bases, structure_judged, fits, judged, va)
        explanations, confirmation = confirm(explanations, bases, drift, maxfev, pool, tr, va)
    structure, finding = explanations[0][:2]
    base = bases[structure]
    spread = search_spread(fitter, base, va)
    log.info("search spread: %d base-model fits within %.0f %% of the control's training error reach a "
             "validation error %.1f %% below the control's", spread[0], 100 * SPREAD_TOLERANCE, 100 * spread[1])
    log.info("explanations that pass (lowest validation error first): %s",
             "; ".join(f"{st} + {name}: {err:.4f}" for st, name, err in explanations))
    report = write_outputs(out_dir, observed, bases, structure, fits[structure], judged[structure], finding, (a, b),
                           (c, d), fitter, spread, emission, time.perf_counter() - started, explanations, src_from,
                           confirmation)
    log.info("diagnose: finding %s (%d rollouts, %.0f s)", finding, fitter.evaluations,
             time.perf_counter() - started)
    return report


def explain(bases: dict, structure_judged, fits: dict, judged: dict, validate: np.ndarray) -> list[tuple]:
    """Every explanation of the footage that passes, as (structure, term or "none", validation error), the lowest
    validation error first; the paper's gas with no term when none passes (then the only entry). The paper's gas
    with its best passing term, and the gas in ambient air (when it passes against the paper's gas) with its best
    passing term or none, are explanations of the same miss: the footage decides between them."""
    def best(st):
        passing = [n for n, j in judged.get(st, {}).items() if j.passes]
        if not passing:
            return st, "none", float(bases[st].errors[validate].mean())
        name = max(passing, key=lambda n: judged[st][n].relative_gain)
        return st, name, float(fits[st][name].errors[validate].mean())

    out = []
    paper = best("paper_gas")
    if paper[1] != "none":
        out.append(paper)
    if structure_judged.clear_gain:
        out.append(best("ambient_air"))
    return sorted(out, key=lambda e: e[2]) or [paper]


def confirm(explanations: list, bases: dict, drift, maxfev: int, pool: FitPool, train: np.ndarray,
            validate: np.ndarray) -> tuple[list, dict | None]:
    """Every explanation with a term that passed (``explain``), its base model and term refitted from scratch with
    :data:`CONFIRM_FACTOR` times ``maxfev`` rollouts per fit and judged by the same rule: the explanations that
    pass there too, the lowest validation error first (the gas in ambient air without its term where only the term
    fails, since the structure passed on its own; the paper's gas with no term where nothing is left), and the
    record of each for report.json (None where no term passed, so nothing was refitted); ``drift``: base fit -> the
    footage's drift away from it (the wind's start); ``pool``: the first fits' pool, renewed for these fits. A
    short search can stop where a term's extra parameter stands in for the base model's own: on the ScalarFlow
    capture at 96 rows buoyancy decay passed with 20.7 % after 20 rollouts a fit and gained 6.5 % after 60
    (BENCHMARKS.md, "Diagnose on the real capture at other observation heights"). The footage's effect passes after
    either."""
    none = ("paper_gas", "none", float(bases["paper_gas"].errors[validate].mean()))
    terms = [(st, name) for st, name, _ in explanations if name != "none"]
    if not terms:
        return explanations, None
    longer = CONFIRM_FACTOR * maxfev
    structures = sorted({st for st, _ in terms})
    log.info("diagnose: confirming %s with %d rollouts a fit", ", ".join(f"{st} + {n}" for st, n in terms), longer)
    # a fitter of its own, so that the search spread (search_spread, from the fitter's record) stays the first fits'
    fitter = pool.renew()
    tasks = [pool.submit(fit_structure, (st, longer)) for st in structures]
    refit = {st: task.result()[1] for st, task in zip(structures, tasks)}
    tasks = [pool.submit(fit_candidate, (refit[st], name, longer, drift(refit[st]))) for st, name in terms]
    fits = {key: task.result() for key, task in zip(terms, tasks)}
    ablations = _ablations(pool, refit, fits, train, validate)
    records = []
    for st, name in terms:
        j = judge(refit[st], fits[(st, name)], train, validate, ablations.get((st, name)))
        records.append({"structure": st, "effect": name, "gain": j.relative_gain, "p": j.p_value,
                        "train_before": j.train_before, "train_after": j.train_after,
                        "without_term": None if j.ablated is None else j.ablated.relative_gain, "holds": j.passes})
        log.info("confirmation with %d rollouts a fit: %s + %s %s (gain %.3g, p %.2g, training error %.4f -> "
                 "%.4f)", longer, st, name, "holds" if j.passes else "does not hold", j.relative_gain, j.p_value,
                 j.train_before, j.train_after)
    held = {(r["structure"], r["effect"]): r["holds"] for r in records}
    kept = confirmed(explanations, held, {st: float(b.errors[validate].mean()) for st, b in bases.items()})
    return kept or [none], {"evals": longer, "rollouts": fitter.evaluations, "explanations": records}


def confirmed(explanations: list, held: dict, base_errors: dict) -> list:
    """The explanations (structure, term, validation error) that stand after the confirmation (``confirm``), the
    lowest validation error first: a structure alone as it was (decided by the base fits), a term where it held
    (``held``: (structure, term) -> bool), and the gas in ambient air without its term where only the term fails
    (the structure passed on its own; ``base_errors``: structure -> its base model's validation error)."""
    kept = []
    for st, name, err in explanations:
        if name == "none" or held[(st, name)]:
            kept.append((st, name, err))
        elif st == "ambient_air":
            kept.append((st, "none", base_errors[st]))
    return sorted(kept, key=lambda e: e[2])


def _ablations(pool: FitPool, bases: dict, fits: dict, train: np.ndarray, validate: np.ndarray) -> dict:
    """(structure, term) -> the fit with its term switched off (``search.ablate``), for the fits of ``fits`` (keyed
    the same) with a clear gain over their structure's base in ``bases``: only those can pass, so only their term is
    switched off to see whether it carries the gain."""
    clear = [key for key, fit in fits.items() if judge(bases[key[0]], fit, train, validate).clear_gain]
    return dict(zip(clear, pool.map(ablate, [(fits[key],) for key in clear])))


def _fitter(sim: PlumeSimulator, observed: Observed, train: np.ndarray) -> Fitter:
    """The fitter of ``sim`` to ``observed``: a particle's footprint is the source spacing seen from the mean
    camera distance."""
    setup = sim.setup
    dist = np.mean([np.linalg.norm(cam.center - np.asarray(setup.source_center)) for cam in observed.cameras])
    sigma = max(0.7, float(np.mean([cam.K[0, 0] for cam in observed.cameras]) * setup.spacing / dist))
    return Fitter(sim, observed.images, observed.cameras, sigma, train)


def _drift(observed: Observed, train: np.ndarray):
    """base fit -> the footage's centroid drift [3] m/s away from the base model's, over the training frames."""
    seen = observables(observed.images, observed.cameras, observed.fps).centroid[train]

    def drift(base) -> np.ndarray:
        return _drift_velocity(seen - observables(base.images, observed.cameras, observed.fps).centroid[train],
                               observed.fps)
    return drift


def _describe(params) -> str:
    if params.structure == "ambient_air":
        return f"alpha {params.alpha:.3f} XSPH c {params.c:.3f} inflow {params.inflow:.3f} m/s"
    return f"alpha {params.alpha:.3f} k {params.k:.3f} layers {params.layers:.1f}/s"


def _drift_velocity(offsets: np.ndarray, fps: float) -> np.ndarray:
    """Least-squares slope [3] m/s of centroid offsets [T, 3] over time (NaN rows skipped)."""
    ok = np.isfinite(offsets).all(1)
    if ok.sum() < 3:
        return np.zeros(3)
    t = np.arange(len(offsets))[ok] / fps
    return np.polyfit(t, offsets[ok], 1)[0]
