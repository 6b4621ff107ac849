"""Stage 1 moves the visual particles with the physical particles the frame keeps: a particle the frame drops
(isolated, out of the volume) moves no Gaussian, so the saved velocity field is exactly the one that moved them
and eval's re-simulation replays a run."""
import numpy as np
import torch

from fluidnexus.recon.config import ReconConfig


def test_a_dropped_particle_moves_no_visual_particle(ti_engine):
    from fluidnexus.engine import ModelConfig, SolverConfig, cylinder_lattice
    from fluidnexus.recon.fit import Views, fit_dynamics
    from fluidnexus.recon.smoke import Smoke
    from fluidnexus.recon.workspace import Workspace

    dtype = ti_engine.tensors.torch_dtype()
    cluster = torch.as_tensor(cylinder_lattice((0.0, 0.0), 0.03, 0.0, 0.03, 0.009), dtype=dtype)
    lone = torch.tensor([[0.3, 0.0, 0.0]], dtype=dtype)  # no neighbour within h: isolated
    p = torch.cat([cluster, lone])
    u = torch.zeros_like(p)
    u[-1] = torch.tensor([0.0, 0.6, 0.0])
    x = torch.tensor([[0.3, 0.001, 0.0], [0.0, 0.015, 0.0]], dtype=dtype)  # beside the lone one; in the cluster
    smoke = Smoke(0, p, u, torch.zeros(len(p), dtype=dtype), x, torch.full((2, 1), 0.7, dtype=dtype),
                  torch.full((2, 3), 0.003, dtype=dtype), torch.tensor([[1.0, 0, 0, 0]] * 2, dtype=dtype),
                  torch.full((2,), 0.1, dtype=dtype))
    ws = Workspace(4 * len(p), 8, SolverConfig(dt=1 / 30), ModelConfig.scalarflow())
    cfg = ReconConfig(dynamics_iters=0, lambda_visual_incomp=0.0)
    views = Views((), torch.zeros((0, 1, 1, 1), dtype=dtype))
    kept = fit_dynamics(smoke, ws, views, cfg, torch.Generator(), keep=lambda q: ~ws.isolated(q))
    assert len(kept.p) == len(cluster) and len(kept.age) == len(cluster)
    np.testing.assert_array_equal(kept.x[0].numpy(), x[0].numpy())  # the dropped particle moved nothing
    everything = fit_dynamics(smoke, ws, views, cfg, torch.Generator())
    assert len(everything.p) == len(p)
    assert everything.x[0, 1] > x[0, 1] + 0.01  # kept, the lone particle carries its Gaussian up
