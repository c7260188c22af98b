"""Target models: FY-1-like dimensions, mesh loading and units, textures."""

import pickle

import numpy as np
import open3d as o3d
import pytest

from tests.vision.conftest import HUBBLE, INCH_M
from vision.target import (
    FY1_BUS_SIZE_M,
    FY1_SPAN_M,
    TEXTURE_KINDS,
    Material,
    Target,
    available_meshes,
    bundled_mesh_path,
    load_mesh,
    procedural_texture,
)


def test_fy1_has_the_published_bus_size_and_tip_to_tip_span(fy1):
    lo, hi = fy1.bbox_T
    assert hi[1] - lo[1] == pytest.approx(FY1_SPAN_M, abs=1e-9)          # wings along y
    bus = fy1.vertices_T[:24]                                            # first box: the bus
    np.testing.assert_allclose(np.ptp(bus, axis=0), FY1_BUS_SIZE_M, atol=1e-12)
    assert FY1_BUS_SIZE_M == (1.42, 1.42, 1.20) and FY1_SPAN_M == 10.556


def test_fy1_bus_faces_have_outward_normals_and_the_mesh_encloses_positive_volume(fy1):
    n = fy1.triangle_normals_T[:12]                                       # bus: 6 faces x 2
    c = fy1.vertices_T[fy1.triangles[:12]].mean(axis=1)
    assert np.all(np.sum(n * c, axis=1) > 0)
    p = fy1.vertices_T[fy1.triangles]
    volume = np.sum(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2]))) / 6.0
    bus = np.prod(FY1_BUS_SIZE_M)
    assert volume > bus                       # closed, outward pieces: bus plus panels and boxes


def test_fy1_is_reproducible_from_its_seed_and_differs_across_seeds(fy1):
    from vision.target import fy1_target

    np.testing.assert_array_equal(fy1_target(seed=0).texture, fy1.texture)
    assert not np.array_equal(fy1_target(seed=1).texture, fy1.texture)


def test_topex_in_inches_has_the_readme_extents_in_metres(topex):
    # README bounding box extents in file units (inches): 373.171 x 277.165 x 230.142
    np.testing.assert_allclose(np.ptp(topex.vertices_T, axis=0),
                               np.array([373.171, 277.165, 230.142]) * INCH_M, rtol=1e-5)
    np.testing.assert_allclose(topex.bbox_T.mean(axis=0), 0.0, atol=1e-9)  # centred on the box
    assert topex.n_triangles == 21158                                      # all faces are real
    assert topex.texture.min() >= 0.0 and topex.texture.max() <= 1.0


def test_hubble_kit_loads_with_the_readme_extents_and_faces():
    t = load_mesh(HUBBLE, unit_m=1e-3, center="none")
    np.testing.assert_allclose(t.bbox_T, np.array([[-32.401001, -48.200001, -0.001],
                                                   [34.764999, 43.701000, 39.810001]]) * 1e-3,
                               atol=1e-9)
    # faces of zero area (collinear corners) are dropped: count them independently
    m = o3d.io.read_triangle_mesh(str(HUBBLE))
    v = np.asarray(m.vertices)[np.asarray(m.triangles)] * 1e-3
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    assert len(area) == 8582
    assert t.n_triangles == int(np.sum(area > 1e-12))


@pytest.mark.parametrize("ext", ["stl", "ply", "obj", "gltf", "off"])
def test_mesh_formats_round_trip_with_unit_scaling(tmp_path, ext):
    box = o3d.geometry.TriangleMesh.create_box(1.0, 2.0, 3.0)
    box.compute_triangle_normals()
    path = tmp_path / f"box.{ext}"
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        assert o3d.io.write_triangle_mesh(str(path), box)
    t = load_mesh(path, unit_m=0.5)
    assert t.n_triangles == 12
    np.testing.assert_allclose(np.ptp(t.vertices_T, axis=0), [0.5, 1.0, 1.5], atol=1e-6)
    assert t.triangle_areas_m2.sum() == pytest.approx(2 * (0.5 * 1 + 0.5 * 1.5 + 1 * 1.5), rel=1e-6)


