"""``reconstruct``: the frame loop of FluidNexus Alg. S1 with a run folder, checkpoints and resume.

Run folder layout (docs/run-format.md)::

    RUN/
      run.json          format tag, kind, the scene folder, frame range
      config.json       the resolved settings: reconstruction, PBF solver and model
      frames/NNNNNN.npz one state per reconstructed frame (fluidnexus.state), written atomically
      logs/recon.log    one line per frame: losses, particle counts, seconds
      summary.json      frames done, time per frame split into simulation / rendering / backward / other

Each frame's random choices come from generators seeded by (seed, frame), and Adam restarts every frame, so the
state saved after frame t determines everything after it: ``--resume`` continues from the last complete frame
and ends where an uninterrupted run would.
"""
from __future__ import annotations

import logging
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from .. import engine, memory
from ..atomic import read_json, write_json
from ..engine.tensors import torch_dtype
from ..errors import InputError, RunError
from ..progress import progress
from ..runs import RUN_FORMAT
from ..scene import Scene
from ..scene_scale import SOURCE_SLAB
from ..scenery.backdrop import scene_backdrop
from ..scenery.static_layer import STATIC_FILE, save_static
from ..scenery.world import declared_scenery, fit_scenery
from ..state import frame_path, load_frame, save_frame
from .config import ReconConfig, differing_keys
from .fit import Views, fit_appearance, fit_dynamics, fit_look, fit_positions
from .initial import emit, frame_generator, initial_smoke, initial_visual, outside
from .memory import recon_estimate
from .observations import load_observations, resolve_frames
from .setup import RunSetup, capacities, scene_source
from .smoke import Smoke
from .source_finder import FoundSource, find_source
from .support import support
from .timing import Stopwatch
from .workspace import Workspace

log = logging.getLogger("fluidnexus")


def locate_smoke(scene: Scene, obs, cfg: ReconConfig, obstacle=None) -> tuple[FoundSource, np.ndarray]:
    """The inflow (declared, or found in the first frames with smoke: ``source_finder``) and the visual seeds
    from the first frame's visual hull, none inside an obstacle."""
    found = find_source(scene, obs, cfg.visual_spacing, SOURCE_SLAB * cfg.length_scale,
                        scene_source(scene, cfg.length_scale), obstacle)
    return found, outside(initial_visual(found.source, found.hull_points, cfg), obstacle, "visual seeds")


def _prepare_folder(out: Path, scene: Scene, setup: RunSetup, frames: tuple[int, int], resume: bool) -> int:
    """Create or check the run folder; return the first frame still to reconstruct."""
    resolved = setup.to_dict()
    if resume:
        config_file = out / "config.json"
        if not config_file.exists():
            raise InputError(out, None, "--resume: no reconstruction run here (config.json missing)")
        saved = read_json(config_file)
        diff = [f"{section}.{k}" for section in resolved
                for k in differing_keys(saved.get(section, {}), resolved[section])]
        if diff:
            raise InputError(config_file, diff[0], f"--resume with different settings: {', '.join(diff)} differ "
                                                   "from the run's config.json")
        done = [t for t in range(*frames) if frame_path(out, t).exists()]
        first = frames[0]
        while first in done:
            first += 1
        return first
    _refuse_occupied(out)
    (out / "frames").mkdir(parents=True, exist_ok=True)
    (out / "logs").mkdir(exist_ok=True)
    write_json(out / "run.json", {"format": RUN_FORMAT, "kind": "recon", "scene": str(scene.root.resolve()),
                                  "frames": list(frames), "arch": engine.current().arch})
    write_json(out / "config.json", resolved)
    return frames[0]


def _refuse_occupied(out: Path) -> None:
    if out.exists() and any(out.iterdir()):
        raise InputError(out, None, "already exists and is not empty (use --resume to continue it, or another --out)")


