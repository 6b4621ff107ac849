"""Video IO: read videos and frame folders into float arrays, write H.264 MP4 and PNG/JPG sequences.

A video inside the library is a float32 array ``[T, H, W, C]`` with values in [0, 1] and C = 1 (gray smoke)
or 3 (RGB), see docs/conventions.md. 8-bit files convert as ``x / 255`` on read and
``round(clip(x, 0, 1) * 255)`` on write (16-bit PNGs as ``x / 65535``).

Reading streams: frames are decoded one at a time (OpenCV's FFmpeg backend for MP4/MOV/AVI files, one image
file at a time for a folder of PNG/JPG frames), decoding stops after the last wanted frame, and only the wanted
frames are kept, in an output array allocated once at its final size.

Writing goes through the ffmpeg executable bundled with imageio-ffmpeg, which has libx264: H.264, yuv420p,
``+faststart`` MP4 plays in browsers (OpenCV's own writer cannot make H.264). yuv420p needs even sizes, so an odd
width or height is padded by one column or row that repeats the last one; reading such a file gives the padded
size. Every write is atomic (a temporary file or folder renamed into place), so a failed write leaves nothing.

Bad input (a missing file, an unreadable or truncated video, a frame range beyond the end) raises
:class:`fluidnexus.errors.InputError` naming the file and the field.
"""
from __future__ import annotations

import contextlib
import re
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator

import cv2
import imageio_ffmpeg
import numpy as np

from .atomic import atomic_dir, atomic_file
from .errors import InputError, require_positive

VIDEO_SUFFIXES = (".mp4", ".m4v", ".mov", ".avi")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
FRAME_FORMATS = ("png", "jpg")
JPEG_QUALITY = 95


@dataclass(frozen=True)
class VideoInfo:
    """What a video holds, read from its header.

    Attributes:
        frame_count: number of frames (checked against the frames actually present in the file).
        width, height: frame size in pixels.
        fps: frames per second; None for a folder of frames unless given.
    """

    frame_count: int
    width: int
    height: int
    fps: float | None


# ---------------------------------------------------------------------------------------------------------
# probing
# ---------------------------------------------------------------------------------------------------------
def probe_video(path: str | Path, fps: float | None = None) -> VideoInfo:
    """Read a video's frame count, size and frame rate without decoding its frames.

    For a video file the container's announced frame count is checked against the packets its demuxer
    actually finds (a stream copy, no decoding, a few milliseconds), so a truncated file is caught here.

    Args:
        path: an MP4/MOV/AVI file, or a folder of PNG/JPG frames (read in natural name order).
        fps: frame rate of a folder of frames (a video file's own rate wins; ignored for files).

    Returns:
        The :class:`VideoInfo`.

    Raises:
        InputError: the path is missing, not a supported video, unreadable or truncated.
    """
    path = _existing(path)
    if path.is_dir():
        files = image_files(path)
        first = _read_image(files[0])
        return VideoInfo(len(files), first.shape[1], first.shape[0],
                         None if fps is None else require_positive(fps, path, "fps"))
    present = _count_packets(path)  # first: ffmpeg rejects a corrupt file quietly, OpenCV would log noise
    cap = _open_capture(path)
    try:
        announced = int(round(cap.get(cv2.CAP_PROP_FRAME_COUNT)))
        info = VideoInfo(announced, int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)),
                         int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)), float(cap.get(cv2.CAP_PROP_FPS)))
    finally:
        cap.release()
    if info.frame_count <= 0 or info.width <= 0 or info.height <= 0 or not info.fps > 0:
        raise InputError(path, "video", "has no readable video stream (frame count, size or frame rate missing)")
    if present < announced:
        raise InputError(path, "video", f"truncated: announced {announced} frames, only {present} present")
    return info