def test_obj_texture_is_used_with_v_up_as_the_obj_format_defines(tmp_path):
    # a unit square in the x-y plane, textured with an image whose top half is white
    m = o3d.geometry.TriangleMesh()
    m.vertices = o3d.utility.Vector3dVector([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
    m.triangles = o3d.utility.Vector3iVector([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 0], [1, 1], [0, 1.0]])
    m.triangle_uvs = o3d.utility.Vector2dVector(uv)
    img = np.zeros((64, 64, 3), np.uint8)
    img[:32] = 255
    m.textures = [o3d.geometry.Image(img)]
    m.triangle_material_ids = o3d.utility.IntVector([0, 0])
    path = tmp_path / "quad.obj"
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        o3d.io.write_triangle_mesh(str(path), m)
    t = load_mesh(path, unit_m=1.0, texture="file", center="none")
    # texture at the top edge of the square (y = 1, v = 1) and at the bottom (y = 0)
    top = t.sample_albedo(t.texture_coords([1], [[0.5, 0.45]]), [0.0], [1])
    bottom = t.sample_albedo(t.texture_coords([0], [[0.5, 0.05]]), [0.0], [0])
    assert top[0] == pytest.approx(1.0) and bottom[0] == pytest.approx(0.0)


def test_texture_lookup_at_texel_centres_returns_texel_times_albedo(fy1):
    rng = np.random.default_rng(0)
    xy = np.c_[rng.integers(0, fy1.texture.shape[1], 50), rng.integers(0, fy1.texture.shape[0], 50)]
    tid = rng.integers(0, fy1.n_triangles, 50)
    got = fy1.sample_albedo(xy.astype(float), np.zeros(50), tid)
    albedo = np.array([m.albedo for m in fy1.materials])[fy1.triangle_material[tid]]
    np.testing.assert_allclose(got, fy1.texture[xy[:, 1], xy[:, 0]] * albedo, atol=1e-6)


def test_texture_lookup_refuses_a_non_finite_mip_level_by_name(fy1):
    """A NaN level would index outside the pyramid's sample grid: refused, naming the parameter and value."""
    with pytest.raises(ValueError, match=r"level: must be finite, got np.float32\(nan\)|level: must be finite, got nan"):
        fy1.sample_albedo(np.array([[10.0, 10.0], [20.0, 20.0]]), np.array([0.0, np.nan]), np.array([0, 1]))


def test_mip_levels_are_box_filtered_means_of_the_finer_level(fy1):
    p = fy1.texture_pyramid
    np.testing.assert_allclose(p[1][10, 20], p[0][20:22, 40:42].mean(), atol=1e-6)
    assert p[4].shape == (p[0].shape[0] // 16, p[0].shape[1] // 16)


@pytest.mark.parametrize("kind", TEXTURE_KINDS)
def test_procedural_textures_are_seeded_bounded_and_textured(kind):
    a = procedural_texture(kind, 0.8, 0.5, texel_m=0.005, rng=3)
    assert a.shape == (100, 160) and a.dtype == np.float32
    assert a.min() >= 0.0 and a.max() <= 1.0 and a.std() > 0.05
    np.testing.assert_array_equal(a, procedural_texture(kind, 0.8, 0.5, texel_m=0.005, rng=3))


def test_target_pickles_without_its_raycasting_scene(fy1):
    _ = fy1.scene
    t = pickle.loads(pickle.dumps(fy1))
    assert "scene" not in t._cache
    np.testing.assert_array_equal(t.vertices_T, fy1.vertices_T)
    assert t.scene is not None


def test_load_mesh_rejects_bad_arguments_naming_them(tmp_path):
    with pytest.raises(ValueError, match="path"):
        load_mesh(tmp_path / "missing.obj", unit_m=1.0)
    with pytest.raises(ValueError, match="unit_m"):
        load_mesh(HUBBLE, unit_m=0.0)
    with pytest.raises(ValueError, match="texture"):
        load_mesh(HUBBLE, unit_m=1e-3, texture="file")


def test_material_and_target_validate_inputs():
    with pytest.raises(ValueError, match="kind"):
        Material("x", "velvet", 0.5)
    with pytest.raises(ValueError, match="albedo"):
        Material("x", "mli", 1.5)
    with pytest.raises(ValueError, match="triangles"):
        Target("t", np.zeros((3, 3)), np.array([[0, 1, 5]]), np.zeros((1, 3, 2)), np.zeros(1, int),
               (Material("x", "mli", 0.5),), np.zeros((16, 16)), 0.01)


def test_bundled_topex_by_name_is_the_inch_scaled_file():
    assert available_meshes() == ("hubble", "topex")
    by_name = load_mesh("topex", seed=0)
    by_path = load_mesh(bundled_mesh_path("topex"), unit_m=INCH_M, seed=0)
    np.testing.assert_array_equal(by_name.vertices_T, by_path.vertices_T)
    np.testing.assert_array_equal(by_name.texture, by_path.texture)
    assert by_name.n_triangles == 21158


def test_bundled_hubble_defaults_to_millimetres():
    t = load_mesh("hubble", center="none")
    np.testing.assert_allclose(np.ptp(t.vertices_T, axis=0), np.array([67.166, 91.901, 39.811]) * 1e-3,
                               atol=1e-8)


def test_unknown_mesh_names_are_refused_in_one_line_naming_the_known_ones():
    with pytest.raises(ValueError, match=r"^path: 'venus' is neither a bundled mesh \('hubble', 'topex'\)"):
        load_mesh("venus")
    with pytest.raises(ValueError, match=r"^name: unknown bundled mesh 'venus'; known: \('hubble', 'topex'\)$"):
        bundled_mesh_path("venus")
    with pytest.raises(ValueError, match="unit_m: required"):
        load_mesh(HUBBLE)
