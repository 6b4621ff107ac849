import numpy as np
import pytest
import torch
from torch import nn

from fluidnexus.errors import InputError
from fluidnexus.lpips import BACKBONE_FILE, HEADS_FILE, load_weights, lpips

CONVS = {"features.0": (64, 3, 11), "features.3": (192, 64, 5), "features.6": (384, 192, 3),
         "features.8": (256, 384, 3), "features.10": (256, 256, 3)}


def save_weights(folder, seed=0):
    """Random weights in the layout of torchvision's alexnet-owt-7be5be79.pth and lpips' v0.1 alex.pth."""
    g = torch.Generator().manual_seed(seed)
    backbone = {}
    for key, (c_out, c_in, k) in CONVS.items():
        backbone[f"{key}.weight"] = torch.randn(c_out, c_in, k, k, generator=g) * (2.0 / (c_in * k * k)) ** 0.5
        backbone[f"{key}.bias"] = torch.randn(c_out, generator=g) * 0.05
    backbone["classifier.6.bias"] = torch.zeros(1000)  # the real file has the classifier too; it is ignored
    heads = {f"lin{i}.model.1.weight": torch.rand(1, c, 1, 1, generator=g) * 0.1
             for i, c in enumerate((64, 192, 384, 256, 256))}
    folder.mkdir(parents=True, exist_ok=True)
    torch.save(backbone, folder / BACKBONE_FILE)
    torch.save(heads, folder / HEADS_FILE)
    return backbone, heads


@pytest.fixture(scope="module")
def weights_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lpips")
    save_weights(folder)
    return folder


@pytest.fixture(scope="module")
def weights(weights_dir):
    return load_weights(weights_dir).to(dtype=torch.float64)


def image(seed, h=40, w=48, c=3):
    return torch.rand(h, w, c, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)


def reference_lpips(folder, img0, img1):
    """Straightforward LPIPS: torchvision's AlexNet `features` layout loaded from the file, then Eq. 1 in numpy."""
    features = nn.Sequential(
        nn.Conv2d(3, 64, 11, stride=4, padding=2), nn.ReLU(), nn.MaxPool2d(3, 2),
        nn.Conv2d(64, 192, 5, padding=2), nn.ReLU(), nn.MaxPool2d(3, 2),
        nn.Conv2d(192, 384, 3, padding=1), nn.ReLU(), nn.Conv2d(384, 256, 3, padding=1), nn.ReLU(),
        nn.Conv2d(256, 256, 3, padding=1), nn.ReLU(), nn.MaxPool2d(3, 2)).double()
    backbone = torch.load(folder / BACKBONE_FILE)
    features.load_state_dict({k[len("features."):]: v for k, v in backbone.items() if k.startswith("features.")})
    heads = torch.load(folder / HEADS_FILE)
    shift = torch.tensor([-0.030, -0.088, -0.188], dtype=torch.float64)
    scale = torch.tensor([0.458, 0.448, 0.450], dtype=torch.float64)
    taps = (1, 4, 7, 9, 11)  # relu1..relu5

    def feats(img):
        x = ((2 * img - 1 - shift) / scale).permute(2, 0, 1)[None]
        out = []
        with torch.no_grad():
            for idx, layer in enumerate(features[:12]):  # the last pool feeds only the classifier
                x = layer(x)
                if idx in taps:
                    out.append(x[0].numpy())  # [C, H, W]
        return out

    total = 0.0
    for layer, (f0, f1) in enumerate(zip(feats(img0), feats(img1))):
        w = heads[f"lin{layer}.model.1.weight"].double().numpy().reshape(-1)
        n0 = f0 / (np.sqrt((f0 ** 2).sum(axis=0)) + 1e-10)
        n1 = f1 / (np.sqrt((f1 ** 2).sum(axis=0)) + 1e-10)
        per_pixel = np.einsum("c,chw->hw", w, (n0 - n1) ** 2)
        total += per_pixel.mean()
    return total


