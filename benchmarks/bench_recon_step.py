"""Where one stage-1 iteration of the reconstruction goes (docs/reconstruction.md, BENCHMARKS.md).

Loads frame T of a reconstruction run, builds the run's workspace and times, one by one, the pieces of a stage-1
iteration at frame T + 1 against the first view's real frame: the differentiable look-ahead PBF step (forward,
forward + backward of its density term), the render with the image loss (forward + backward), the advection of
the visual particles and the density term. Medians over --repeats calls after one warm-up call.

    python benchmarks/bench_recon_step.py --run RUN --frame 60
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from fluidnexus import engine


def median_ms(fn, repeats: int) -> float:
    fn()
    times = []
    for _ in range(repeats):
        tic = time.perf_counter()
        fn()
        times.append(time.perf_counter() - tic)
    return 1000.0 * float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", required=True, help="A reconstruction run folder.")
    ap.add_argument("--frame", type=int, required=True, help="Frame T of the run (T + 1 must be in the videos).")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--arch", choices=["cpu", "cuda"], default="cpu")
    args = ap.parse_args()
    engine.init(args.arch)
    from fluidnexus.engine.tensors import torch_dtype
    from fluidnexus.metrics import image_loss
    from fluidnexus.predict.rollout import RunContext
    from fluidnexus.recon.losses import density_loss
    from fluidnexus.recon.observations import load_observations
    from fluidnexus.recon.smoke import Smoke
    from fluidnexus.recon.workspace import Workspace
    from fluidnexus.runs import open_run

    run = open_run(args.run)
    ctx = RunContext.of(run)
    prev = Smoke.from_state(run.state(args.frame), torch_dtype())
    ws = Workspace(prev.p.shape[0] + 64, prev.x.shape[0] + 64, ctx.solver, ctx.model)
    obs = load_observations(run.scene(check_videos=False), (args.frame + 1, args.frame + 2), run.resolution,
                            run.channels)
    image, camera = torch.as_tensor(obs.frame(args.frame + 1)[0], dtype=ws.dtype), obs.cameras[0]
    rho0 = ctx.solver.rest_density
    p_sim, _ = ws.simulate(prev.p, prev.u, prev.age)

    def leaf():
        p = p_sim.clone().requires_grad_(True)
        return p, (p - prev.p) / ws.dt

    def lookahead(backward: bool):
        p, u = leaf()
        p_next, _ = ws.simulate(p, u, prev.age + ws.dt, differentiable=True)
        if backward:
            density_loss(engine.density_at(p_next, p_next, ws.next_query), rho0).backward()

    def render_loss():
        x = prev.x.clone().requires_grad_(True)
        rendered, _, _ = engine.render(camera, x, prev.scale, prev.rotation, prev.opacity, prev.color)
        image_loss(rendered, image).backward()

    def advection():
        p, u = leaf()
        engine.advect(prev.x, p, u, ws.dt, ws.advect_query).sum().backward()

    def density():
        p, _ = leaf()
        density_loss(engine.density_at(p, p, ws.density_query), rho0).backward()

    rows = {"lookahead_forward_ms": lambda: lookahead(False), "lookahead_forward_backward_ms": lambda: lookahead(True),
            "render_and_loss_forward_backward_ms": render_loss, "advection_forward_backward_ms": advection,
            "density_term_forward_backward_ms": density}
    result = {"run": args.run, "frame": args.frame, "physical": int(prev.p.shape[0]), "visual": int(prev.x.shape[0]),
              "image": [camera.width, camera.height], "torch_threads": torch.get_num_threads()}
    result.update({name: round(median_ms(fn, args.repeats), 1) for name, fn in rows.items()})
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
