"""Sources of any direction: the emitter disk, the inflow velocity, the emission window, and the source finder on
a sideways jet rendered from three cameras."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from fluidnexus.camera import Camera
from fluidnexus.engine import SourceDisk
from fluidnexus.engine.emitter import disk_lattice
from fluidnexus.recon.config import ReconConfig
from fluidnexus.recon.observations import Observations
from fluidnexus.recon.source_finder import find_source
from fluidnexus.scene import Scene, Source, View, Volume
from fluidnexus.scenery.backdrop import scene_backdrop


def _angle(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.degrees(np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))))


def test_emitter_disk_is_perpendicular_to_the_direction_and_exact_for_up():
    center = (0.1, 0.2, -0.3)
    up = SourceDisk(center=center, radius=0.05, spacing=0.01)
    np.testing.assert_array_equal(up.lattice(), disk_lattice(center, 0.05, 0.01))
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    tilted = replace(up, direction=tuple(d))
    pts = tilted.lattice()
    assert len(pts) == up.count
    np.testing.assert_allclose((pts - center) @ d, 0, atol=1e-12)  # in the plane across the direction
    np.testing.assert_allclose(np.linalg.norm(pts - center, axis=1).max(), 0.05, atol=0.01)


def _empty_smoke(dtype=torch.float64):
    from fluidnexus.recon.smoke import Smoke

    e = torch.zeros((0, 3), dtype=dtype)
    return Smoke(0, e, e, torch.zeros(0, dtype=dtype), e, torch.zeros((0, 1), dtype=dtype), e,
                 torch.zeros((0, 4), dtype=dtype), torch.zeros(0, dtype=dtype))


def test_emission_follows_a_declared_direction_speed_and_window(ti_engine):
    from fluidnexus.engine import ModelConfig, SolverConfig
    from fluidnexus.recon.initial import emit, physical_source
    from fluidnexus.recon.workspace import Workspace

    cfg = ReconConfig(frames=(0, 8))
    source = Source((0.0, 0.3, 0.0), 0.03, direction=(1.0, 0.0, 0.0), speed=0.6, window=(2, 6))
    smoke = _empty_smoke()
    emit(smoke, source, cfg, 1)  # before the window: nothing
    assert smoke.p.shape[0] == 0
    emit(smoke, source, cfg, 2)
    n = smoke.p.shape[0]
    assert n == physical_source(source, cfg).count and smoke.x.shape[0] > 0
    np.testing.assert_allclose(smoke.u.numpy(), np.tile([0.6, 0.0, 0.0], (n, 1)))
    np.testing.assert_allclose(smoke.p.numpy()[:, 0], 0.0, atol=0.1 * cfg.physical_emit_spacing)  # the disk: x = 0
    emit(smoke, source, cfg, 6)  # after the window: nothing
    assert smoke.p.shape[0] == n
    ws = Workspace(4 * n, 4 * smoke.x.shape[0], SolverConfig(dt=1 / 30), ModelConfig.scalarflow())
    p0, p, u = smoke.p.clone(), smoke.p, smoke.u
    for _ in range(4):
        p, u = ws.simulate(p, u, smoke.age)
    moved = (p - p0).mean(dim=0).numpy()
    assert moved[0] > 0.03 and _angle(moved, [1, 0, 0]) < 20  # the gas leaves along the source, not up


def _jet_video(cameras, direction, start, frames, speed_px=None):
    """[V, T, H, W, 1]: a jet of smoke out of a nozzle at the origin along ``direction``, switched on at frame
    ``start``, its front advancing 0.03 m per frame; rendered by splatting points of the smoke cylinder."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    a = np.cross(d, [0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.cross(d, [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(d, a)
    rng = np.random.default_rng(0)
    out = np.zeros((len(cameras), frames, cameras[0].height, cameras[0].width, 1), np.float32)
    for t in range(start, frames):
        length = 0.03 * (t - start + 1)
        s = rng.uniform(0, length, 6000)
        r = 0.02 * (1 + s / 0.3) * np.sqrt(rng.uniform(0, 1, 6000))  # widening downstream
        phi = rng.uniform(0, 2 * np.pi, 6000)
        pts = np.outer(s, d) + np.outer(r * np.cos(phi), a) + np.outer(r * np.sin(phi), b)
        for v, cam in enumerate(cameras):
            uv, depth = cam.project(pts)
            col, row = np.floor(uv[:, 0]).astype(int), np.floor(uv[:, 1]).astype(int)
            ok = (depth > 0) & (col >= 0) & (col < cam.width) & (row >= 0) & (row < cam.height)
            out[v, t, row[ok], col[ok], 0] = 0.7
    return out