def test_loads_the_documented_files_with_alexnet_shapes(weights_dir):
    w = load_weights(weights_dir)
    assert [tuple(t.shape) for t in w.conv_weights] == [(64, 3, 11, 11), (192, 64, 5, 5), (384, 192, 3, 3),
                                                        (256, 384, 3, 3), (256, 256, 3, 3)]
    assert [tuple(t.shape) for t in w.heads] == [(1, c, 1, 1) for c in (64, 192, 384, 256, 256)]
    backbone = torch.load(weights_dir / BACKBONE_FILE)
    torch.testing.assert_close(w.conv_biases[2], backbone["features.6.bias"], rtol=0, atol=0)


def test_matches_a_straightforward_reimplementation(weights_dir, weights):
    for seed in (1, 2):
        a, b = image(seed), image(seed + 10)
        value = float(lpips(weights, a, b))
        assert value > 0
        assert value == pytest.approx(reference_lpips(weights_dir, a, b), rel=1e-10)


def test_identical_images_give_zero_and_distance_is_symmetric(weights):
    a, b = image(3), image(4)
    assert float(lpips(weights, a, a)) == 0.0
    assert float(lpips(weights, a, b)) == pytest.approx(float(lpips(weights, b, a)), rel=1e-12)


def test_grows_with_added_noise(weights):
    a = image(5) * 0.5 + 0.25
    noise = torch.randn(a.shape, generator=torch.Generator().manual_seed(6), dtype=torch.float64)
    values = [float(lpips(weights, a, (a + s * noise).clamp(0, 1))) for s in (0.0, 0.01, 0.03, 0.1, 0.3)]
    assert values[0] == 0.0
    assert all(lo < hi for lo, hi in zip(values, values[1:])), values


def test_batches_gray_and_float32(weights_dir, weights):
    a, b = image(7, c=1), image(8, c=1)
    gray = float(lpips(weights, a, b))
    assert gray == pytest.approx(float(lpips(weights, a.expand(-1, -1, 3), b.expand(-1, -1, 3))), rel=1e-12)
    batch = lpips(weights, torch.stack([a, b]), torch.stack([b, b]))
    assert batch.shape == (2,)
    assert batch[0] == pytest.approx(gray, rel=1e-12) and batch[1] == 0.0
    f32 = lpips(load_weights(weights_dir), a.float(), b.float())
    assert f32.dtype == torch.float32 and float(f32) == pytest.approx(gray, rel=1e-4)


def test_bad_images_are_rejected(weights):
    with pytest.raises(InputError, match="at least 31x31"):
        lpips(weights, image(0, 30, 64), image(1, 30, 64))
    with pytest.raises(InputError, match="one shape"):
        lpips(weights, image(0), image(1, c=1))
    with pytest.raises(InputError, match="1 or 3 channels"):
        lpips(weights, image(0, c=4), image(1, c=4))
    assert float(lpips(weights, image(0, 31, 31), image(1, 31, 31))) > 0  # the smallest size works


def test_missing_files_keys_and_bad_shapes_are_named(tmp_path):
    with pytest.raises(InputError, match="weights folder not found"):
        load_weights(tmp_path / "nowhere")
    backbone, heads = save_weights(tmp_path / "w")
    (tmp_path / "w" / HEADS_FILE).unlink()
    with pytest.raises(InputError, match=f"{HEADS_FILE}: file not found"):
        load_weights(tmp_path / "w")
    torch.save({k: v for k, v in heads.items() if k != "lin3.model.1.weight"}, tmp_path / "w" / HEADS_FILE)
    with pytest.raises(InputError, match=r"alex\.pth: lin3\.model\.1\.weight: missing key"):
        load_weights(tmp_path / "w")
    torch.save(heads, tmp_path / "w" / HEADS_FILE)
    torch.save({**backbone, "features.8.weight": torch.zeros(256, 384, 5, 5)}, tmp_path / "w" / BACKBONE_FILE)
    with pytest.raises(InputError, match=r"features\.8\.weight: expected shape \(256, 384, 3, 3\), got"):
        load_weights(tmp_path / "w")
    (tmp_path / "w" / BACKBONE_FILE).write_bytes(b"junk")
    with pytest.raises(InputError, match="not a readable torch state dict"):
        load_weights(tmp_path / "w")