def reconstruct(scene: Scene, out: str | Path, setup: RunSetup, resume: bool = False,
                max_memory: int | None = None) -> dict:
    """Reconstruct the smoke of ``scene`` into the run folder ``out``; return the summary.

    Before it reads a video or writes a file, and again once the first frame's hull is known, the run's memory
    is estimated (``fluidnexus.memory``) and refused over ``max_memory`` bytes (None: the default limit).

    Raises:
        InputError: bad settings, no usable view, a frame range outside the videos, a mismatched --resume,
            an estimated memory over the limit.
        RunError: the optimisation diverged or a frame could not be written; the last good frame is kept.
    """
    out = Path(out)
    setup = replace(setup, config=_physical_support(scene, setup.config))
    cfg = setup.config
    frames = resolve_frames(scene, cfg.frames)
    declared = declared_scenery(scene)  # before anything is written
    limit = memory.parse_limit(None) if max_memory is None else max_memory
    memory.check(recon_estimate(scene, replace(setup, config=replace(cfg, frames=frames)), frames, 0), limit)
    if not resume:
        _refuse_occupied(out)
    cameras = {v.name: v.camera.scaled(cfg.resolution) for v in scene.usable_views()}
    scenery = fit_scenery(scene, declared, cameras, cfg.channels, cfg.static_iters, cfg.seed, frames,
                          out / STATIC_FILE)
    obstacle = scenery.obstacle
    if obstacle is not None and cfg.lambda_next:
        log.info("the scene has obstacles: the look-ahead term is off (a step with an obstacle has no gradient)")
    setup = replace(setup, config=replace(cfg, frames=frames, lambda_next=0.0 if obstacle else cfg.lambda_next))
    cfg = setup.config
    backdrop = scene_backdrop(scene, cfg.channels, scenery.layer)
    obs = load_observations(scene, frames, cfg.resolution, cfg.channels, backdrop)
    found, seeds = locate_smoke(scene, obs, cfg, obstacle)
    source = found.source
    log.info("%s", memory.check(recon_estimate(scene, setup, frames, len(seeds)), limit).describe())
    setup = replace(setup, config=_initial_look(scene, cfg, obs, found, out, resume))
    first = _prepare_folder(out, scene, setup, frames, resume)
    if first >= frames[1] and (out / "summary.json").is_file():  # a finished run resumed: nothing to do
        log.info("every frame of %d:%d is already in %s", *frames, out)
        return read_json(out / "summary.json")
    if scenery.layer is not None and not (out / STATIC_FILE).is_file():
        save_static(out, scenery.layer)
    if first == frames[0]:  # predict/interact read the inflow from run.json, also of an unfinished run
        write_json(out / "run.json", {**read_json(out / "run.json"), "source": source.to_dict(),
                                      "source_finder": found.record, **scenery.record})
    ws = Workspace(*capacities(frames[1] - frames[0], setup, source, len(seeds)), setup.solver, setup.model,
                   extra_gaussians=max((len(b.static) for b in obs.behind if b.static is not None), default=0))
    ws.set_obstacle(obstacle)
    handler = logging.FileHandler(out / "logs" / "recon.log")
    handler.setFormatter(logging.Formatter("%(asctime)s %(message)s"))
    log.addHandler(handler)
    watch = Stopwatch()
    try:
        summary = _frame_loop(out, setup, obs, ws, source, seeds, first, watch, scene.volume)
    finally:
        log.removeHandler(handler)
        handler.close()
    return summary


def over_backdrop(scene: Scene) -> bool:
    """The footage shows the smoke over a backdrop: the scene has clean plates or a backdrop colour other than
    black."""
    return bool(scene.backgrounds) or (scene.backdrop_color is not None and any(scene.backdrop_color))


def _physical_support(scene: Scene, cfg: ReconConfig) -> ReconConfig:
    """``cfg`` with ``physical_support`` resolved: ``auto`` is on over a backdrop, off on black."""
    if cfg.physical_support != "auto":
        return cfg
    return replace(cfg, physical_support="on" if over_backdrop(scene) else "off")


def _initial_look(scene: Scene, cfg: ReconConfig, obs, found: FoundSource, out: Path, resume: bool) -> ReconConfig:
    """``cfg`` with the initial look (``ReconConfig.initial_look``): fitted to the earliest frame of the run with
    smoke, at that frame's hull (a look fitted to a frame without smoke would be invisible: a burst that starts
    later), or read back from the run's config.json when resuming (the fit gives the same values; reading them
    saves its time). The constants stay where no frame shows smoke. The hull holds no point inside an obstacle
    (``find_source``)."""
    fitted = cfg.initial_look == "fit" or (cfg.initial_look == "auto" and over_backdrop(scene))
    if not fitted:
        return cfg
    if resume and (out / "config.json").is_file():
        saved = read_json(out / "config.json").get("recon", {})
        return replace(cfg, color0=saved.get("color0", cfg.color0), opacity0=saved.get("opacity0", cfg.opacity0))
    t = found.smoke_frame
    if t is None:
        log.info("initial look: no frame shows smoke, the constants %.4g, %.4g are kept", cfg.color0, cfg.opacity0)
        return cfg
    dtype = torch_dtype()
    color, opacity = fit_look(torch.as_tensor(found.smoke_hull, dtype=dtype), _views(obs, t, dtype), cfg,
                              frame_generator(cfg.seed, t))
    log.info("initial look fitted to frame %d: colour %.4g, opacity %.4g (from %.4g, %.4g)", t, color,
             opacity, cfg.color0, cfg.opacity0)
    return replace(cfg, color0=color, opacity0=opacity)