def test_source_finder_finds_a_sideways_jet(tmp_path):
    direction = np.array([1.0, 0.25, -0.3])
    cameras = tuple(Camera.look_at(96, 96, 110.0, eye, (0.15, 0.0, 0.0))
                    for eye in ((0.15, 0.2, 1.0), (1.1, 0.3, 0.2), (-0.6, 0.4, -0.7)))
    video = _jet_video(cameras, direction, start=2, frames=12)
    volume = Volume((-0.2, -0.3, -0.3), (0.5, 0.3, 0.3))
    views = tuple(View(f"cam{i}", "input", c, f"cam{i}.mp4") for i, c in enumerate(cameras))
    scene = Scene(tmp_path, 30.0, 12, views, volume, None)
    obs = Observations(tuple(v.name for v in views), cameras, 0, video)
    found = find_source(scene, obs, 0.01, 0.01, Source((0.15, -0.3, 0.0), 0.02))
    src = found.source
    assert _angle(src.direction, direction) < 15, (src, found.record)
    assert np.linalg.norm(np.asarray(src.center)) < 0.04  # the nozzle is at the origin
    assert src.window == (2, None) and found.record["first_smoke_frame"] == 2
    assert 0.3 < src.speed < 1.5  # the front advances 0.03 m per frame at 30 fps: 0.9 m/s
    # the same jet as dark smoke on a white backdrop (scene.json backdrop_color) is found the same way
    white_scene = replace(scene, backdrop_color=(1.0, 1.0, 1.0))
    behind = tuple(scene_backdrop(white_scene, 1).behind(c, v.name) for v, c in zip(views, cameras))
    white = find_source(white_scene, replace(obs, images=1.0 - video, behind=behind), 0.01, 0.01,
                        Source((0.15, -0.3, 0.0), 0.02)).source
    assert white == src
    # the same jet as the smoke layers that synth writes of dark smoke (colour 0.04, smoke over black: 0.7 opaque
    # is 0.028, under the hull's 0.05) is found the same way once the views say how far their smoke can reach
    dark = [dict(v.provenance or {}, smoke_layer={"over": "black", "smoke_color": [0.04] * 3}) for v in views]
    layers = replace(scene, views=tuple(replace(v, provenance=p) for v, p in zip(views, dark)))
    behind = tuple(scene_backdrop(layers, 1).behind(c, v.name) for v, c in zip(views, cameras))
    assert all(b.reach == np.float32(0.04) for b in behind)
    faint = replace(obs, images=0.04 * video, behind=behind)
    assert find_source(layers, faint, 0.01, 0.01, Source((0.15, -0.3, 0.0), 0.02)).source == src
    unaware = tuple(replace(b, reach=1.0) for b in behind)  # as before: no frame shows smoke
    assert find_source(layers, replace(faint, behind=unaware), 0.01, 0.01,
                       Source((0.15, -0.3, 0.0), 0.02)).record["method"].startswith("fallback")
    # a declared source keeps its direction; only its centre moves to the foot of the first frame's smoke
    declared = Source((0.3, 0.0, 0.0), 0.02, direction=tuple(direction / np.linalg.norm(direction)), speed=0.9)
    kept = find_source(replace(scene, source=declared), replace(obs, first=0), 0.01, 0.01, declared).source
    assert kept == declared  # frame 0 has no smoke: the declared source as it is


