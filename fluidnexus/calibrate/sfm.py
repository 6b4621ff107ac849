"""Camera calibration from images with pycolmap structure-from-motion.

Input is either one image or short video per camera of a multi-camera rig (the first frame of each video is
used), or a single hand-held sweep video (``frames_per_video`` evenly spaced frames, one camera each). The
pipeline is SIFT feature extraction on the CPU, exhaustive matching and incremental mapping. Every rig input
gets its own undistorted SIMPLE_PINHOLE camera (focal length refined by bundle adjustment, principal point
at the image centre); the frames of a sweep share one. The largest reconstruction is kept; every input must
be registered in it.

The result is then moved into the project's world frame (docs/conventions.md):

* **Up (+y).** A rig or a sweep is held upright: the cameras have no roll, so every camera's x axis (image
  right) is horizontal and world up is the direction orthogonal to all of them, the eigenvector of
  ``sum_i x_i x_i^T`` with the smallest eigenvalue, signed to agree with the cameras' image-up vectors
  (camera -y, i.e. ``-R[1]``). This holds for cameras tilted down at a subject, where the mean image-up vector
  leans towards the subject by the tilt angle. When the x axes are (nearly) parallel, e.g. a sideways
  translation, that direction is not determined and up falls back to the mean image-up vector ``mean(-R[1])``.
  ``SfmResult.up_axis_source`` says which was used.
* **Heading.** The rotation about +y puts the cameras' mean horizontal viewing direction along -z.
* **Origin.** The cameras' look-at point, the least-squares intersection of their optical axes, is moved to
  the origin (for a rig that is the subject the cameras are aimed at). When the axes are (nearly) parallel it
  is undetermined and the median of the sparse points is used instead.
* **Scale.** SfM fixes scale only up to a factor. With ``scale_distance=(A, B, metres)`` the world is scaled
  so that the camera centres of A and B are ``metres`` apart (``SfmResult.metric`` is True); otherwise SfM's
  arbitrary scale is kept and ``metric`` is False.
"""
from __future__ import annotations

import logging
import math
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from ..camera import Camera
from ..errors import InputError

log = logging.getLogger(__name__)

