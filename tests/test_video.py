"""Video IO: round trips, frame selection, resizing, channels, folders, AVI, streaming, bad input, atomic writes."""
from __future__ import annotations

import re
import subprocess

import cv2
import imageio_ffmpeg
import numpy as np
import pytest

from fluidnexus import video
from fluidnexus.errors import InputError
from fluidnexus.video import (VideoInfo, parse_frame_range, probe_video, read_video, write_frames,
                              write_video)

# H.264 at the default CRF 18 on smooth content, after the full-range -> video-range (16..235) round trip.
CODEC_MEAN_TOL = 2.0 / 255
CODEC_MAX_TOL = 16.0 / 255


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(1.0 / np.mean((a.astype(np.float64) - b) ** 2)))


def level(i: int) -> float:
    """The gray level of frame i of :func:`numbered_frames` (distinct per frame, codec-robust)."""
    return (20 + 10 * i) / 255.0


def numbered_frames(count: int, height: int = 32, width: int = 48) -> np.ndarray:
    """[count, H, W, 1] flat frames whose level identifies the frame index."""
    return np.stack([np.full((height, width, 1), level(i), np.float32) for i in range(count)])


def smooth_rgb(count: int, height: int = 32, width: int = 48) -> np.ndarray:
    """[count, H, W, 3] smooth colour gradients that change over time."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    frames = []
    for t in range(count):
        r = 0.2 + 0.6 * x / width
        g = 0.3 + 0.4 * y / height + 0.02 * t
        b = 0.8 - 0.5 * (x + y) / (width + height)
        frames.append(np.stack([r, g, b], axis=-1))
    return np.stack(frames).astype(np.float32)


def frame_levels(frames: np.ndarray) -> np.ndarray:
    return frames.reshape(len(frames), -1).mean(axis=1)


def ffmpeg_stream_line(path) -> str:
    """ffmpeg's description of the first video stream of ``path`` (codec, pixel format, size)."""
    done = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", str(path)],
                          capture_output=True, text=True)
    return next(line for line in done.stderr.splitlines() if "Video:" in line)


@pytest.fixture(scope="module")
def numbered_mp4(tmp_path_factory):
    """A 20-frame 48x32 H.264 MP4 whose frame i has gray level ``level(i)``."""
    path = tmp_path_factory.mktemp("numbered") / "numbered.mp4"
    return write_video(path, numbered_frames(20), fps=25)


# ---- round trips -------------------------------------------------------------------------------------------
def test_gray_round_trip_keeps_shape_and_values(tmp_path):
    y, x = np.mgrid[0:32, 0:48].astype(np.float32)
    frames = np.stack([0.5 + 0.3 * np.sin(2 * np.pi * (x + 2 * y + 3 * t) / 40) for t in range(12)])[..., None]
    path = write_video(tmp_path / "gray.mp4", frames, fps=30)
    back = read_video(path, gray=True)
    assert back.shape == (12, 32, 48, 1) and back.dtype == np.float32
    assert np.abs(back - frames).mean() < CODEC_MEAN_TOL
    assert psnr(back, frames) > 38.0
    # CRF 0 is lossless in luma: only 8-bit rounding and the video-range (16..235) mapping of yuv420p remain.
    lossless = read_video(write_video(tmp_path / "crf0.mp4", frames, fps=30, crf=0), gray=True)
    assert np.abs(lossless - frames).max() <= 2.0 / 255
    rgb = read_video(path)
    assert rgb.shape == (12, 32, 48, 3)
    # A gray video decodes with R = G = B, and gray=True returns exactly that channel.
    assert np.abs(rgb[..., 0] - rgb[..., 2]).max() <= 1.0 / 255 + 1e-6
    np.testing.assert_allclose(back[..., 0], rgb[..., 1], atol=1.0 / 255 + 1e-6)


def test_rgb_round_trip_keeps_channel_order(tmp_path):
    frames = smooth_rgb(8)
    back = read_video(write_video(tmp_path / "rgb.mp4", frames, fps=24), channels=3)
    assert back.shape == frames.shape
    assert np.abs(back - frames).mean() < CODEC_MEAN_TOL
    np.testing.assert_allclose(back.mean(axis=(0, 1, 2)), frames.mean(axis=(0, 1, 2)), atol=2.0 / 255)


