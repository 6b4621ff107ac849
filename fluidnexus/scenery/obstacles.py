"""Rigid obstacles of a captured scene: scene.json ``obstacles`` and ``calibrate --obstacle`` (docs/scene-format.md).

An obstacle is a ball ``{"kind": "sphere", "center": [x, y, z], "radius": r}`` or a closed triangle mesh
``{"kind": "mesh", "file": "obstacles/NAME.ply"}`` (any file trimesh reads, relative to the scene folder), in the
scene's coordinates. Reconstruction and prediction apply them to the gas with the engine's one-way coupling
(``fluidnexus/engine/obstacle.py``): no physical or visual particle ends a step inside one.

Checks (an :class:`InputError` naming scene.json and e.g. ``obstacles[1].radius``): a radius > 0, finite
numbers, a mesh file that exists, loads and is closed, and a body that meets the scene's volume (an obstacle
wholly outside it cannot touch the smoke and is almost certainly given in another frame or unit).

``interact --ball`` / ``--mesh`` place one body of the same two kinds in a prediction (:func:`make_obstacle`). A mesh
becomes a signed-distance grid (negative inside) over its bounding box plus a margin, computed once by the engine
(``signed_distance_grid``: exact point-triangle distance to the nearest face, sign from the generalised winding
number), so any closed OBJ/STL/PLY that trimesh loads works without a spatial index.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, require_finite, require_positive

KINDS = ("sphere", "mesh")
GRID_NODES = 40  # nodes along the longest side of a mesh's signed-distance grid


@dataclass(frozen=True)
class SphereBody:
    """A ball of ``radius`` around ``center`` (scene coordinates)."""

    center: tuple[float, float, float]
    radius: float

    def to_dict(self) -> dict:
        return {"kind": "sphere", "center": list(self.center), "radius": self.radius}

    def bounds(self, root: Path | None = None) -> tuple[np.ndarray, np.ndarray]:
        c = np.asarray(self.center)
        return c - self.radius, c + self.radius


@dataclass(frozen=True)
class MeshBody:
    """A closed triangle mesh in the file ``file`` (relative to the scene folder ``root``)."""

    file: str

    def to_dict(self) -> dict:
        return {"kind": "mesh", "file": self.file}

    def bounds(self, root: Path) -> tuple[np.ndarray, np.ndarray]:
        mesh = load_mesh(root / self.file)
        return np.asarray(mesh.bounds[0], float), np.asarray(mesh.bounds[1], float)


def load_mesh(path: str | Path, fld: str = "file"):
    """A closed triangle mesh (trimesh.Trimesh) from any file trimesh reads; an InputError naming the file and
    ``fld`` otherwise."""
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise InputError(path, fld, "file not found")
    try:
        mesh = trimesh.load(path, force="mesh")
    except Exception as err:  # trimesh raises many types for unreadable files
        raise InputError(path, fld, f"cannot load a triangle mesh ({err})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InputError(path, fld, "no triangles in the file")
    if not mesh.is_watertight:
        raise InputError(path, fld, "the mesh is not closed (watertight); an obstacle needs an inside")
    return mesh


def mesh_sdf_grid(mesh, nodes: int = GRID_NODES, margin_cells: int = 2) -> tuple[np.ndarray, np.ndarray, float]:
    """Signed distance phi [nx, ny, nz] m of ``mesh`` on a grid over its box; returns (phi, origin, spacing)."""
    from ..engine.obstacle import signed_distance_grid

    lo, hi = np.asarray(mesh.bounds[0], float), np.asarray(mesh.bounds[1], float)
    spacing = float((hi - lo).max()) / (nodes - 1 - 2 * margin_cells)
    origin = lo - margin_cells * spacing
    res = np.ceil((hi - origin) / spacing).astype(int) + margin_cells + 1
    phi = signed_distance_grid(np.asarray(mesh.triangles, dtype=np.float64), origin, spacing, res)
    return phi, origin, spacing


def parse_sphere(text: str, option: str, form: str) -> SphereBody:
    """``CX,CY,CZ,R`` -> SphereBody; an InputError naming ``option`` (whose value has the form ``form``) for
    anything but four finite numbers with R > 0."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise InputError(None, option, f"expected {form} with four finite numbers, got {text!r}")
    if values[3] <= 0:
        raise InputError(None, option, f"the sphere's radius must be > 0, got {values[3]}")
    return SphereBody(tuple(values[:3]), values[3])


def _check_in_volume(body, volume, root: Path, path, fld: str) -> None:
    if volume is None:
        return
    lo, hi = body.bounds(root)
    if np.any(hi < np.asarray(volume.min)) or np.any(lo > np.asarray(volume.max)):
        raise InputError(path, fld, f"lies outside the scene volume {list(volume.min)}..{list(volume.max)} "
                                    f"(its box is {lo.round(4).tolist()}..{hi.round(4).tolist()}); give it in "
                                    "scene coordinates")