VIDEO_SUFFIXES = {".mp4", ".mov", ".avi", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg"}
DEFAULT_FRAMES_PER_VIDEO = 24
# Below this normalised eigenvalue the cameras' x axes (or optical axes) do not span the needed directions.
DEGENERATE_SPREAD = 1e-3
UP_FROM_X_AXES = "normal to the cameras' x axes (upright cameras, no roll)"
UP_FROM_IMAGE_UP = "mean image-up vector of the cameras (x axes nearly parallel)"


@dataclass(frozen=True, eq=False)
class SfmResult:
    """Calibrated cameras in the project's world frame (+y up).

    Attributes:
        cameras: camera name (the input file stem; ``<stem>_f<frame>`` for the frames of a sweep video, with
            the frame index in the video) -> undistorted :class:`Camera`.
        mean_reprojection_error_px: mean reprojection error of the sparse points in pixels.
        num_points: number of sparse 3D points.
        points: [num_points, 3] sparse points in the same world frame (metres if ``metric``).
        up_axis_source: how world up was chosen (see the module docstring).
        metric: True if the scale was set from ``scale_distance``; False if SfM's arbitrary scale was kept.
    """

    cameras: dict[str, Camera]
    mean_reprojection_error_px: float
    num_points: int
    points: np.ndarray
    up_axis_source: str
    metric: bool


@dataclass(frozen=True, eq=False)
class _View:
    """One image handed to SfM: its camera name, where it came from (for error messages) and its pixels."""

    name: str
    source: str
    image: np.ndarray  # [H, W, 3] uint8 BGR, as cv2 reads it


def calibrate_images(inputs: list[Path], work_dir: Path,
                     scale_distance: tuple[str, str, float] | None = None,
                     frames_per_video: int = DEFAULT_FRAMES_PER_VIDEO,
                     progress: Callable[[str], None] | None = None) -> SfmResult:
    """Calibrate cameras from images or videos with structure-from-motion.

    Args:
        inputs: image or video files; one per rig camera, or a single sweep video.
        work_dir: scratch folder for the extracted frames, the COLMAP database and the sparse model (created;
            a previous run's database and model in it are replaced).
        scale_distance: optional ``(name_a, name_b, metres)``: the known distance between two camera centres.
        frames_per_video: frames sampled from a single sweep video.
        progress: optional callback taking a one-line description of the stage being started.
    Returns:
        The calibrated cameras, aligned to +y up (see the module docstring).
    Raises:
        InputError: too few inputs, an unreadable file, unknown ``scale_distance`` names, an SfM failure, or
            inputs that SfM could not register (named in the message).
    """
    report = progress or (lambda message: None)
    report("reading images")
    views, shared_intrinsics = _read_views([Path(p) for p in inputs], frames_per_video)
    if scale_distance is not None:
        _check_scale_distance(scale_distance, [v.name for v in views])
    recon = _run_sfm(views, Path(work_dir), shared_intrinsics, report)
    report("aligning to +y up")
    cameras = _registered_cameras(recon, views)
    points = np.array([p.xyz for p in recon.points3D.values()], dtype=np.float64).reshape(-1, 3)
    rotation, up_source = _world_rotation(list(cameras.values()))
    origin = _look_at_point(list(cameras.values()), points)
    scale = 1.0 if scale_distance is None else _metric_scale(cameras, scale_distance)
    cameras = {name: _transform_camera(cam, rotation, origin, scale) for name, cam in cameras.items()}
    return SfmResult(cameras=cameras,
                     mean_reprojection_error_px=float(recon.compute_mean_reprojection_error()),
                     num_points=len(points), points=scale * (points - origin) @ rotation.T,
                     up_axis_source=up_source, metric=scale_distance is not None)


# ---- reading inputs -------------------------------------------------------------------------------------
def _read_views(inputs: list[Path], frames_per_video: int) -> tuple[list[_View], bool]:
    """The images to calibrate, and whether they share one camera (the frames of a single sweep video)."""
    if len(inputs) == 1 and inputs[0].suffix.lower() in VIDEO_SUFFIXES:
        if frames_per_video < 2:
            raise InputError(None, "frames_per_video", f"a sweep needs >= 2 frames, got {frames_per_video}")
        return _sweep_views(inputs[0], frames_per_video), True
    if len(inputs) < 2:
        raise InputError(inputs[0] if inputs else None, None,
                         "calibration needs at least 2 images (one per camera) or a single sweep video")
    views = []
    for path in inputs:
        if path.suffix.lower() in VIDEO_SUFFIXES:
            image = _read_video_frames(path, [0])[0]
        else:
            _require_file(path)
            image = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if image is None:
                raise InputError(path, None, "cannot read the image (unsupported or corrupt file)")
        views.append(_View(path.stem, str(path), image))
    names = [v.name for v in views]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise InputError(None, None, f"two inputs have the same file stem {duplicates}; camera names must differ")
    return views, False


def _sweep_views(path: Path, frames_per_video: int) -> list[_View]:
    """``frames_per_video`` evenly spaced frames of a sweep video, named ``<stem>_f<frame index>``."""
    count = _count_video_frames(path)
    if count < 2:
        raise InputError(path, None, f"a sweep video needs at least 2 frames, it has {count}")
    indices = sorted({round(i) for i in np.linspace(0, count - 1, min(frames_per_video, count))})
    frames = _read_video_frames(path, indices)
    return [_View(f"{path.stem}_f{i:04d}", f"{path} (frame {i})", img) for i, img in zip(indices, frames)]


def _require_file(path: Path) -> None:
    if not path.is_file():
        raise InputError(path, None, "no such file")


def _count_video_frames(path: Path) -> int:
    """Number of decodable frames (counted by decoding: container frame counts can be wrong)."""
    _require_file(path)
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise InputError(path, None, "cannot open the video")
        count = 0
        while cap.grab():
            count += 1
        return count
    finally:
        cap.release()


def _read_video_frames(path: Path, indices: list[int]) -> list[np.ndarray]:
    """The frames at the sorted ``indices`` of a video, as [H, W, 3] uint8 BGR."""
    _require_file(path)
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise InputError(path, None, "cannot open the video")
        frames, wanted = [], set(indices)
        for index in range(indices[-1] + 1):
            if not cap.grab():
                break
            if index in wanted:
                ok, frame = cap.retrieve()
                if not ok:
                    break
                frames.append(frame)
        if len(frames) != len(indices):
            raise InputError(path, None, f"cannot decode frame {indices[len(frames)]} of the video")
        return frames
    finally:
        cap.release()


def _check_scale_distance(scale_distance, names: list[str]) -> None:
    name_a, name_b, metres = scale_distance
    unknown = [n for n in (name_a, name_b) if n not in names]
    if unknown:
        raise InputError(None, "--scale-distance", f"unknown camera name(s) {unknown}; cameras are {names}")
    if name_a == name_b:
        raise InputError(None, "--scale-distance", "needs two different cameras")
    try:
        positive = math.isfinite(float(metres)) and float(metres) > 0
    except (TypeError, ValueError):
        positive = False
    if not positive:
        raise InputError(None, "--scale-distance", f"distance must be a finite number > 0 metres, got {metres!r}")


# ---- structure from motion ----------------------------------------------------------------------------------
def _run_sfm(views: list[_View], work_dir: Path, shared_intrinsics: bool, report):
    """Feature extraction, exhaustive matching and incremental mapping; returns the largest reconstruction."""
    import pycolmap

    image_dir, database, sparse = work_dir / "images", work_dir / "database.db", work_dir / "sparse"
    image_dir.mkdir(parents=True, exist_ok=True)
    database.unlink(missing_ok=True)
    shutil.rmtree(sparse, ignore_errors=True)
    sparse.mkdir()
    for view in views:
        if not cv2.imwrite(str(image_dir / f"{view.name}.png"), view.image):
            raise InputError(image_dir, None, f"cannot write the frame of {view.source}")
    names = [f"{view.name}.png" for view in views]

    pycolmap.set_random_seed(0)
    report(f"extracting SIFT features from {len(views)} images")
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "SIMPLE_PINHOLE"
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.use_gpu = False
    mode = pycolmap.CameraMode.SINGLE if shared_intrinsics else pycolmap.CameraMode.PER_IMAGE
    pycolmap.extract_features(database, image_dir, image_names=names, camera_mode=mode, reader_options=reader,
                              extraction_options=extraction, device=pycolmap.Device.cpu)
    report("matching features (exhaustive)")
    matching = pycolmap.FeatureMatchingOptions()
    matching.use_gpu = False
    pycolmap.match_exhaustive(database, matching_options=matching, device=pycolmap.Device.cpu)
    report("incremental mapping")
    options = pycolmap.IncrementalPipelineOptions()
    options.min_model_size = 2  # keep partial models so that unregistered inputs can be named
    options.random_seed = 0
    models = pycolmap.incremental_mapping(database, image_dir, sparse, options=options)
    if not models:
        raise InputError(None, None, "structure-from-motion found no reconstruction from "
                         f"{', '.join(v.source for v in views)} (too little overlap or texture?)")
    return max(models.values(), key=lambda rec: rec.num_reg_images())


def _registered_cameras(recon, views: list[_View]) -> dict[str, Camera]:
    """Our cameras for every view; raises if SfM did not register some of them."""
    by_name = {image.name: image for image in recon.images.values() if image.has_pose}
    missing = [v.source for v in views if f"{v.name}.png" not in by_name]
    if missing:
        raise InputError(None, None, f"structure-from-motion could not register {', '.join(missing)} "
                         f"({len(views) - len(missing)} of {len(views)} registered)")
    images = {v.name: by_name[f"{v.name}.png"] for v in views}
    return {name: Camera.from_pycolmap(image.camera, image.cam_from_world()) for name, image in images.items()}


# ---- alignment --------------------------------------------------------------------------------------------
def _world_rotation(cameras: list[Camera]) -> tuple[np.ndarray, str]:
    """[3, 3] rotation from SfM world to our world (+y up, mean heading -z), and how up was chosen."""
    rights = np.stack([cam.R[0] for cam in cameras])
    image_up = np.stack([-cam.R[1] for cam in cameras]).mean(0)
    evals, evecs = np.linalg.eigh(rights.T @ rights / len(cameras))
    if evals[1] > DEGENERATE_SPREAD:
        up, source = evecs[:, 0], UP_FROM_X_AXES
        up = up if up @ image_up >= 0 else -up
    else:
        up, source = image_up / np.linalg.norm(image_up), UP_FROM_IMAGE_UP
        log.warning("the cameras' x axes are nearly parallel; up is their mean image-up vector")
    forward = np.stack([cam.forward for cam in cameras]).mean(0)
    heading = forward - (forward @ up) * up
    if np.linalg.norm(heading) < 1e-6:  # the cameras look straight down (or up) on average: any heading will do
        heading = np.cross(up, np.eye(3)[np.argmin(np.abs(up))])
    back = -heading / np.linalg.norm(heading)  # becomes +z
    # Rows are the SfM-world directions of our x, y, z axes.
    return np.stack([np.cross(up, back), up, back]), source


def _look_at_point(cameras: list[Camera], points: np.ndarray) -> np.ndarray:
    """[3] least-squares intersection of the optical axes (SfM world); the points' median if undetermined.

    Minimises ``sum_i |(I - d_i d_i^T)(p - c_i)|^2`` over p, for centres ``c_i`` and unit viewing directions
    ``d_i``.
    """
    A, b = np.zeros((3, 3)), np.zeros(3)
    for cam in cameras:
        P = np.eye(3) - np.outer(cam.forward, cam.forward)
        A += P
        b += P @ cam.center
    if np.linalg.eigvalsh(A / len(cameras))[0] > DEGENERATE_SPREAD:
        return np.linalg.solve(A, b)
    log.warning("the cameras' optical axes are nearly parallel; the origin is the median of the sparse points")
    return np.median(points, axis=0)


def _metric_scale(cameras: dict[str, Camera], scale_distance: tuple[str, str, float]) -> float:
    """Factor that makes the distance between the centres of cameras A and B equal to the given metres."""
    name_a, name_b, metres = scale_distance
    centres = np.stack([cam.center for cam in cameras.values()])
    baseline = np.linalg.norm(cameras[name_a].center - cameras[name_b].center)
    if baseline <= 1e-6 * np.ptp(centres, axis=0).max():
        raise InputError(None, "--scale-distance", f"cameras {name_a} and {name_b} are at the same place")
    return float(metres) / baseline


def _transform_camera(cam: Camera, rotation: np.ndarray, origin: np.ndarray, scale: float) -> Camera:
    """The camera after the world map ``X' = scale * rotation (X - origin)``."""
    R = cam.R @ rotation.T
    w2c = np.eye(4)
    w2c[:3, :3] = R
    w2c[:3, 3] = scale * (cam.t + cam.R @ origin)
    return Camera(cam.width, cam.height, cam.K, w2c)