def test_written_mp4_is_h264_yuv420p_faststart(tmp_path):
    path = write_video(tmp_path / "clip.mp4", smooth_rgb(3), fps=30)
    line = ffmpeg_stream_line(path)
    assert "h264" in line and "yuv420p" in line and "48x32" in line
    data = path.read_bytes()
    assert data.index(b"moov") < data.index(b"mdat")  # playable while downloading
    assert probe_video(path) == VideoInfo(frame_count=3, width=48, height=32, fps=30.0)


def test_odd_size_is_padded_by_repeating_the_edge(tmp_path):
    frames = smooth_rgb(4, height=33, width=47)
    back = read_video(write_video(tmp_path / "odd.mp4", frames, fps=10))
    assert back.shape == (4, 34, 48, 3)
    assert np.abs(back[:, :33, :47] - frames).mean() < CODEC_MEAN_TOL
    np.testing.assert_allclose(back[:, :33, 47], frames[:, :, 46], atol=CODEC_MAX_TOL)
    np.testing.assert_allclose(back[:, 33, :47], frames[:, 32], atol=CODEC_MAX_TOL)


def test_png_round_trip_is_exact_and_follows_the_quantization_convention(tmp_path):
    frames = np.array([-0.2, 0.0, 0.3, 128 / 255, 0.5, 1.0, 1.3], np.float32).reshape(7, 1, 1, 1)
    frames = np.broadcast_to(frames, (7, 4, 6, 1))
    write_frames(tmp_path / "seq", frames)
    assert sorted(p.name for p in (tmp_path / "seq").iterdir())[:2] == ["000000.png", "000001.png"]
    back = read_video(tmp_path / "seq")
    assert back.shape == (7, 4, 6, 1)
    expected = np.round(np.clip(frames, 0, 1) * 255) / 255
    np.testing.assert_array_equal(back, expected.astype(np.float32))
    assert back[3, 0, 0, 0] == np.float32(128 / 255) and back[0, 0, 0, 0] == 0 and back[6, 0, 0, 0] == 1


def test_jpg_round_trip_rgb(tmp_path):
    frames = smooth_rgb(3)
    back = read_video(write_frames(tmp_path / "seq", frames, fmt="jpg"))
    assert back.shape == frames.shape
    assert np.abs(back - frames).mean() < 2.0 / 255


# ---- frame selection, resizing, channels -------------------------------------------------------------------
@pytest.mark.parametrize("frames, stride, expected", [
    (None, 1, list(range(20))),
    (slice(3, 10), 2, [3, 5, 7, 9]),
    (range(4, 8), 1, [4, 5, 6, 7]),
    (slice(None, None, 5), 1, [0, 5, 10, 15]),
    (slice(-3, None), 1, [17, 18, 19]),
    (slice(0, 20, 2), 3, [0, 6, 12, 18]),
])
def test_frame_range_and_stride_select_the_right_frames(numbered_mp4, frames, stride, expected):
    clip = read_video(numbered_mp4, frames=frames, stride=stride, gray=True)
    assert clip.shape == (len(expected), 32, 48, 1)
    np.testing.assert_allclose(frame_levels(clip), [level(i) for i in expected], atol=1.5 / 255)


@pytest.mark.parametrize("frames", [slice(0, 50), slice(15, 25), slice(20, None), slice(5, 5), slice(-30, 4)])
def test_frame_range_beyond_the_video_is_refused(numbered_mp4, frames):
    with pytest.raises(InputError) as err:
        read_video(numbered_mp4, frames=frames)
    assert err.value.field == "frames" and err.value.path == str(numbered_mp4)
    assert "20 frames" in str(err.value) and f"{frames.start}:" in str(err.value)


def test_zero_or_negative_stride_is_refused(numbered_mp4):
    for stride in (0, -1):
        with pytest.raises(InputError, match="stride"):
            read_video(numbered_mp4, stride=stride)


