"""The smoke layer of a single video over its plate: arrays with a known opacity and colour, then ``synth`` on a
scene with a plate and ``calibrate --video --plate``."""
import json
import shutil

import cv2
import numpy as np
import pytest

from fluidnexus.scene import load_scene
from fluidnexus.scenery.plate_store import read_image, read_plate
from fluidnexus.scenery.smoke_layer import MIN_CONTRAST, NoSmoke, smoke_layer
from fluidnexus.video import read_video, write_video
from tests.clirun import assert_clean_failure, invoke, ok
from tests.gen.test_gen_cli import tiny_scene

from .plate_scenes import backdrop, noise

WIDTH, HEIGHT, FRAMES = 32, 24, 8
SMOKE = {"bright": (0.95, 0.93, 0.9), "dark": (0.1, 0.12, 0.15)}  # on a dark / a bright textured backdrop
ALPHA_MAE = 0.015  # measured 0.0071 (bright smoke) and 0.0084 (dark smoke) with noise sigma 0.004
COLOR_ERROR = 0.01  # per channel; measured 0.0056 and 0.0052 (the bound's 99.9 % quantile takes some noise)


def opacity(seed: int = 3) -> np.ndarray:
    """[T, H, W] a textured blob drifting up and right, opaque (a = 1) in its core (1 % of the samples)."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float32)
    out = np.zeros((FRAMES, HEIGHT, WIDTH), np.float32)
    for t in range(FRAMES):
        blob = np.exp(-(((xx - WIDTH * (0.3 + 0.05 * t)) / 7) ** 2 + ((yy - HEIGHT * 0.6 + t) / 6) ** 2))
        out[t] = np.clip(1.3 * blob * (0.6 + 0.4 * noise(rng, HEIGHT, WIDTH)), 0, 1)
    return out


def composite(back, alpha, color, sigma=0.0):
    video = back * (1 - alpha[..., None]) + np.asarray(color, np.float32) * alpha[..., None]
    video += np.random.default_rng(1).normal(0, sigma, video.shape)
    return np.clip(video, 0, 1).astype(np.float32)


@pytest.mark.parametrize("kind", ["bright", "dark"])
def test_opacity_and_colour_are_recovered(kind):
    back = backdrop(7, "bright" if kind == "bright" else "dark", HEIGHT, WIDTH)  # scenes.BACKDROP: under that smoke
    alpha, color = opacity(), np.array(SMOKE[kind], np.float32)
    assert (alpha > 0.99).mean() > 0.005 and (alpha < 0.01).mean() > 0.2
    smoke = smoke_layer(composite(back, alpha, color, 0.004), back, np.ones((HEIGHT, WIDTH), np.float32))
    assert np.abs(smoke.color - color).max() < COLOR_ERROR
    assert np.abs(smoke.alpha - alpha).mean() < ALPHA_MAE
    np.testing.assert_allclose(smoke.layer, smoke.alpha[..., None] * smoke.color, atol=1e-6)  # premultiplied
    assert smoke.layer[alpha < 0.005].max() == 0  # no noise haze where there is (almost) no smoke
    assert smoke.ill_conditioned == 0


def test_smoke_between_the_backdrop_colours():
    """Grey smoke over a black and white checker: brighter than half the backdrop, darker than the other half."""
    yy, xx = np.mgrid[0:HEIGHT, 0:WIDTH]
    back = np.where(((yy // 4 + xx // 4) % 2 == 0)[..., None], 0.05, 0.95) * np.ones(3, np.float32)
    alpha, color = opacity(), np.array([0.5, 0.45, 0.4], np.float32)
    smoke = smoke_layer(composite(back, alpha, color), back.astype(np.float32), np.ones((HEIGHT, WIDTH), np.float32))
    assert np.abs(smoke.color - color).max() < COLOR_ERROR
    assert np.abs(smoke.alpha - alpha).mean() < ALPHA_MAE  # measured 0.0048


def test_ill_conditioned_pixels_and_unsure_plate():
    """Where the plate has the smoke's colour the smoke is invisible: opacity 0 there, the rest unharmed, the
    colour still found even with a wrong plate marked unsure elsewhere; gray footage (C = 1) works alike."""
    alpha, color = opacity(), np.array(SMOKE["bright"], np.float32)
    back = backdrop(7, "bright", HEIGHT, WIDTH)
    back[:, :8] = color
    video = composite(back, alpha, color)
    wrong, confidence = back.copy(), np.ones((HEIGHT, WIDTH), np.float32)
    wrong[16:, 24:], confidence[16:, 24:] = 0.6, 0.0
    smoke = smoke_layer(video, wrong, confidence)
    assert smoke.ill_conditioned == pytest.approx(8 / WIDTH, abs=0.01)
    assert smoke.alpha[:, :, :8].max() == 0
    assert np.abs(smoke.alpha - alpha)[:, :16, 8:].mean() < ALPHA_MAE  # measured 0.0019
    assert np.abs(smoke.color - color).max() < COLOR_ERROR
    gray = backdrop(7, "dark", HEIGHT, WIDTH)[..., :1]
    smoke = smoke_layer(composite(gray, alpha, [0.1]), gray, np.ones((HEIGHT, WIDTH), np.float32))
    assert smoke.layer.shape == (FRAMES, HEIGHT, WIDTH, 1) and abs(smoke.color[0] - 0.1) < COLOR_ERROR
    assert np.abs(smoke.alpha - alpha).mean() < ALPHA_MAE  # measured 0.0038
    assert MIN_CONTRAST == 0.1  # docs/background.md states it


def test_smoke_that_is_never_opaque_needs_its_colour():
    """White smoke at most 0.6 opaque over a textured backdrop: taken as opaque, its densest part gives a colour
    too dark and a layer with the backdrop's texture in it; given the colour, the layer is the smoke."""
    back = backdrop(7, "dark", HEIGHT, WIDTH)
    alpha, white = 0.6 * opacity(), np.ones(3, np.float32)
    video, sure = composite(back, alpha, white), np.ones((HEIGHT, WIDTH), np.float32)
    truth = alpha[..., None] * white
    guessed, given = smoke_layer(video, back, sure), smoke_layer(video, back, sure, white)
    assert guessed.color.max() < 0.95  # a mix of white and the backdrop behind the densest smoke: 0.90-0.92
    np.testing.assert_array_equal(given.color, white)
    assert np.abs(given.alpha - alpha).mean() < ALPHA_MAE  # measured 0.0106: the noise floor cuts thin smoke
    assert np.abs(given.layer - truth).mean() < 0.3 * np.abs(guessed.layer - truth).mean()  # 0.011 against 0.047


