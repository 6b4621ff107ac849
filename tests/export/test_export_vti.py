import numpy as np
import pytest

from fluidnexus.errors import InputError
from fluidnexus.export.vti import grid_points, read_vti, write_vti

ORIGIN = (-0.25, 0.0, 0.5)
SPACING = (0.05, 0.1, 0.2)
SHAPE = (4, 3, 5)  # nz, ny, nx: all different, so a transposed axis cannot pass


def fields(rng):
    return {"density": rng.random(SHAPE).astype(np.float32),
            "velocity": rng.normal(size=SHAPE + (3,)).astype(np.float32)}


def test_round_trip_is_exact(tmp_path):
    arrays = fields(np.random.default_rng(0))
    write_vti(tmp_path / "f.vti", ORIGIN, SPACING, arrays)
    origin, spacing, back = read_vti(tmp_path / "f.vti")
    np.testing.assert_array_equal(origin, ORIGIN)
    np.testing.assert_array_equal(spacing, SPACING)
    assert list(back) == ["density", "velocity"]
    for name in arrays:
        assert back[name].dtype == np.float32
        np.testing.assert_array_equal(back[name], arrays[name])


def test_header_and_point_order_follow_vtk(tmp_path):
    arrays = fields(np.random.default_rng(1))
    write_vti(tmp_path / "f.vti", ORIGIN, SPACING, arrays)
    raw = (tmp_path / "f.vti").read_bytes()
    head = raw[:raw.index(b"<AppendedData")].decode()
    assert 'WholeExtent="0 4 0 2 0 3"' in head
    assert 'Scalars="density"' in head and 'Vectors="velocity"' in head
    body = raw.index(b"_", raw.index(b"<AppendedData")) + 1
    nbytes = int(np.frombuffer(raw, "<u8", 1, body)[0])
    assert nbytes == 4 * np.prod(SHAPE)
    first = np.frombuffer(raw, "<f4", 3, body + 8)
    d = arrays["density"]
    np.testing.assert_array_equal(first, [d[0, 0, 0], d[0, 0, 1], d[0, 0, 2]])  # x varies fastest


def test_grid_points_put_node_ijk_at_origin_plus_ijk_times_spacing():
    pts = grid_points(ORIGIN, SPACING, SHAPE)
    assert pts.shape == SHAPE + (3,)
    k, j, i = 3, 1, 4
    np.testing.assert_allclose(pts[k, j, i], np.add(ORIGIN, np.multiply([i, j, k], SPACING)))


def test_vtk_reads_our_file(tmp_path):
    vtk = pytest.importorskip("vtk")
    from vtk.util.numpy_support import vtk_to_numpy

    arrays = fields(np.random.default_rng(2))
    write_vti(tmp_path / "f.vti", ORIGIN, SPACING, arrays)
    reader = vtk.vtkXMLImageDataReader()
    reader.SetFileName(str(tmp_path / "f.vti"))
    reader.Update()
    image = reader.GetOutput()
    assert image.GetDimensions() == (5, 3, 4)
    np.testing.assert_allclose(image.GetOrigin(), ORIGIN)
    np.testing.assert_allclose(image.GetSpacing(), SPACING)
    pd = image.GetPointData()
    assert pd.GetScalars().GetName() == "density" and pd.GetVectors().GetName() == "velocity"
    np.testing.assert_array_equal(vtk_to_numpy(pd.GetArray("density")), arrays["density"].reshape(-1))
    np.testing.assert_array_equal(vtk_to_numpy(pd.GetArray("velocity")), arrays["velocity"].reshape(-1, 3))
    pts = grid_points(ORIGIN, SPACING, SHAPE).reshape(-1, 3)
    for pid in (0, 7, 33, len(pts) - 1):
        np.testing.assert_allclose(image.GetPoint(pid), pts[pid])


@pytest.mark.parametrize("arrays, message", [
    ({}, "no arrays"),
    ({"density": np.zeros((4, 3))}, "must be"),
    ({"velocity": np.zeros((4, 3, 5, 2))}, "must be"),
    ({"density": np.zeros((4, 3, 5)), "v": np.zeros((4, 3, 6, 3))}, "has grid"),
    ({"bad name": np.zeros((4, 3, 5))}, "identifier"),
])
def test_bad_arrays_are_rejected(tmp_path, arrays, message):
    with pytest.raises(ValueError, match=message):
        write_vti(tmp_path / "f.vti", ORIGIN, SPACING, arrays)
    assert not (tmp_path / "f.vti").exists()


def test_bad_spacing_is_rejected(tmp_path):
    with pytest.raises(ValueError, match="spacing must be > 0"):
        write_vti(tmp_path / "f.vti", ORIGIN, (0.1, 0.0, 0.1), {"density": np.zeros(SHAPE)})


def test_bad_files_raise_input_errors(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        read_vti(tmp_path / "missing.vti")
    (tmp_path / "x.vti").write_text('<?xml version="1.0"?><VTKFile type="ImageData"></VTKFile>')
    with pytest.raises(InputError, match="no raw appended data"):
        read_vti(tmp_path / "x.vti")