def test_parse_frame_range():
    assert parse_frame_range("0:120") == slice(0, 120)
    assert parse_frame_range(":-1") == slice(None, -1)
    assert parse_frame_range("5:") == slice(5, None)
    with pytest.raises(InputError) as err:
        parse_frame_range("0-120")
    assert err.value.field == "--frames"


def test_resize_shrinks_by_area_average_and_enlarges(tmp_path):
    checker = (np.indices((16, 24)).sum(axis=0) % 2).astype(np.float32)[None, ..., None]
    folder = write_frames(tmp_path / "checker", np.concatenate([checker, 1 - checker]))
    half = read_video(folder, scale=0.5)
    assert half.shape == (2, 8, 12, 1)
    np.testing.assert_allclose(half, 0.5, atol=1e-6)  # each output pixel averages a 2x2 block
    sized = read_video(folder, size=(6, 4))
    assert sized.shape == (2, 4, 6, 1)
    np.testing.assert_allclose(sized, 0.5, atol=1e-6)
    big = read_video(folder, size=(48, 40))
    assert big.shape == (2, 40, 48, 1) and 0 <= big.min() and big.max() <= 1
    video_half = read_video(write_video(tmp_path / "v.mp4", smooth_rgb(2), 10), size=(24, 16))
    assert video_half.shape == (2, 16, 24, 3)
    with pytest.raises(InputError, match="either size or scale"):
        read_video(folder, size=(6, 4), scale=0.5)


def test_gray_of_a_colour_image_is_luma(tmp_path):
    rgb = np.zeros((1, 2, 3, 3), np.float32)
    rgb[0, 0, 0] = [1, 0, 0]
    rgb[0, 0, 1] = [0, 1, 0]
    rgb[0, 0, 2] = [0, 0, 1]
    rgb[0, 1] = [0.4, 0.4, 0.4]
    gray = read_video(write_frames(tmp_path / "c", rgb), gray=True)
    assert gray.shape == (1, 2, 3, 1)
    np.testing.assert_allclose(gray[0, 0, :, 0], [0.299, 0.587, 0.114], atol=1.0 / 255)
    np.testing.assert_allclose(gray[0, 1, :, 0], 102 / 255, atol=1e-7)  # R = G = B stays exact


def test_channels_option(tmp_path):
    folder = write_frames(tmp_path / "g", numbered_frames(2, 4, 4))
    assert read_video(folder).shape == (2, 4, 4, 1)  # a gray PNG keeps its single channel
    three = read_video(folder, channels=3)
    assert three.shape == (2, 4, 4, 3)
    np.testing.assert_array_equal(three[..., 0], three[..., 2])
    with pytest.raises(InputError) as err:
        read_video(folder, gray=True, channels=3)
    assert err.value.field == "channels"
    with pytest.raises(InputError, match="1 or 3"):
        read_video(folder, channels=2)


# ---- folders and other containers ----------------------------------------------------------------------------
def test_folder_frames_are_read_in_natural_order(tmp_path):
    for i in (1, 2, 10):
        cv2.imwrite(str(tmp_path / f"f{i}.png"), np.full((4, 4), 10 * i, np.uint8))
    (tmp_path / "notes.txt").write_text("not a frame")
    info = probe_video(tmp_path, fps=12)
    assert info == VideoInfo(frame_count=3, width=4, height=4, fps=12.0)
    assert probe_video(tmp_path).fps is None
    np.testing.assert_allclose(frame_levels(read_video(tmp_path)), np.array([10, 20, 100]) / 255, atol=1e-7)