def test_smoke_in_view_from_the_first_frame_moving_near_up_is_a_plume():
    """Smoke in view from the run's first frame (its start not filmed) moving 20 degrees from up is a developed
    plume: its inflow points up, its foot the lowest smoke (at the nozzle). The same smoke whose start is filmed,
    and smoke moving 60 degrees from up (a jet), keep the measured direction."""
    from fluidnexus.recon.source_finder import PLUME_CONE_DEG, UP

    cameras = tuple(Camera.look_at(96, 96, 110.0, eye, (0.0, 0.15, 0.0))
                    for eye in ((0.0, 0.3, 1.0), (1.0, 0.35, 0.1), (-0.7, 0.45, -0.7)))
    views = tuple(View(f"cam{i}", "input", c, f"cam{i}.mp4") for i, c in enumerate(cameras))
    scene = Scene(Path("."), 30.0, 12, views, Volume((-0.35, -0.1, -0.35), (0.35, 0.5, 0.35)), None)
    for tilt, start in ((20.0, 0), (20.0, 2), (60.0, 0)):
        direction = np.array([np.sin(np.radians(tilt)), np.cos(np.radians(tilt)), 0.0])
        obs = Observations(tuple(v.name for v in views), cameras, 0, _jet_video(cameras, direction, start, 12))
        found = find_source(scene, obs, 0.01, 0.01, Source((0.0, -0.1, 0.0), 0.02))
        assert abs(found.record["motion_degrees_from_up"] - tilt) < 12, found.record
        if tilt < PLUME_CONE_DEG and start == 0:
            assert found.source.direction == UP and found.record["degrees_from_up"] == 0.0, found.record
            assert "a developed plume" in found.record["direction"]
        else:
            assert _angle(found.source.direction, direction) < 12 and found.record["direction"] == "centroid motion"
        assert np.linalg.norm(np.asarray(found.source.center)) < 0.04, found.source  # the nozzle is at the origin
        assert found.source.speed > 0.3


def test_initial_look_is_fitted_where_the_smoke_first_shows(tmp_path, ti_engine):
    """A jet switched on at frame 2: frame 0 shows nothing, so a look fitted there would be invisible (opacity near
    0); it is fitted to frame 2's hull instead and comes out near the jet's own look."""
    from fluidnexus.recon.fit import Views, fit_look
    from fluidnexus.recon.run import _initial_look

    direction = np.array([1.0, 0.25, -0.3])
    cameras = tuple(Camera.look_at(48, 48, 55.0, eye, (0.15, 0.0, 0.0))
                    for eye in ((0.15, 0.2, 1.0), (1.1, 0.3, 0.2), (-0.6, 0.4, -0.7)))
    video = _jet_video(cameras, direction, start=2, frames=6)
    views = tuple(View(f"cam{i}", "input", c, f"cam{i}.mp4") for i, c in enumerate(cameras))
    scene = Scene(tmp_path, 30.0, 6, views, Volume((-0.2, -0.3, -0.3), (0.5, 0.3, 0.3)), None)
    obs = Observations(tuple(v.name for v in views), cameras, 0, video)
    found = find_source(scene, obs, 0.02, 0.02, Source((0.15, -0.3, 0.0), 0.02))
    assert found.smoke_frame == 2 and len(found.smoke_hull) >= 8 and len(found.hull_points) == 0
    cfg = ReconConfig(frames=(0, 6), initial_look="fit", views_per_iter=3)
    at_zero = fit_look(torch.as_tensor(found.smoke_hull), Views(cameras, torch.as_tensor(video[:, 0]), ()), cfg,
                       torch.Generator().manual_seed(0))
    assert at_zero[1] < 0.02  # the premise: fitted to frame 0, the look is invisible
    look = _initial_look(scene, cfg, obs, found, tmp_path, resume=False)
    assert look.opacity0 > 0.05 and look.color0 > 0.3, (look.color0, look.opacity0)
    # no smoke in any frame: the constants are kept
    empty = find_source(scene, replace(obs, images=np.zeros_like(video)), 0.02, 0.02, Source((0.15, -0.3, 0.0), 0.02))
    assert empty.smoke_frame is None
    kept = _initial_look(scene, cfg, replace(obs, images=np.zeros_like(video)), empty, tmp_path, resume=False)
    assert (kept.color0, kept.opacity0) == (cfg.color0, cfg.opacity0)
