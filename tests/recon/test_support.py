"""Gas under the smoke (recon/support.py): a Gaussian with no physical particle within h gets one at rest under it,
so that stage 1 can move it; one that has gas gets none; nothing is seeded inside an obstacle; ``auto`` is on over
a backdrop and off on black."""
import json

import numpy as np
import torch
from click.testing import CliRunner

from fluidnexus_cli.main import main
from fluidnexus.recon.config import ReconConfig


def _smoke(x, p, dtype):
    from fluidnexus.recon.smoke import Smoke

    m = len(x)
    return Smoke(0, p, torch.zeros_like(p), torch.zeros(len(p), dtype=dtype), x, torch.full((m, 1), 0.7, dtype=dtype),
                 torch.full((m, 3), 0.003, dtype=dtype), torch.tensor([[1.0, 0, 0, 0]] * m, dtype=dtype),
                 torch.full((m,), 0.1, dtype=dtype))


def test_unsupported_gaussians_get_gas_and_stage_one_moves_them(ti_engine):
    from fluidnexus.engine import ModelConfig, SolverConfig, cylinder_lattice
    from fluidnexus.recon.fit import Views, fit_dynamics
    from fluidnexus.recon.support import support, unsupported
    from fluidnexus.recon.workspace import Workspace

    dtype = ti_engine.tensors.torch_dtype()
    spacing = 0.009
    cluster = torch.as_tensor(cylinder_lattice((0.0, 0.0), 0.03, 0.0, 0.03, spacing), dtype=dtype)
    far = torch.tensor([[0.3, 0.0, 0.0], [0.3, 0.001, 0.001], [0.3 + 3 * spacing, 0.0, 0.0]], dtype=dtype)
    x = torch.cat([torch.tensor([[0.0, 0.015, 0.0]], dtype=dtype), far])  # one in the gas, three far from it
    smoke = _smoke(x, cluster.clone(), dtype)
    ws = Workspace(2 * len(cluster), 8, SolverConfig(dt=1 / 30), ModelConfig.scalarflow())
    assert unsupported(smoke.x, smoke.p, ws).tolist() == [False, True, True, True]
    seeded = support(smoke, ws, spacing)
    assert seeded == 2  # the first two far Gaussians share a cell of the physical lattice
    assert len(smoke.p) == len(cluster) + 2 and torch.all(smoke.u[-2:] == 0) and torch.all(smoke.age[-2:] == 0)
    cells = (np.floor(np.array([0.3, 0.3 + 3 * spacing]) / spacing) + 0.5) * spacing  # the lattice cells' centres
    np.testing.assert_allclose(np.sort(smoke.p[-2:, 0].numpy()), cells, atol=1e-6)
    assert not unsupported(smoke.x, smoke.p, ws).any()
    assert support(smoke, ws, spacing) == 0  # nothing more where every Gaussian has gas
    # the seeded gas gives the far Gaussians the velocity stage 1 fits (here: a particle moved by hand)
    cfg = ReconConfig(dynamics_iters=0, lambda_visual_incomp=0.0)
    views = Views((), torch.zeros((0, 1, 1, 1), dtype=dtype))
    moved = _smoke(smoke.x, smoke.p, dtype)
    moved.u[-2:] = torch.tensor([0.0, 0.3, 0.0], dtype=dtype)
    step = fit_dynamics(moved, ws, views, cfg, torch.Generator())
    assert torch.all(step.x[1:, 1] > smoke.x[1:, 1])  # the far Gaussians move now


def test_nothing_is_seeded_inside_an_obstacle(ti_engine):
    from fluidnexus.engine import ModelConfig, SolverConfig
    from fluidnexus.engine.obstacle import SphereObstacle
    from fluidnexus.recon.support import support
    from fluidnexus.recon.workspace import Workspace

    dtype = ti_engine.tensors.torch_dtype()
    ws = Workspace(64, 8, SolverConfig(dt=1 / 30), ModelConfig.scalarflow())
    ws.set_obstacle(SphereObstacle((0.0, 0.0, 0.0), 0.05))
    x = torch.tensor([[0.0, 0.0505, 0.0], [0.02, 0.0475, 0.0]], dtype=dtype)  # on the ball's surface
    smoke = _smoke(x, torch.zeros((0, 3), dtype=dtype), dtype)
    assert support(smoke, ws, 0.009) >= 1
    assert torch.all(torch.linalg.norm(smoke.p, dim=1) >= 0.05 - 1e-6)


def test_auto_is_on_over_a_backdrop_only(tmp_path):
    from fluidnexus.recon.run import _physical_support
    from fluidnexus.scene import load_scene

    cfg = ReconConfig()
    assert cfg.physical_support == "auto"
    result = CliRunner().invoke(main, ["calibrate", "--sample", "scalarflow", "--out", str(tmp_path / "s")])
    assert result.exit_code == 0, result.output
    scene = load_scene(tmp_path / "s")
    assert _physical_support(scene, cfg).physical_support == "off"  # ScalarFlow's glow on black
    data = json.loads((tmp_path / "s" / "scene.json").read_text())
    data["backdrop_color"] = [1.0, 1.0, 1.0]
    (tmp_path / "s" / "scene.json").write_text(json.dumps(data))
    assert _physical_support(load_scene(tmp_path / "s"), cfg).physical_support == "on"
    assert _physical_support(scene, ReconConfig(physical_support="on")).physical_support == "on"