def parse_obstacles(items, path, volume=None, root: Path | None = None) -> tuple:
    """Parse scene.json's ``obstacles`` list (a mesh is read and checked against the volume only when it is built,
    :func:`engine_obstacle`)."""
    if items is None:
        return ()
    if not isinstance(items, list):
        raise InputError(path, "obstacles", "expected a list of {kind: sphere|mesh, ...}")
    out = []
    for i, item in enumerate(items):
        fld = f"obstacles[{i}]"
        kind = item.get("kind") if isinstance(item, dict) else None
        if kind not in KINDS:
            raise InputError(path, f"{fld}.kind", f"must be one of {KINDS}, got {kind!r}")
        if kind == "sphere":
            center = require_finite(item.get("center"), path, f"{fld}.center")
            if center.shape != (3,):
                raise InputError(path, f"{fld}.center", f"expected 3 numbers, got {item.get('center')!r}")
            radius = item.get("radius")
            if not isinstance(radius, (int, float)) or isinstance(radius, bool):
                raise InputError(path, f"{fld}.radius", f"must be a number > 0, got {radius!r}")
            body = SphereBody(tuple(float(v) for v in center), require_positive(radius, path, f"{fld}.radius"))
            _check_in_volume(body, volume, root, path, fld)
        else:
            file = item.get("file")
            if not isinstance(file, str) or not file:
                raise InputError(path, f"{fld}.file", "expected the mesh file, relative to the scene folder")
            body = MeshBody(file)
            if root is not None and not (root / file).is_file():
                raise InputError(path, f"{fld}.file", f"{root / file}: file not found")
        out.append(body)
    return tuple(out)


def parse_option(text: str) -> SphereBody | tuple[str, Path]:
    """``sphere:CX,CY,CZ,R`` -> SphereBody; ``mesh:FILE`` -> ("mesh", FILE). InputError on ``--obstacle``."""
    kind, _, rest = text.partition(":")
    if kind == "sphere":
        return parse_sphere(rest, "--obstacle", "sphere:CX,CY,CZ,R")
    if kind == "mesh" and rest:
        return "mesh", Path(rest)
    raise InputError(None, "--obstacle", f"expected sphere:CX,CY,CZ,R or mesh:FILE, got {text!r}")


def engine_obstacle(bodies, root: Path, volume=None):
    """The engine body (``SphereObstacle``, ``GridObstacle`` or an ``ObstacleGroup`` of several) of a scene's
    obstacles, or None without any. Meshes are read here: an unreadable or open mesh, or one outside ``volume``,
    is an InputError naming scene.json and ``obstacles[i].file``. Needs the engine started."""
    from ..engine.obstacle import GridObstacle, SphereObstacle

    root = Path(root)
    scene_file = root / "scene.json"
    built = []
    for i, body in enumerate(bodies):
        if isinstance(body, SphereBody):
            built.append(SphereObstacle(body.center, body.radius))
            continue
        try:
            mesh = load_mesh(root / body.file)
        except InputError as err:
            raise InputError(scene_file, f"obstacles[{i}].file", f"{err.path}: {err.message}") from None
        _check_in_volume(body, volume, root, scene_file, f"obstacles[{i}]")
        built.append(GridObstacle(*mesh_sdf_grid(mesh)))
    return join(*built)


def join(*obstacles):
    """One engine body from several (None entries skipped), or None."""
    from ..engine.obstacle import ObstacleGroup

    present = [o for o in obstacles if o is not None]
    if not present:
        return None
    return present[0] if len(present) == 1 else ObstacleGroup(present)


def place_obstacles(options, root: Path, frame=None, volume=None) -> tuple:
    """The scene bodies of ``calibrate --obstacle`` values (``parse_option`` results, in the imported file's own
    frame and unit), converted into the scene by ``frame`` (a ``world_frame.SourceFrame``, None: the identity);
    a mesh is read, converted and written into ``root``/obstacles/ as PLY. Errors name ``--obstacle``."""
    out = []
    for i, opt in enumerate(options):
        if isinstance(opt, SphereBody):
            center = opt.center if frame is None else tuple(float(v) for v in frame.to_scene(opt.center))
            radius = opt.radius if frame is None else float(frame.length_to_scene(opt.radius))
            body = SphereBody(center, radius)
        else:
            mesh = load_mesh(opt[1], "--obstacle")
            if frame is not None:
                mesh.vertices = frame.to_scene(mesh.vertices)
            (root / "obstacles").mkdir(exist_ok=True)
            body = MeshBody(f"obstacles/obstacle{i}.ply")
            mesh.export(root / body.file)
        try:
            _check_in_volume(body, volume, root, None, "--obstacle")
        except InputError as err:
            raise InputError(None, "--obstacle", f"{_describe(options[i])}: {err.message}") from None
        out.append(body)
    return tuple(out)


def _describe(opt) -> str:
    if isinstance(opt, SphereBody):
        return f"sphere:{','.join(f'{v:g}' for v in (*opt.center, opt.radius))}"
    return f"mesh:{opt[1]}"


def make_obstacle(ball: str | None, mesh_file: str | Path | None, nodes: int = GRID_NODES):
    """The engine obstacle of ``interact --ball CX,CY,CZ,R`` (metres) or ``--mesh FILE`` (exactly one), plus a JSON
    description of it. Needs the engine started."""
    from ..engine.obstacle import GridObstacle, SphereObstacle

    if (ball is None) == (mesh_file is None):
        raise InputError(None, "--ball/--mesh", "give exactly one of --ball and --mesh")
    if ball is not None:
        body = parse_sphere(ball, "--ball", "CX,CY,CZ,R in metres")
        return SphereObstacle(body.center, body.radius), {"kind": "ball", "center": list(body.center),
                                                          "radius": body.radius}
    mesh = load_mesh(mesh_file, "--mesh")
    phi, origin, spacing = mesh_sdf_grid(mesh, nodes)
    return GridObstacle(phi, origin, spacing), {"kind": "mesh", "file": str(Path(mesh_file).resolve()),
                                                "faces": int(len(mesh.faces)), "grid": list(phi.shape),
                                                "spacing": spacing}