def test_sixteen_bit_png_is_scaled_by_65535(tmp_path):
    cv2.imwrite(str(tmp_path / "a.png"), np.full((2, 2), 65535 // 5, np.uint16))
    np.testing.assert_allclose(read_video(tmp_path), (65535 // 5) / 65535, rtol=1e-6)


def test_jpg_folder_written_by_another_tool(tmp_path):
    for i in range(3):
        cv2.imwrite(str(tmp_path / f"{i:03d}.jpg"), np.full((8, 10, 3), (40 * i, 100, 200), np.uint8))
    clip = read_video(tmp_path)
    assert clip.shape == (3, 8, 10, 3)
    # cv2 wrote (B, G, R) = (40 i, 100, 200); in memory the order is RGB.
    np.testing.assert_allclose(clip[:, 0, 0], [[200 / 255, 100 / 255, 40 * i / 255] for i in range(3)],
                               atol=3 / 255)


def test_avi_read(tmp_path):
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 15, (40, 24))
    for i in range(12):
        writer.write(np.full((24, 40, 3), round(level(i) * 255), np.uint8))
    writer.release()
    assert probe_video(path) == VideoInfo(frame_count=12, width=40, height=24, fps=15.0)
    clip = read_video(path, frames=slice(2, 12), stride=3, gray=True)
    np.testing.assert_allclose(frame_levels(clip), [level(i) for i in (2, 5, 8, 11)], atol=2 / 255)


# ---- streaming: only the wanted frames are decoded -------------------------------------------------------------
class CountingCapture:
    """Wraps cv2.VideoCapture and counts decoded (grabbed) frames across all instances."""

    grabs = 0

    def __init__(self, *args):
        self._cap = REAL_CAPTURE(*args)

    def grab(self):
        CountingCapture.grabs += 1
        return self._cap.grab()

    def __getattr__(self, name):
        return getattr(self._cap, name)


REAL_CAPTURE = cv2.VideoCapture


@pytest.mark.parametrize("frames, decoded", [(slice(0, 3), 3), (slice(5, 8), 8), (slice(0, 20, 10), 11),
                                             (None, 20)])
def test_reading_stops_after_the_last_wanted_frame(numbered_mp4, monkeypatch, frames, decoded):
    monkeypatch.setattr(video.cv2, "VideoCapture", CountingCapture)
    CountingCapture.grabs = 0
    clip = read_video(numbered_mp4, frames=frames, gray=True)
    assert CountingCapture.grabs == decoded
    assert len(clip) == len(range(20)[frames or slice(None)])


def test_folder_reading_loads_only_the_wanted_images(tmp_path, monkeypatch):
    folder = write_frames(tmp_path / "seq", numbered_frames(10, 4, 4))
    loaded = []
    real_imread = cv2.imread
    monkeypatch.setattr(video.cv2, "imread", lambda name, *a: loaded.append(name) or real_imread(name, *a))
    clip = read_video(folder, frames=slice(6, 8))
    assert len(clip) == 2
    assert [n[-10:] for n in loaded] == ["000000.png", "000006.png", "000007.png"]  # first one: probe


# ---- bad input -------------------------------------------------------------------------------------------------
def test_missing_file(tmp_path):
    with pytest.raises(InputError) as err:
        read_video(tmp_path / "nope.mp4")
    assert err.value.path == str(tmp_path / "nope.mp4") and err.value.field == "video"
    assert "not found" in str(err.value)


def test_garbage_bytes(tmp_path):
    path = tmp_path / "garbage.mp4"
    path.write_bytes(np.random.default_rng(0).bytes(20000))
    with pytest.raises(InputError) as err:
        probe_video(path)
    assert err.value.path == str(path) and err.value.field == "video" and "\n" not in str(err.value)


def test_unsupported_suffix_and_empty_folder(tmp_path):
    (tmp_path / "clip.gif").write_bytes(b"GIF89a")
    with pytest.raises(InputError, match="unsupported file type"):
        probe_video(tmp_path / "clip.gif")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no PNG or JPG"):
        read_video(tmp_path / "empty")


def test_corrupt_or_mismatched_image_in_a_folder(tmp_path):
    folder = write_frames(tmp_path / "seq", numbered_frames(3, 4, 4))
    (folder / "000001.png").write_bytes(b"\x89PNG broken")
    with pytest.raises(InputError) as err:
        read_video(folder)
    assert err.value.path == str(folder / "000001.png") and err.value.field == "frame"
    cv2.imwrite(str(folder / "000001.png"), np.zeros((5, 4), np.uint8))
    with pytest.raises(InputError, match="4x5 but earlier frames are 4x4"):
        read_video(folder)


def _cut_in_half(src, dest):
    data = src.read_bytes()
    dest.write_bytes(data[: len(data) // 2])
    return dest


@pytest.fixture(scope="module")
def noisy_mp4(tmp_path_factory):
    """A 60-frame MP4 of noise (large enough that half its bytes hold some whole frames)."""
    frames = np.random.default_rng(1).random((60, 64, 64, 1), dtype=np.float32)
    return write_video(tmp_path_factory.mktemp("noisy") / "noisy.mp4", frames, fps=30)


def test_truncated_mp4_with_index_first_is_detected(noisy_mp4, tmp_path):
    half = _cut_in_half(noisy_mp4, tmp_path / "half.mp4")
    with pytest.raises(InputError) as err:
        read_video(half, frames=slice(0, 2))
    match = re.search(r"announced (\d+) frames, only (\d+) present", str(err.value))
    assert match and int(match[1]) == 60 and 0 < int(match[2]) < 60
    assert err.value.path == str(half) and err.value.field == "video"


def test_truncated_mp4_with_index_last_is_detected(noisy_mp4, tmp_path):
    index_last = tmp_path / "index_last.mp4"  # the usual layout of an MP4 recorded by a camera or by ffmpeg
    subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(noisy_mp4), "-c", "copy",
                    str(index_last)], check=True)
    assert index_last.read_bytes().index(b"mdat") < index_last.read_bytes().index(b"moov")
    with pytest.raises(InputError, match="not a readable video"):
        probe_video(_cut_in_half(index_last, tmp_path / "half.mp4"))


def test_truncation_is_also_caught_while_decoding(noisy_mp4, tmp_path, monkeypatch):
    half = _cut_in_half(noisy_mp4, tmp_path / "half.mp4")
    monkeypatch.setattr(video, "_count_packets", lambda path: 60)  # pretend the demuxer check passed
    with pytest.raises(InputError, match=r"announced 60 frames, decoded \d+"):
        read_video(half)


# ---- atomic writes ---------------------------------------------------------------------------------------------
def _failing_frames(good: int):
    for frame in smooth_rgb(good):
        yield frame
    raise RuntimeError("renderer crashed")


def test_failed_video_write_leaves_nothing(tmp_path):
    dest = tmp_path / "out.mp4"
    with pytest.raises(RuntimeError, match="renderer crashed"):
        write_video(dest, _failing_frames(3), fps=30)
    assert list(tmp_path.iterdir()) == []
    dest.write_bytes(b"previous")
    with pytest.raises(ValueError, match="NaN"):
        write_video(dest, np.full((2, 4, 4, 1), np.nan, np.float32), fps=30)
    assert dest.read_bytes() == b"previous" and len(list(tmp_path.iterdir())) == 1


def test_failed_frames_write_leaves_nothing(tmp_path):
    with pytest.raises(RuntimeError, match="renderer crashed"):
        write_frames(tmp_path / "seq", _failing_frames(3))
    assert list(tmp_path.iterdir()) == []


def test_write_rejects_bad_frames_and_fps(tmp_path):
    with pytest.raises(ValueError, match="C = 1 or 3"):
        write_video(tmp_path / "a.mp4", np.zeros((2, 4, 4, 2)), fps=30)
    with pytest.raises(ValueError, match="first frame's shape"):
        write_frames(tmp_path / "s", [np.zeros((4, 4, 1)), np.zeros((4, 6, 1))])
    with pytest.raises(ValueError, match="no frames"):
        write_video(tmp_path / "a.mp4", [], fps=30)
    with pytest.raises(InputError) as err:
        write_video(tmp_path / "a.mp4", np.zeros((2, 4, 4, 1)), fps=0)
    assert err.value.field == "fps"
    with pytest.raises(ValueError, match="fmt"):
        write_frames(tmp_path / "s", np.zeros((1, 4, 4, 1)), fmt="bmp")
    assert list(tmp_path.iterdir()) == []


def test_streamed_write_from_a_generator(tmp_path):
    frames = smooth_rgb(5)
    path = write_video(tmp_path / "gen.mp4", (f for f in frames), fps=30)
    assert probe_video(path).frame_count == 5