def test_the_colour_lies_beyond_the_samples():
    """White smoke at most 0.6 opaque, densest over the dark end of a gray ramp (0.2 to 0.9) and thin over the
    bright end: the densest smoke alone gives a dark mix (0.70); no sample may be more than opaque, so the colour
    is at least the brightest smoke seen, and the layer is nearer the smoke."""
    x = np.linspace(0, 1, WIDTH, dtype=np.float32)
    back = np.repeat((0.2 + 0.7 * x)[None, :, None], HEIGHT, axis=0)
    rng = np.random.default_rng(3)
    alpha = np.stack([0.6 * np.exp(-((x - 0.05 * t / FRAMES) / 0.6) ** 2) * (0.7 + 0.3 * noise(rng, HEIGHT, WIDTH))
                      for t in range(FRAMES)])
    video = composite(back, alpha, [1.0], 0.004)
    smoke = smoke_layer(video, back, np.ones((HEIGHT, WIDTH), np.float32))
    seen = video[video - back > 0.02]
    assert smoke.color[0] >= np.quantile(seen, 0.999) - 1e-6  # measured 0.853; the densest smoke's median: 0.696
    raw = (video - back)[..., 0] / (smoke.color[0] - back[..., 0])
    assert (raw[video[..., 0] - back[..., 0] > 0.02] > 1).mean() <= 0.002  # all but the 0.1 % quantile: 0.1 %
    assert np.abs(smoke.layer[..., 0] - alpha).mean() < 0.08  # measured 0.061; the densest's median: 0.144


def test_no_smoke_is_refused():
    back = backdrop(7, "dark", HEIGHT, WIDTH)
    with pytest.raises(NoSmoke):
        smoke_layer(np.repeat(back[None], 4, axis=0), back, np.ones((HEIGHT, WIDTH), np.float32))


# ---- synth on a scene with a plate ----------------------------------------------------------------------
TINT = np.array([1.0, 0.95, 0.9], np.float32)


def plated_scenes(tmp_path):
    """Three copies of a tiny scene cut from the ScalarFlow sample (input train02, novel train00 and train04): the
    smoke alone over black (``clean``: opacity twice the sample's brightness, so that the densest tenth of the smoke
    is opaque; colour TINT); that smoke over a textured backdrop (``raw``); the same with the backdrop as train02's
    plate (``plated``)."""
    clean = tiny_scene(tmp_path / "clean")
    alpha = np.clip(2 * read_video(clean / "videos/train02.mp4", channels=1)[..., 0], 0, 1)
    back = backdrop(7, "bright", *alpha.shape[1:])
    write_video(clean / "videos/train02.mp4", alpha[..., None] * TINT, 30.0, crf=12)
    shutil.copytree(clean, tmp_path / "raw")
    write_video(tmp_path / "raw/videos/train02.mp4", back * (1 - alpha[..., None]) + TINT * alpha[..., None], 30.0,
                crf=12)
    shutil.copytree(tmp_path / "raw", tmp_path / "plated")
    cv2.imwrite(str(tmp_path / "plate.png"), np.rint(back[..., ::-1] * 65535).astype(np.uint16))
    ok("background", tmp_path / "plated", "--plate", f"train02={tmp_path / 'plate.png'}")
    return clean, tmp_path / "raw", tmp_path / "plated"