def image_files(folder: str | Path) -> list[Path]:
    """The PNG/JPG files of a frame folder, in natural order (``f2.png`` before ``f10.png``).

    Raises:
        InputError: the folder holds no PNG or JPG file.
    """
    folder = Path(folder)
    files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES]
    if not files:
        raise InputError(folder, "video", "folder holds no PNG or JPG frames")
    return sorted(files, key=_natural_key)


def _natural_key(path: Path) -> list:
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", path.name)]


def _existing(path: str | Path) -> Path:
    path = Path(path)
    if not path.exists():
        raise InputError(path, "video", "file not found")
    if path.is_file() and path.suffix.lower() not in VIDEO_SUFFIXES:
        raise InputError(path, "video", f"unsupported file type {path.suffix!r}; expected one of "
                                        f"{', '.join(VIDEO_SUFFIXES)} or a folder of PNG/JPG frames")
    return path


def _open_capture(path: Path) -> cv2.VideoCapture:
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    if not cap.isOpened():
        cap.release()
        raise InputError(path, "video", "cannot be opened as a video (unreadable, corrupt or truncated file)")
    return cap


def _count_packets(path: Path) -> int:
    """Number of video packets the demuxer reads from ``path`` (ffmpeg stream copy to a null sink)."""
    cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-nostdin", "-v", "error", "-nostats", "-i", str(path),
           "-map", "0:v:0", "-c", "copy", "-f", "null", "-progress", "pipe:1", "-"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    counts = re.findall(r"^frame=(\d+)$", done.stdout, flags=re.MULTILINE)
    if not counts or int(counts[-1]) == 0:
        reason = (done.stderr.strip().splitlines() or ["no video frames found"])[-1]
        raise InputError(path, "video", f"not a readable video (corrupt or truncated file): {reason}")
    return int(counts[-1])


# ---------------------------------------------------------------------------------------------------------
# reading
# ---------------------------------------------------------------------------------------------------------
def read_video(path: str | Path, frames: slice | range | None = None, stride: int = 1,
               size: tuple[int, int] | None = None, scale: float | None = None, gray: bool = False,
               channels: int | None = None) -> np.ndarray:
    """Read (part of) a video or frame folder into a float32 array.

    Args:
        path: an MP4/MOV/AVI file or a folder of PNG/JPG frames.
        frames: half-open frame range as a ``slice`` or ``range`` (None: all frames). Negative bounds count
            from the end as in Python; a range reaching beyond the video is an error, never silently cut.
            Its step multiplies ``stride``.
        stride: keep every ``stride``-th frame of the range.
        size: output (width, height) in pixels; shrinking uses area averaging, enlarging bilinear.
        scale: output size as a factor of the input size (rounded); exclusive with ``size``.
        gray: return C = 1 (luma ``0.299 R + 0.587 G + 0.114 B``; exact for gray videos with R = G = B).
        channels: 1 or 3 to force the channel count (3 repeats a gray channel); None keeps the file's own
            (3 for video files, 1 or 3 for images; an alpha channel is dropped). ``gray`` means ``channels=1``.

    Returns:
        [T, H, W, C] float32 in [0, 1], T = number of wanted frames.

    Raises:
        InputError: missing/unreadable/truncated input, or a frame range, size or channel count that does not fit.
    """
    path = _existing(path)
    info = probe_video(path)
    wanted = frame_range(frames, stride, info.frame_count, path)
    out_w, out_h = _output_size(info.width, info.height, size, scale, path)
    out_c = _output_channels(gray, channels, path)
    files = image_files(path) if path.is_dir() else None
    decoded = _decode_folder(files, wanted) if files else _decode_file(path, wanted, info.frame_count)
    video = None
    for k, raw in enumerate(decoded):
        frame = _to_float(raw, out_w, out_h, out_c)
        if video is None:  # allocated once, at its final size, when the channel count is known
            video = np.empty((len(wanted),) + frame.shape, np.float32)
        video[k] = frame
    return video


