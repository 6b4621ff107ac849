"""``fluidnexus refine``: make every ``novel`` video temporally coherent (paper Sec. 3.1, Eq. 2)."""
from __future__ import annotations

from pathlib import Path

import click

from fluidnexus.scene import load_scene

from .options import max_memory_option
from .synth import resolution_option


@click.command()
@click.argument("scene_dir", metavar="SCENE", type=click.Path(path_type=Path, file_okay=False))
@click.option("--method", type=click.Choice(["temporal", "cogvideox"]), default="temporal", show_default=True,
              help="temporal: optical-flow temporal filter; cogvideox: video SDEdit from local weights.")
@click.option("--weights", type=click.Path(path_type=Path), help="Local diffusers-format CogVideoX folder.")
@click.option("--lora", type=click.Path(path_type=Path), help="Local LoRA folder for CogVideoX.")
@click.option("--strength", type=float, default=0.5, show_default=True, help="cogvideox: SDEdit strength.")
@click.option("--steps", type=int, default=50, show_default=True, help="cogvideox: denoising steps.")
@click.option("--prompt", help="cogvideox: text prompt (default: a generic smoke-plume caption).")
@click.option("--prompt-embeds", type=click.Path(path_type=Path, dir_okay=False),
              help="cogvideox: torch-saved prompt embeddings [1, L, D] instead of a prompt.")
@click.option("--seed", type=int, default=0, show_default=True, help="cogvideox: noise seed.")
@click.option("--offload", is_flag=True, help="cogvideox: CPU offload of sub-models (small GPUs).")
@click.option("--device", type=click.Choice(["auto", "cpu", "cuda"]), default="auto", show_default=True,
              help="cogvideox: torch device.")
@resolution_option
@max_memory_option
def refine(scene_dir: Path, method: str, weights: Path | None, lora: Path | None, strength: float, steps: int,
           prompt: str | None, prompt_embeds: Path | None, seed: int, offload: bool, device: str, resolution: str,
           max_memory: str) -> None:
    """Refine every novel video of SCENE; the unrefined video is kept and named in the provenance.

    \b
    fluidnexus refine scene                      # temporal filter, runs anywhere
    fluidnexus refine scene --method cogvideox --weights ~/models/CogVideoX-5b --lora ~/models/lora --offload
    """
    from fluidnexus.gen.novel_views import refine_views
    from fluidnexus.memory import parse_limit
    from fluidnexus.working_resolution import resolve_resolution

    limit = parse_limit(max_memory)
    scene = load_scene(scene_dir)
    options = {}
    if method == "cogvideox":
        from fluidnexus.gen.cogvideox import DEFAULT_PROMPT, CogVideoXConfig

        config = CogVideoXConfig(strength=strength, steps=steps, prompt=prompt or DEFAULT_PROMPT,
                                 prompt_embeds=None if prompt_embeds is None else str(prompt_embeds), seed=seed,
                                 device=None if device == "auto" else device, offload=offload)
        options = {"weights": weights, "lora": lora, "config": config}
    refine_views(scene, method, options, resolve_resolution(resolution, scene), limit)
