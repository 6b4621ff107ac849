"""The learned backends on tiny random models built here, saved, and loaded through the real loading code."""
import numpy as np
import pytest

pytest.importorskip("diffusers")
pytest.importorskip("sentencepiece")

from fluidnexus.errors import InputError  # noqa: E402
from fluidnexus.gen.synthesizer import SynthesisInput, make_synthesizer  # noqa: E402

from gen.tiny_models import save_tiny_cogvideox, save_tiny_cogvideox_lora, save_tiny_zero123  # noqa: E402


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    root = tmp_path_factory.mktemp("tiny")
    cog = save_tiny_cogvideox(root)
    return {"zero123": save_tiny_zero123(root), "cogvideox": cog,
            "lora": save_tiny_cogvideox_lora(cog, root / "lora")}


def _cameras():
    from fluidnexus.camera import Camera

    a = Camera.look_at(18, 32, 30.0, [0.0, 0.2, 1.2], [0.0, 0.25, 0.0])
    b = Camera.look_at(18, 32, 30.0, [1.2 * np.sqrt(0.5), 0.2, 1.2 * np.sqrt(0.5)], [0.0, 0.25, 0.0])
    return a, b


def _zero123(folder):
    from fluidnexus.gen.zero123 import Zero123Config

    return make_synthesizer("zero123", weights=folder, config=Zero123Config(steps=3, resolution=16, device="cpu"))


def test_zero123_shapes_range_determinism(folders):
    from fluidnexus.scene import Source, Volume

    src, tgt = _cameras()
    video = np.random.default_rng(0).random((2, 32, 18, 1)).astype(np.float32)
    inp = SynthesisInput(video, src, Source((0, 0, 0), 0.02), Volume((-0.3, 0, -0.3), (0.3, 0.5, 0.3)))
    synth = _zero123(folders["zero123"])
    out = synth.synthesize(inp, tgt)
    assert out.shape == (2, 32, 18, 1) and out.dtype == np.float32
    assert 0.0 <= out.min() and out.max() <= 1.0 and out.std() > 0
    assert np.array_equal(out, synth.synthesize(inp, tgt))  # seeded
    assert not np.array_equal(out[0], out[1])  # a different frame (and seed) gives a different result


def test_zero123_pose_condition():
    from fluidnexus.gen.zero123 import relative_pose

    src, tgt = _cameras()
    pose = relative_pose(src, tgt, np.array([0.0, 0.25, 0.0]))
    assert pose[0] == pytest.approx(0.0, abs=1e-9) and pose[3] == pytest.approx(0.0, abs=1e-9)
    assert pose[1] == pytest.approx(np.sin(np.pi / 4)) and pose[2] == pytest.approx(np.cos(np.pi / 4))


def test_incomplete_folders_name_what_is_missing(folders, tmp_path):
    import shutil

    broken = tmp_path / "z"
    shutil.copytree(folders["zero123"], broken)
    shutil.rmtree(broken / "cc_projection")
    (broken / "unet" / "config.json").unlink()
    with pytest.raises(InputError) as err:
        _zero123(broken)
    assert "cc_projection/config.json" in str(err.value) and "unet/config.json" in str(err.value)
    with pytest.raises(InputError, match="model_index.json"):
        make_cogvideox(tmp_path)
    with pytest.raises(InputError, match="never downloads"):
        make_synthesizer("zero123")


def make_cogvideox(folder, lora=None, **options):
    from fluidnexus.gen.cogvideox import CogVideoXConfig
    from fluidnexus.gen.refiner import make_refiner

    config = CogVideoXConfig(**{"strength": 0.6, "steps": 4, "size": (32, 32), "window": 9, "prefix": 5,
                                "max_text_length": 16, "device": "cpu", **options})
    return make_refiner("cogvideox", weights=folder, lora=lora, config=config)


def test_cogvideox_long_video_shapes_determinism_prefix_and_lora(folders):
    video = np.random.default_rng(1).random((17, 12, 20, 1)).astype(np.float32)
    refiner = make_cogvideox(folders["cogvideox"])
    out = refiner.refine(video)
    assert out.shape == video.shape and out.dtype == np.float32
    assert 0.0 <= out.min() and out.max() <= 1.0
    # windows [0, 9), then 5 prefix frames + 4 new ones twice: every later window ends on its clean prefix
    assert len(refiner.windows) == 3 and refiner.windows[0]["prefix"] is None
    for record in refiner.windows[1:]:
        prefix = record["prefix"]
        assert prefix.shape[1] == 2  # 5 frames = 2 latent frames of the causal VAE
        assert np.array_equal(record["final"][:, :2].numpy(), prefix.numpy())
        assert not np.array_equal(record["final"][:, 2:].numpy(), np.zeros_like(record["final"][:, 2:].numpy()))
    assert np.array_equal(out, refiner.refine(video))  # seeded
    with_lora = make_cogvideox(folders["cogvideox"], lora=folders["lora"]).refine(video)
    assert np.abs(with_lora - out).max() > 1e-3
    assert refiner.provenance()["prefix"] == 5


def test_cogvideox_zero_strength_returns_the_input(folders):
    video = np.random.default_rng(2).random((9, 12, 20, 3)).astype(np.float32)
    out = make_cogvideox(folders["cogvideox"], strength=0.01).refine(video)
    assert np.array_equal(out, video)