def test_synth_writes_smoke_layers_over_black(tmp_path):
    scenes = plated_scenes(tmp_path)
    for root in scenes:
        ok("synth", root)
    clean, raw, plated = (load_scene(root) for root in scenes)
    for name in ("train00", "train04"):
        truth, over_raw, layer = (read_video(s.video_path(s.view(name))) for s in (clean, raw, plated))
        empty = truth.max(axis=-1) < 0.02  # no smoke in the novel view synthesised from the smoke alone
        assert empty.mean() > 0.3
        assert over_raw[empty].mean() > 0.1  # synthesised from the raw frames: the backdrop's texture shows
        assert layer[empty].mean() < 0.005  # from the smoke layer: black (measured 0.00014-0.00028)
        assert np.abs(layer - truth).mean() < 0.05 * np.abs(over_raw - truth).mean()  # measured 0.3 %
        assert np.abs(layer - truth)[~empty].mean() < 0.1 * truth[~empty].mean()  # the smoke kept: measured 5 %
        record = plated.view(name).provenance["smoke_layer"]
        assert record["over"] == "black" and record["input_plate"] == "backgrounds/train02.png"
        # measured 0.027, H.264 chroma (the median alone: 0.022; a per-channel bound took the chroma error: 0.045)
        assert np.abs(np.array(record["smoke_color"]) - TINT).max() < 0.05
        assert "smoke_layer" not in raw.view(name).provenance
    ok("refine", plated.root)  # keeps the record with the refined video
    assert load_scene(plated.root).view("train00").provenance["smoke_layer"] == record
    assert record["smoke_color_from"] == "estimated"


def test_synth_takes_the_smoke_colour_when_known(tmp_path):
    """``--smoke-color`` replaces the estimate (recorded as such); a bad value, or a colour for an input view
    without a plate, stops synth in one line before anything is written."""
    clean, raw, plated = plated_scenes(tmp_path)
    ok("synth", plated, "--smoke-color", ",".join(str(v) for v in TINT))
    record = load_scene(plated).view("train00").provenance["smoke_layer"]
    assert record["smoke_color_from"] == "--smoke-color"
    np.testing.assert_allclose(record["smoke_color"], TINT, atol=1e-4)
    for bad in ("white", "1,1", "1.2,1,1"):
        assert_clean_failure(invoke("synth", clean, "--smoke-color", bad), "--smoke-color")
    before = (raw / "scene.json").read_text()
    assert_clean_failure(invoke("synth", raw, "--smoke-color", "1,1,1"), "--smoke-color")
    assert (raw / "scene.json").read_text() == before and not list((raw / "videos").glob("*_synth.mp4"))


# ---- calibrate --video --plate --------------------------------------------------------------------------


def calibrate_video(video, out, *extra):
    return invoke("calibrate", "--video", video, "--fov-deg", 50, "--views", 3, "--out", out, *extra)


def test_calibrate_video_writes_the_plate_as_background_does(tmp_path, make_video):
    video = make_video(tmp_path / "phone.mp4", frames=6, width=24, height=32, channels=3)
    cv2.imwrite(str(tmp_path / "wall.png"), np.random.default_rng(0).integers(0, 256, (32, 24, 3), np.uint8))
    assert calibrate_video(video, tmp_path / "a", "--plate", tmp_path / "wall.png").exit_code == 0
    scene = load_scene(tmp_path / "a")
    plate, confidence = read_plate(scene, "phone")
    np.testing.assert_array_equal(plate, read_image(tmp_path / "wall.png"))
    assert np.all(confidence == 1) and scene.backgrounds["phone"].source == "plate"
    assert calibrate_video(video, tmp_path / "b").exit_code == 0  # without --plate: no plate, as before
    assert not load_scene(tmp_path / "b").backgrounds and not (tmp_path / "b/backgrounds").exists()
    ok("background", tmp_path / "b", "--plate", f"phone={tmp_path / 'wall.png'}")
    for name in ("phone.png", "phone.confidence.png", "sheet.png"):
        assert (tmp_path / "a/backgrounds" / name).read_bytes() == (tmp_path / "b/backgrounds" / name).read_bytes()
    records = [json.loads((tmp_path / s / "scene.json").read_text())["backgrounds"] for s in "ab"]
    assert records[0] == records[1]


def test_calibrate_refuses_bad_plates(tmp_path, make_video):
    video = make_video(tmp_path / "phone.mp4", frames=4, width=24, height=32, channels=3)
    cv2.imwrite(str(tmp_path / "small.png"), np.zeros((16, 24, 3), np.uint8))
    (tmp_path / "broken.png").write_bytes(b"not an image" * 20)
    out = tmp_path / "s"
    assert_clean_failure(calibrate_video(video, out, "--plate", tmp_path / "small.png"),
                         "small.png", "--plate", "24x16", "24x32")
    assert_clean_failure(calibrate_video(video, out, "--plate", tmp_path / "broken.png"),
                         "broken.png", "--plate", "cannot be decoded")
    assert_clean_failure(calibrate_video(video, out, "--plate", tmp_path / "none.png"),
                         "none.png", "--plate", "file not found")
    assert_clean_failure(invoke("calibrate", "--sample", "scalarflow", "--plate", tmp_path / "small.png", "--out",
                                out), "--plate", "--video only")
    assert not out.exists()
