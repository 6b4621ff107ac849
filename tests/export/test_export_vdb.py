"""The OpenVDB writer: read back by its own reader, by OpenVDB itself (Debian's python3-openvdb under the system
Python, run as a subprocess), and ``export --format vdb`` against ``--format vti`` of the same frame."""
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from clirun import assert_clean_failure, invoke, ok
from fluidnexus.errors import InputError
from fluidnexus.export.vdb import read_vdb, write_vdb
from fluidnexus.export.vti import grid_points, read_vti
from fluidnexus.state import FrameState

from handmade_run import write_run
from handmade_scene import ring_camera, write_scene

ORIGIN = (-0.25, 0.0, 0.5)
SPACING = (0.05, 0.1, 0.2)
SHAPE = (20, 150, 9)  # nz, ny, nx: all different, and y spans two internal nodes of 128 voxels
SYSTEM_PYTHON = "/usr/bin/python3"


def sparse_fields(rng):
    density = np.zeros(SHAPE, np.float32)
    density[2:7, 100:140, 1:8] = rng.random((5, 40, 7)) + 0.1
    density[15, 3, 0] = 2.5  # a lone voxel in another leaf
    velocity = rng.normal(size=SHAPE + (3,)).astype(np.float32) * (density[..., None] > 0)
    return {"density": density, "velocity": velocity}


def test_own_reader_gets_every_active_voxel_back(tmp_path):
    arrays = sparse_fields(np.random.default_rng(0))
    write_vdb(tmp_path / "f.vdb", ORIGIN, SPACING, arrays)
    grids = read_vdb(tmp_path / "f.vdb")
    assert list(grids) == ["density", "velocity"]
    assert grids["density"]["class"] == "fog volume"
    for name, arr in arrays.items():
        g = grids[name]
        np.testing.assert_array_equal(g["translation"], ORIGIN)
        np.testing.assert_array_equal(g["scale"], SPACING)
        i, j, k = g["ijk"].T
        nonzero = arr if arr.ndim == 3 else np.abs(arr).sum(-1)
        assert len(i) == np.count_nonzero(nonzero)
        np.testing.assert_array_equal(g["values"], arr[k, j, i])


def test_an_empty_field_is_an_empty_grid(tmp_path):
    write_vdb(tmp_path / "f.vdb", ORIGIN, SPACING, {"density": np.zeros((3, 4, 5))})
    assert len(read_vdb(tmp_path / "f.vdb")["density"]["ijk"]) == 0


def test_bad_input_is_rejected(tmp_path):
    with pytest.raises(ValueError, match="has grid"):
        write_vdb(tmp_path / "f.vdb", ORIGIN, SPACING, {"density": np.zeros((2, 3, 4)), "v": np.zeros((2, 3, 5, 3))})
    assert not (tmp_path / "f.vdb").exists()
    with pytest.raises(InputError, match="file not found"):
        read_vdb(tmp_path / "f.vdb")
    (tmp_path / "x.vdb").write_bytes(b"\0" * 64)
    with pytest.raises(InputError, match="not an OpenVDB file"):
        read_vdb(tmp_path / "x.vdb")


# ---- OpenVDB itself ------------------------------------------------------------------------------------------
OPENVDB_DUMP = r"""
import json, sys
try:
    import openvdb as vdb
except ImportError:
    import pyopenvdb as vdb
grids, meta = vdb.readAll(sys.argv[1])
out = {"file": {k: str(v) for k, v in meta.items()}, "grids": {}}
for g in grids:
    acc = g.getConstAccessor()
    voxels = [[list(ijk), (list(v) if isinstance(v, tuple) else v)]
              for ijk, v in ((tuple(int(c) for c in item.min), item.value) for item in g.citerOnValues())]
    lo, hi = g.evalActiveVoxelBoundingBox()
    out["grids"][g.name] = {
        "type": g.valueTypeName, "class": str(g.gridClass), "active": g.activeVoxelCount(),
        "bbox": [list(lo), list(hi)], "voxels": voxels,
        "world_of_ijk": [list(g.transform.indexToWorld(p)) for p in ((0, 0, 0), (1, 2, 3), (8, 130, 17))],
        "voxel_size": list(g.transform.voxelSize()),
        "background": g.background if not isinstance(g.background, tuple) else list(g.background)}
print(json.dumps(out))
"""


