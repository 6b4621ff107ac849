"""Tiny randomly initialised diffusers models saved to a folder, for the learned backends' tests (CPU, seconds)."""
from __future__ import annotations

from pathlib import Path

WORDS = ("a plume of white smoke rises and swirls against a black background thin gray wisps curl upward "
         "the fluid flows slowly in still air").split()


def _tokenizer(folder: Path):
    """A T5 tokenizer with a sentencepiece model trained here on a few words (nothing downloaded)."""
    import sentencepiece as spm
    from transformers import T5Tokenizer

    folder.mkdir(parents=True, exist_ok=True)
    lines = [" ".join(WORDS[i:] + WORDS[:i]) for i in range(len(WORDS))]
    spm.SentencePieceTrainer.train(sentence_iterator=iter(lines), model_prefix=str(folder / "spiece"),
                                   vocab_size=40, model_type="unigram", pad_id=0, eos_id=1, unk_id=2, bos_id=-1,
                                   minloglevel=2)
    return T5Tokenizer(vocab_file=str(folder / "spiece.model"), extra_ids=0, legacy=True)


def save_tiny_cogvideox(root: Path) -> Path:
    """A complete CogVideoX V2V folder: 1-layer transformer, 8-channel VAE, 1-layer T5, local tokenizer."""
    import torch
    from diffusers import (AutoencoderKLCogVideoX, CogVideoXDDIMScheduler, CogVideoXTransformer3DModel,
                           CogVideoXVideoToVideoPipeline)
    from transformers import T5Config, T5EncoderModel

    torch.manual_seed(0)
    transformer = CogVideoXTransformer3DModel(
        num_attention_heads=2, attention_head_dim=8, in_channels=4, out_channels=4, time_embed_dim=4,
        text_embed_dim=16, num_layers=1, sample_width=8, sample_height=8, sample_frames=9, patch_size=2,
        temporal_compression_ratio=4, max_text_seq_length=16)
    vae = AutoencoderKLCogVideoX(
        in_channels=3, out_channels=3, down_block_types=("CogVideoXDownBlock3D",) * 3,
        up_block_types=("CogVideoXUpBlock3D",) * 3, block_out_channels=(8, 8, 8), latent_channels=4,
        layers_per_block=1, norm_num_groups=2, temporal_compression_ratio=4)
    text_encoder = T5EncoderModel(T5Config(vocab_size=64, d_model=16, d_kv=8, d_ff=32, num_layers=1,
                                           num_heads=2, relative_attention_num_buckets=8))
    tokenizer = _tokenizer(root / "_spm")
    scheduler = CogVideoXDDIMScheduler(timestep_spacing="trailing")
    pipe = CogVideoXVideoToVideoPipeline(tokenizer=tokenizer, text_encoder=text_encoder, vae=vae,
                                         transformer=transformer, scheduler=scheduler)
    pipe.save_pretrained(root / "cogvideox")
    return root / "cogvideox"


def save_tiny_cogvideox_lora(pipe_root: Path, out: Path) -> Path:
    """A LoRA for the tiny transformer with non-zero B matrices (so it changes the output)."""
    import torch
    from diffusers import CogVideoXVideoToVideoPipeline
    from peft import LoraConfig
    from peft.utils import get_peft_model_state_dict

    pipe = CogVideoXVideoToVideoPipeline.from_pretrained(pipe_root)
    pipe.transformer.add_adapter(LoraConfig(r=4, lora_alpha=4, target_modules=["to_q", "to_k", "to_v", "to_out.0"],
                                            init_lora_weights=False))
    torch.manual_seed(1)
    with torch.no_grad():
        for name, p in pipe.transformer.named_parameters():
            if "lora_" in name:
                p.normal_(0, 0.5)
    CogVideoXVideoToVideoPipeline.save_lora_weights(out, transformer_lora_layers=get_peft_model_state_dict(
        pipe.transformer))
    return out


def save_tiny_zero123(root: Path, embed: int = 32) -> Path:
    """A complete Zero123 folder: 2-level UNet (8 in-channels), 2-level VAE, 1-layer CLIP vision, projection."""
    import torch
    from diffusers import AutoencoderKL, DDIMScheduler, UNet2DConditionModel
    from transformers import CLIPVisionConfig, CLIPVisionModelWithProjection

    from fluidnexus.gen.zero123 import camera_projection_class

    torch.manual_seed(0)
    folder = root / "zero123"
    UNet2DConditionModel(sample_size=8, in_channels=8, out_channels=4, layers_per_block=1,
                         block_out_channels=(32, 32), norm_num_groups=8, cross_attention_dim=embed,
                         attention_head_dim=8, down_block_types=("CrossAttnDownBlock2D", "DownBlock2D"),
                         up_block_types=("UpBlock2D", "CrossAttnUpBlock2D")).save_pretrained(folder / "unet")
    AutoencoderKL(in_channels=3, out_channels=3, latent_channels=4, block_out_channels=(8, 8), layers_per_block=1,
                  norm_num_groups=4, down_block_types=("DownEncoderBlock2D",) * 2,
                  up_block_types=("UpDecoderBlock2D",) * 2).save_pretrained(folder / "vae")
    CLIPVisionModelWithProjection(CLIPVisionConfig(hidden_size=32, intermediate_size=37, num_hidden_layers=1,
                                                   num_attention_heads=4, image_size=16, patch_size=8,
                                                   projection_dim=embed)).save_pretrained(folder / "image_encoder")
    camera_projection_class()(in_channel=embed + 4, out_channel=embed).save_pretrained(folder / "cc_projection")
    DDIMScheduler(num_train_timesteps=1000, beta_schedule="scaled_linear", beta_start=0.00085, beta_end=0.012,
                  clip_sample=False, set_alpha_to_one=False).save_pretrained(folder / "scheduler")
    return folder