def frame_range(frames: slice | range | None, stride: int, count: int, path=None) -> range:
    """Resolve a half-open frame selection against a video of ``count`` frames.

    Args:
        frames: ``slice``/``range`` (negative bounds count from the end) or None for all frames.
        stride: step, multiplied with the step of ``frames``.
        count: number of frames in the video.
        path: the video, for error messages.

    Returns:
        The frame indices as a ``range`` inside [0, count).

    Raises:
        InputError: bounds beyond the video, an empty selection or a non-positive step (field ``frames``).
    """
    frames = slice(None) if frames is None else frames
    if not isinstance(frames, (slice, range)):
        raise InputError(path, "frames", f"expected a slice or range, got {frames!r}")
    step = (1 if frames.step is None else int(frames.step)) * int(stride)
    if step <= 0:
        raise InputError(path, "frames", f"stride must be a positive integer, got {step}")
    start = 0 if frames.start is None else int(frames.start)
    stop = count if frames.stop is None else int(frames.stop)
    start, stop = (start + count if start < 0 else start), (stop + count if stop < 0 else stop)
    shown = f"{'' if frames.start is None else frames.start}:{'' if frames.stop is None else frames.stop}"
    if not 0 <= start < stop <= count:
        raise InputError(path, "frames", f"range {shown} does not fit the video's {count} frames "
                                         "(half-open, must select at least one frame)")
    return range(start, stop, step)


def parse_frame_range(text: str) -> slice:
    """Parse a command-line frame range ``"START:STOP"`` (either may be empty or negative) into a slice.

    Raises:
        InputError: ``text`` is not of that form (field ``--frames``).
    """
    match = re.fullmatch(r"\s*(-?\d+)?\s*:\s*(-?\d+)?\s*", text)
    if match is None:
        raise InputError(None, "--frames", f"expected START:STOP (half-open, e.g. 0:120), got {text!r}")
    start, stop = (None if g is None else int(g) for g in match.groups())
    return slice(start, stop)


def _output_size(width: int, height: int, size, scale, path) -> tuple[int, int]:
    if size is not None and scale is not None:
        raise InputError(path, "size", "give either size or scale, not both")
    if size is not None:
        out = tuple(int(v) for v in size)
        if len(out) != 2 or min(out) <= 0:
            raise InputError(path, "size", f"expected (width, height) > 0, got {size!r}")
        return out
    if scale is not None:
        s = require_positive(scale, path, "scale")
        return max(1, round(width * s)), max(1, round(height * s))
    return width, height


def _output_channels(gray: bool, channels: int | None, path) -> int | None:
    if gray and channels not in (None, 1):
        raise InputError(path, "channels", f"gray=True gives 1 channel, but channels={channels} was asked")
    if channels not in (None, 1, 3):
        raise InputError(path, "channels", f"must be 1 or 3, got {channels!r}")
    return 1 if gray else channels


def _decode_file(path: Path, wanted: range, announced: int) -> Iterator[np.ndarray]:
    """Yield the wanted frames of a video file as RGB uint8 [H, W, 3], decoding no frame past the last one."""
    cap = _open_capture(path)
    try:
        for index in range(wanted[-1] + 1):
            if not cap.grab():
                raise InputError(path, "video", f"truncated or corrupt: announced {announced} frames, "
                                                f"decoded {index}")
            if index in wanted:
                ok, bgr = cap.retrieve()
                if not ok:
                    raise InputError(path, "video", f"frame {index} cannot be decoded")
                yield cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    finally:
        cap.release()


def _decode_folder(files: list[Path], wanted: range) -> Iterator[np.ndarray]:
    """Yield the wanted images of a frame folder (uint8/uint16, [H, W, 1] or RGB [H, W, 3]), all one size."""
    first_shape = None
    for index in wanted:
        image = _read_image(files[index])
        if first_shape is None:
            first_shape = image.shape[:2]
        elif image.shape[:2] != first_shape:
            raise InputError(files[index], "frame", f"is {image.shape[1]}x{image.shape[0]} but earlier frames "
                                                    f"are {first_shape[1]}x{first_shape[0]}")
        yield image