def openvdb_dump(path: Path) -> dict:
    """What OpenVDB's own Python module reads from ``path`` (skips where the system Python has no OpenVDB)."""
    probe = "try:\n import openvdb\nexcept ImportError:\n import pyopenvdb"
    if not Path(SYSTEM_PYTHON).exists() or subprocess.run([SYSTEM_PYTHON, "-c", probe],
                                                          capture_output=True).returncode != 0:
        pytest.skip(f"OpenVDB's Python module is not installed for {SYSTEM_PYTHON} "
                    "(Debian: apt-get install python3-openvdb); the independent VDB reader is missing")
    done = subprocess.run([SYSTEM_PYTHON, "-c", OPENVDB_DUMP, str(path)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_openvdb_reads_values_and_transform(tmp_path):
    arrays = sparse_fields(np.random.default_rng(1))
    write_vdb(tmp_path / "f.vdb", ORIGIN, SPACING, arrays)
    dump = openvdb_dump(tmp_path / "f.vdb")
    assert dump["file"]["creator"] == "fluidnexus"
    assert list(dump["grids"]) == ["density", "velocity"]
    assert dump["grids"]["density"]["type"] == "float" and dump["grids"]["velocity"]["type"] == "vec3s"
    assert dump["grids"]["density"]["class"].lower().replace("_", " ").endswith("fog volume")
    for name, arr in arrays.items():
        g = dump["grids"][name]
        nonzero = arr if arr.ndim == 3 else np.abs(arr).sum(-1)
        k, j, i = np.nonzero(nonzero)
        assert g["active"] == len(i)
        assert g["bbox"] == [[int(i.min()), int(j.min()), int(k.min())], [int(i.max()), int(j.max()), int(k.max())]]
        ijk = np.array([v[0] for v in g["voxels"]])
        values = np.array([v[1] for v in g["voxels"]], np.float32)
        np.testing.assert_array_equal(values, arr[ijk[:, 2], ijk[:, 1], ijk[:, 0]])
        assert len(np.unique(ijk, axis=0)) == len(i)
        np.testing.assert_allclose(g["voxel_size"], SPACING)
        for ijk_at, world in zip(((0, 0, 0), (1, 2, 3), (8, 130, 17)), g["world_of_ijk"]):
            np.testing.assert_allclose(world, np.add(ORIGIN, np.multiply(ijk_at, SPACING)), atol=1e-12)
    # voxel (i, j, k) is the VTI grid's node (i, j, k)
    pts = grid_points(ORIGIN, SPACING, SHAPE)
    np.testing.assert_allclose(dump["grids"]["density"]["world_of_ijk"][1], pts[3, 2, 1], atol=1e-12)


# ---- export ----------------------------------------------------------------------------------------------------
def plume_state(frame: int) -> FrameState:
    """A blob of physical particles (and a few Gaussians) rising through the volume."""
    rng = np.random.default_rng(frame)
    n, m = 300, 20
    p = (rng.normal(size=(n, 3)) * [0.08, 0.12, 0.08] + [0.05, 0.3 + 0.1 * frame, -0.02]).astype(np.float32)
    u = np.tile([0.0, 0.5, 0.0], (n, 1)).astype(np.float32)
    return FrameState(frame, p, u, p[:m].copy(), np.full((m, 1), 0.8, np.float32), np.full((m, 3), 0.05, np.float32),
                      np.tile([1.0, 0, 0, 0], (m, 1)).astype(np.float32), np.full(m, 0.5, np.float32))


@pytest.fixture
def plume_run(tmp_path):
    scene = write_scene(tmp_path / "scene", [("cam0", "input", ring_camera(0), None)])
    return write_run(tmp_path / "run", scene, [plume_state(t) for t in range(2)], h=0.1, dt=1 / 25)


def vti_reference(vti_file):
    """(density sum, world bbox of the non-zero nodes) of a .vti export."""
    origin, spacing, arrays = read_vti(vti_file)
    k, j, i = np.nonzero(arrays["density"])
    ijk = np.stack([i, j, k], 1)
    return float(arrays["density"].sum()), origin + ijk.min(0) * spacing, origin + ijk.max(0) * spacing


def test_export_vdb_holds_the_vti_frame(plume_run, tmp_path, ti_engine):
    ok("export", plume_run, "--format", "vti", "--voxel", "0.04", "--out", tmp_path / "vti", "--arch", "cpu")
    ok("export", plume_run, "--format", "vdb", "--voxel", "0.04", "--out", tmp_path / "vdb", "--arch", "cpu")
    assert sorted(p.name for p in (tmp_path / "vdb").iterdir()) == ["000000.vdb", "000001.vdb"]
    total, lo, hi = vti_reference(tmp_path / "vti" / "000001.vti")
    assert total > 0
    g = read_vdb(tmp_path / "vdb" / "000001.vdb")["density"]
    world = g["translation"] + g["ijk"] * g["scale"]
    np.testing.assert_allclose(g["values"].sum(dtype=np.float64), total, rtol=1e-6)
    np.testing.assert_allclose(world.min(0), lo, atol=1e-9)
    np.testing.assert_allclose(world.max(0), hi, atol=1e-9)


def test_openvdb_reads_the_export_as_the_vti_frame(plume_run, tmp_path, ti_engine):
    ok("export", plume_run, "--format", "vti", "--voxel", "0.04", "--out", tmp_path / "vti", "--arch", "cpu")
    ok("export", plume_run, "--format", "vdb", "--voxel", "0.04", "--out", tmp_path / "vdb", "--arch", "cpu")
    total, lo, hi = vti_reference(tmp_path / "vti" / "000001.vti")
    origin, spacing, _ = read_vti(tmp_path / "vti" / "000001.vti")
    g = openvdb_dump(tmp_path / "vdb" / "000001.vdb")["grids"]["density"]
    values = np.array([v[1] for v in g["voxels"]], np.float64)
    np.testing.assert_allclose(values.sum(), total, rtol=1e-6)
    bbox = np.array(g["bbox"])
    np.testing.assert_allclose(origin + bbox[0] * spacing, lo, atol=1e-9)
    np.testing.assert_allclose(origin + bbox[1] * spacing, hi, atol=1e-9)
    np.testing.assert_allclose(g["world_of_ijk"][0], origin, atol=1e-12)
    np.testing.assert_allclose(g["voxel_size"], spacing, rtol=1e-12)
    assert g["active"] == np.count_nonzero(read_vti(tmp_path / "vti" / "000001.vti")[2]["density"])


def test_export_vdb_needs_a_volume(tmp_path):
    scene = tmp_path / "scene"
    write_scene(scene, [("cam0", "input", ring_camera(0), None)])
    data = json.loads((scene / "scene.json").read_text())
    del data["volume"]
    (scene / "scene.json").write_text(json.dumps(data))
    run = write_run(tmp_path / "run", scene, [plume_state(0)], h=0.1, dt=1 / 25)
    assert_clean_failure(invoke("export", run, "--format", "vdb", "--out", tmp_path / "o"), "volume", "vdb")