def _views(obs, t: int, dtype) -> Views:
    return Views(obs.cameras, torch.as_tensor(obs.frame(t), dtype=dtype),
                 tuple(b.render_args(dtype) for b in obs.behind))


def _frame_loop(out, setup, obs, ws, source, seeds, first, watch, volume) -> dict:
    cfg = setup.config
    start, stop = cfg.frames
    started = time.perf_counter()
    with progress("reconstruct", stop - first) as bar:
        if first == start:
            with watch.measure("initialisation"):
                try:
                    smoke = _first_frame(source, seeds, obs, ws, cfg, bar, watch)
                except FloatingPointError as err:
                    raise RunError(f"frame {start} (initialisation): {err}; nothing was saved") from None
            smoke = _save(out, smoke, start)
            bar.advance()
            first += 1
        else:
            smoke = Smoke.from_state(load_frame(frame_path(out, first - 1)), ws.dtype)
            log.info("resuming after frame %d", first - 1)
        for t in range(first, stop):
            tic = time.perf_counter()
            smoke = _save(out, _one_frame(smoke, t, source, obs, ws, cfg, bar, watch, out, volume), t)
            log.info("frame %d: %d physical, %d visual particles, %.1f s", t, smoke.p.shape[0], smoke.x.shape[0],
                     time.perf_counter() - tic)
            bar.advance()
    elapsed = time.perf_counter() - started
    summary = {"format": RUN_FORMAT, "frames": [start, stop], "frames_this_session": stop - first,
               "source": source.to_dict(),
               "elapsed_s": round(elapsed, 3), "timing_s": watch.totals(),
               "seconds_per_frame": round(elapsed / max(1, stop - first), 3),
               "particles": {"physical": int(smoke.p.shape[0]), "visual": int(smoke.x.shape[0])}}
    write_json(out / "summary.json", summary)
    return summary


def _first_frame(source, seeds, obs, ws, cfg, bar, watch) -> Smoke:
    start = cfg.frames[0]
    smoke = initial_smoke(source, seeds, cfg, ws, start)
    views = _views(obs, start, ws.dtype)
    fit_positions(smoke, views, cfg, frame_generator(cfg.seed, start), bar, watch)
    smoke.x = ws.push_out(smoke.x)
    fit_appearance(smoke, views, cfg, frame_generator(cfg.seed, start), bar, watch)
    return smoke


def inside(p: torch.Tensor, volume, margin: float) -> torch.Tensor:
    """[N] bool: particles within ``margin`` of the scene volume (everything when the scene has none)."""
    if volume is None:
        return torch.ones(p.shape[0], dtype=torch.bool)
    lo = torch.as_tensor(volume.min, dtype=p.dtype) - margin
    hi = torch.as_tensor(volume.max, dtype=p.dtype) + margin
    return ((p >= lo) & (p <= hi)).all(dim=1)


def _one_frame(prev: Smoke, t, source, obs, ws, cfg, bar, watch, out, volume) -> Smoke:
    views = _views(obs, t, ws.dtype)
    if cfg.physical_support == "on":
        log.info("frame %d: %d physical particles seeded under the visual particles without any", t,
                 support(prev, ws, cfg.physical_spacing))
    emit(prev, source, cfg, t, obstacle=ws.obstacle)
    try:
        with watch.measure("dynamics"):
            dyn = fit_dynamics(prev, ws, views, cfg, frame_generator(cfg.seed, t),
                               lambda p: ~ws.isolated(p) & inside(p, volume, ws.solver.h), bar, watch)
        smoke = Smoke(t, dyn.p, dyn.u, dyn.age, dyn.x, prev.color, prev.scale, prev.rotation, prev.opacity)
        with watch.measure("appearance"):
            losses = fit_appearance(smoke, views, cfg, frame_generator(cfg.seed, t), bar, watch)
    except FloatingPointError as err:
        raise RunError(f"frame {t}: {err}. The last good frame is {t - 1}: {frame_path(out, t - 1)}; "
                       "fix the setting and continue with --resume") from None
    log.info("frame %d losses: %s", t, ", ".join(f"{k}={v:.4g}" for k, v in {**dyn.losses, **losses}.items()))
    return smoke


def _save(out: Path, smoke: Smoke, t: int) -> Smoke:
    """Write frame ``t`` and return the state exactly as saved (float32), which the next frame starts from, so
    that a run resumed from the file continues identically whatever the engine precision."""
    state = smoke.to_state()
    try:
        save_frame(frame_path(out, t), state)
    except OSError as err:
        raise RunError(f"could not write {frame_path(out, t)} ({err.strerror or err}); the last complete frame "
                       f"is kept, continue with --resume once there is room") from None
    return Smoke.from_state(state, smoke.p.dtype)