def _read_image(file: Path) -> np.ndarray:
    """Read one PNG/JPG as uint8/uint16 [H, W, 1] (gray) or [H, W, 3] (RGB, alpha dropped)."""
    image = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
    if image is None or image.dtype not in (np.uint8, np.uint16):
        raise InputError(file, "frame", "cannot be decoded as an 8- or 16-bit image")
    if image.ndim == 2:
        return image[:, :, None]
    return cv2.cvtColor(image[:, :, :3], cv2.COLOR_BGR2RGB)


def _to_float(raw: np.ndarray, width: int, height: int, channels: int | None) -> np.ndarray:
    """Convert a uint8/uint16 [H, W, 1|3] frame to float32 [height, width, C] in [0, 1]."""
    if channels == 1 and raw.shape[2] == 3:
        raw = cv2.cvtColor(raw, cv2.COLOR_RGB2GRAY)[:, :, None]
    elif channels == 3 and raw.shape[2] == 1:
        raw = np.repeat(raw, 3, axis=2)
    frame = raw.astype(np.float32) / np.float32(np.iinfo(raw.dtype).max)
    if frame.shape[1] != width or frame.shape[0] != height:
        shrink = width <= frame.shape[1] and height <= frame.shape[0]
        frame = cv2.resize(frame, (width, height), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
        frame = frame.reshape(height, width, -1)
    return frame


# ---------------------------------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------------------------------
def write_video(path: str | Path, frames: np.ndarray | Iterable[np.ndarray], fps: float, crf: int = 18,
                preset: str = "medium") -> Path:
    """Write frames as a browser-playable H.264 (libx264, yuv420p, +faststart) MP4, atomically.

    Frames are streamed to ffmpeg one at a time, so ``frames`` may be a generator of [H, W, C] frames.
    An odd width or height is padded to even by repeating the last column or row.

    Args:
        path: destination file (MP4 container whatever the suffix).
        frames: [T, H, W, C] floats in [0, 1] with C = 1 or 3, or an iterable of [H, W, C] frames.
        fps: frames per second (> 0).
        crf: x264 constant rate factor, 0 (lossless luma) to 51; 18 is visually lossless.
        preset: x264 speed/size preset (``ultrafast`` ... ``veryslow``).

    Returns:
        ``path`` as a Path.

    Raises:
        ValueError: a frame has the wrong shape or non-finite values.
        InputError: ``fps`` is not a finite number > 0.
        RuntimeError: ffmpeg failed (its error message is included).
    """
    path = Path(path)
    fps = require_positive(fps, path, "fps")
    frames = iter(frames)
    first = _check_frame(next(frames, None), None)
    height, width, channels = first.shape
    cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-nostdin", "-y", "-v", "error",
           "-f", "rawvideo", "-pix_fmt", "gray" if channels == 1 else "rgb24",
           "-s", f"{width + width % 2}x{height + height % 2}", "-r", f"{fps!r}", "-i", "-",
           "-an", "-c:v", "libx264", "-preset", preset, "-crf", str(int(crf)), "-pix_fmt", "yuv420p",
           "-movflags", "+faststart", "-f", "mp4"]
    with atomic_file(path) as tmp, tempfile.TemporaryFile() as log:
        proc = subprocess.Popen(cmd + [str(tmp)], stdin=subprocess.PIPE, stderr=log)
        try:
            for frame in _chain(first, frames):
                proc.stdin.write(_to_bytes(_check_frame(frame, first.shape)).tobytes())
        except BrokenPipeError:
            pass  # ffmpeg exited early; its message is reported below
        except BaseException:
            proc.kill()
            raise
        finally:
            with contextlib.suppress(BrokenPipeError):
                proc.stdin.close()
            proc.wait()
        if proc.returncode != 0:
            log.seek(0)
            raise RuntimeError(f"ffmpeg failed writing {path}: {log.read().decode(errors='replace').strip()}")
    return path


