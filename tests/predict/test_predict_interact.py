"""Wind and rigid obstacles in the rollout: direction, monotonicity, no particle inside, mesh == sphere."""
from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh

from fluidnexus.predict.rollout import RunContext, rollout, with_wind, workspace_for
from fluidnexus.recon.smoke import Smoke
from fluidnexus.runs import open_run
from fluidnexus.scenery.obstacles import make_obstacle

from .conftest import invoke, ok


def _start(run_dir):
    run = open_run(run_dir)
    return RunContext.of(run), Smoke.from_state(run.state(0), torch.float64)


def _centroid_x(run_dir, accel, frames=2):
    ctx, start = _start(run_dir)
    model = ctx.model if accel is None else with_wind(ctx.model, (accel, 0.0, 0.0), "uniform", 0.0, 1.0)
    last = list(rollout(start, frames, workspace_for(start, frames, ctx, model), ctx))[-1]
    return float(last.x[:, 0].mean()), float(last.p[:, 0].mean())


def test_wind_moves_the_plume_downwind_monotonically(start_run):
    base = _centroid_x(start_run, None)
    zero = _centroid_x(start_run, 0.0)
    weak = _centroid_x(start_run, 2.0)
    strong = _centroid_x(start_run, 6.0)
    assert zero == base  # a zero wind is no wind, bit for bit
    for k in range(2):  # visual and physical centroids
        assert base[k] < weak[k] < strong[k]
        assert strong[k] - base[k] > 2.0 * (weak[k] - base[k])  # roughly proportional to the strength


def test_height_profile_pushes_the_top_more(start_run):
    ctx, start = _start(start_run)
    y0 = ctx.source.center[1]
    model = with_wind(ctx.model, (4.0, 0.0, 0.0), "height", y0, 0.1)
    last = list(rollout(start, 2, workspace_for(start, 2, ctx, model), ctx))[-1]
    plain = list(rollout(start, 2, workspace_for(start, 2, ctx, ctx.model), ctx))[-1]
    shift = (last.x[:, 0] - plain.x[:, 0]).numpy()  # visual particles: same set with and without wind
    height = plain.x[:, 1].numpy()
    low, high = height < np.quantile(height, 0.2), height > np.quantile(height, 0.8)
    assert shift[high].mean() > 2.0 * max(shift[low].mean(), 1e-9)


def _ball_spec(ctx):
    cx, cy, cz = ctx.source.center
    return (cx, cy + 0.03, cz), 0.04


def test_no_particle_inside_the_ball_after_any_step(start_run):
    ctx, start = _start(start_run)
    center, r = _ball_spec(ctx)
    c = torch.tensor(center, dtype=torch.float64)
    assert ((start.p - c).norm(dim=1) < r).sum() > 10 and ((start.x - c).norm(dim=1) < r).sum() > 10
    obstacle, _ = make_obstacle(",".join(map(str, (*center, r))), None)
    frames = list(rollout(start, 4, workspace_for(start, 4, ctx, ctx.model), ctx, obstacle))
    for smoke in frames:
        assert (smoke.p - c).norm(dim=1).min() >= r * (1 - 1e-9)
        assert (smoke.x - c).norm(dim=1).min() >= r * (1 - 1e-9)
    free = list(rollout(start, 4, workspace_for(start, 4, ctx, ctx.model), ctx))
    assert (free[-1].p - c).norm(dim=1).min() < 0.5 * r  # without the ball the smoke would be inside it


def test_icosphere_mesh_matches_the_analytic_ball(start_run, tmp_path):
    ctx, start = _start(start_run)
    center, r = _ball_spec(ctx)
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=r)
    mesh.apply_translation(center)
    mesh.export(tmp_path / "ball.stl")
    ball, _ = make_obstacle(",".join(map(str, (*center, r))), None)
    grid, info = make_obstacle(None, tmp_path / "ball.stl")
    assert info["kind"] == "mesh" and info["faces"] == 320
    a = list(rollout(start, 1, workspace_for(start, 1, ctx, ctx.model), ctx, ball))[-1]
    b = list(rollout(start, 1, workspace_for(start, 1, ctx, ctx.model), ctx, grid))[-1]
    c = torch.tensor(center, dtype=torch.float64)
    assert (b.p - c).norm(dim=1).min() >= r - 1e-3  # within the facet and grid error of the sphere
    assert abs(a.p.shape[0] - b.p.shape[0]) <= 0.005 * a.p.shape[0]  # isolated-particle deletion may differ
    assert a.x.shape == b.x.shape
    gap = (a.x - b.x).norm(dim=1)  # facets (~0.5 mm sagitta at 320 faces) and grid error, through one PBF step
    assert float(gap.mean()) < 1.5e-3 and float(gap.quantile(0.95)) < 3e-3 and float(gap.max()) < 1e-2


@pytest.mark.parametrize("args, field", [
    (["--ball", "0.3,0.1,-0.2,0"], "--ball"),
    (["--ball", "0.3,0.1,-0.2,-0.05"], "--ball"),
    (["--ball", "0.3,0.1,-0.2"], "--ball"),
    (["--wind", "nan,0,0"], "--wind"),
    (["--wind", "1,0"], "--wind"),
    (["--wind", "1,0,0", "--frames", "0"], "--frames"),
    ([], "--wind/--ball/--mesh"),
])
def test_interact_rejects_bad_input(start_run, tmp_path, args, field):
    if "--frames" not in args:
        args = args + ["--frames", "2"]
    result = invoke("interact", start_run, "--out", tmp_path / "x", "--no-refit", *args)
    assert result.exit_code == 2, result.output
    assert field in result.output
    assert not (tmp_path / "x").exists()


def test_interact_rejects_bad_meshes(start_run, tmp_path):
    (tmp_path / "junk.obj").write_text("this is not a mesh\n")
    open_mesh = trimesh.creation.icosphere(subdivisions=1, radius=0.03)
    open_mesh.update_faces(np.arange(len(open_mesh.faces)) != 0)
    open_mesh.export(tmp_path / "open.obj")
    for name, words in (("junk.obj", "mesh"), ("open.obj", "not closed"), ("missing.stl", "not found")):
        result = invoke("interact", start_run, "--mesh", tmp_path / name, "--frames", 2, "--out", tmp_path / "x",
                        "--no-refit", "--arch", "cpu")
        assert result.exit_code == 2, result.output
        assert words in result.output and name in result.output
        assert not (tmp_path / "x").exists()


def test_interact_writes_side_by_side_videos(start_run, tmp_path):
    from fluidnexus.video import read_video

    ctx, _ = _start(start_run)
    center, r = _ball_spec(ctx)
    out = tmp_path / "ball"
    ok("interact", start_run, "--ball", ",".join(map(str, (*center, r))), "--wind", "1,0,0", "--frames", 2,
       "--out", out, "--no-refit", "--arch", "cpu")
    run = open_run(out)
    assert run.info["kind"] == "interact" and run.info["interaction"]["obstacle"]["kind"] == "ball"
    assert [t["kind"] for t in run.config["model"]["terms"]][-1] == "wind"
    videos = sorted(p.name for p in (out / "videos").glob("compare_*.mp4"))
    assert videos == ["compare_train00.mp4", "compare_train02.mp4"]
    frame = read_video(out / "videos" / "compare_train02.mp4")[0]
    half = (frame.shape[1] - 4) // 2
    # the ball is drawn opaque on the right (with) side only
    assert (frame[:, half + 4:] > 0.15).sum() > (frame[:, :half] > 0.15).sum() + 50