def write_frames(folder: str | Path, frames: np.ndarray | Iterable[np.ndarray], fmt: str = "png") -> Path:
    """Write frames as an image sequence ``000000.png``, ``000001.png``, ... into ``folder``, atomically.

    The folder appears complete or not at all; an existing folder is replaced only once the new one is done.

    Args:
        folder: destination folder.
        frames: [T, H, W, C] floats in [0, 1] with C = 1 or 3, or an iterable of [H, W, C] frames.
        fmt: ``png`` (lossless 8-bit) or ``jpg`` (quality 95).

    Returns:
        ``folder`` as a Path.

    Raises:
        ValueError: unknown ``fmt``, a frame with the wrong shape or non-finite values.
    """
    fmt = fmt.lower().lstrip(".")
    if fmt not in FRAME_FORMATS:
        raise ValueError(f"fmt must be one of {FRAME_FORMATS}, got {fmt!r}")
    params = [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY] if fmt == "jpg" else []
    folder = Path(folder)
    with atomic_dir(folder) as tmp:
        shape = None
        for index, frame in enumerate(frames):
            frame = _check_frame(frame, shape)
            shape = frame.shape
            image = _quantize(frame)
            image = image[:, :, 0] if shape[2] == 1 else cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
            if not cv2.imwrite(str(tmp / f"{index:06d}.{fmt}"), image, params):
                raise RuntimeError(f"OpenCV could not write {folder / f'{index:06d}.{fmt}'}")
        if shape is None:
            raise ValueError("no frames to write")
    return folder


def _chain(first: np.ndarray, rest: Iterator[np.ndarray]) -> Iterator[np.ndarray]:
    yield first
    yield from rest


def _check_frame(frame, shape: tuple | None) -> np.ndarray:
    """Validate one [H, W, C] frame (C = 1 or 3, finite, same shape as the first) and return it as float32."""
    if frame is None:
        raise ValueError("no frames to write")
    frame = np.asarray(frame, dtype=np.float32)
    if frame.ndim != 3 or frame.shape[2] not in (1, 3) or min(frame.shape) == 0:
        raise ValueError(f"a frame must be [H, W, C] with C = 1 or 3, got shape {frame.shape}")
    if shape is not None and frame.shape != shape:
        raise ValueError(f"all frames must have the first frame's shape {shape}, got {frame.shape}")
    if not np.all(np.isfinite(frame)):
        raise ValueError("frames contain NaN or infinite values")
    return frame


def _quantize(frame: np.ndarray) -> np.ndarray:
    """float [H, W, C] in [0, 1] -> uint8, as ``round(clip(x, 0, 1) * 255)`` (docs/conventions.md)."""
    return np.rint(np.clip(frame, 0.0, 1.0) * 255.0).astype(np.uint8)


def _to_bytes(frame: np.ndarray) -> np.ndarray:
    """Quantize a frame and pad it to even width and height (yuv420p) by repeating the last column/row."""
    image = _quantize(frame)
    pad = ((0, image.shape[0] % 2), (0, image.shape[1] % 2), (0, 0))
    return np.ascontiguousarray(np.pad(image, pad, mode="edge") if any(p[1] for p in pad) else image)


def read_footage(path: Path, size: tuple[int, int] | None = None) -> np.ndarray:
    """[T, H, W, C] float32 at ``size`` (width, height; None: the file's); a gray video stored as RGB
    (R = G = B) comes back with C = 1."""
    video = read_video(path, size=size)
    if video.shape[-1] == 3 and np.array_equal(video[..., :1], video[..., 1:2]) and np.array_equal(
            video[..., :1], video[..., 2:]):
        return np.ascontiguousarray(video[..., :1])
    return video


def resize_video(video: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """[T, H, W, C] resampled (bilinear) to ``size`` (width, height); unchanged when it already has that size."""
    if video.shape[1:3] == (size[1], size[0]):
        return video
    return np.stack([cv2.resize(f, size, interpolation=cv2.INTER_LINEAR).reshape(size[1], size[0], -1)
                     for f in video])
