"""The Earth behind the target (vision.earth): limb geometry, albedo light, truth, and the unchanged default."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.ndimage import distance_transform_edt

from vision.camera import PinholeCamera, look_at
from vision.earth import EARTH_RADIUS_M, EarthScene
from vision.render import cast_body_points, render, render_batch
from vision.target import fy1_target

R_E = EARTH_RADIUS_M
R_ORBIT = R_E + 870e3
Q_IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def earth() -> EarthScene:
    return EarthScene(R_ORBIT, np.random.default_rng(7))


@pytest.fixture(scope="module")
def target():
    return fy1_target()


def _plate_irradiance_sun_at_zenith(r_m: float, albedo: float) -> float:
    """E/E_sun on a plate facing nadir from a Lambertian sphere lit from the zenith, by a surface integral
    over the sphere (independent of the module's solid-angle quadrature): ∫ L cos α cos β / D² dA / π."""
    def f(g):
        D = np.sqrt(R_E**2 + r_m**2 - 2 * R_E * r_m * np.cos(g))
        cos_a, cos_b = (r_m - R_E * np.cos(g)) / D, (r_m * np.cos(g) - R_E) / D
        return albedo * np.cos(g) * cos_a * cos_b / D**2 * 2 * np.pi * R_E**2 * np.sin(g) / np.pi
    return quad(f, 0.0, np.arccos(R_E / r_m), epsabs=0, epsrel=1e-10)[0]


def test_earth_pixels_are_where_the_limb_angle_asin_re_over_r_puts_them(earth):
    # a camera at the target, its optical axis on the limb: a pixel sees the Earth iff its ray is within ρ of nadir
    rho = np.arcsin(R_E / R_ORBIT)
    assert earth.limb_half_angle_rad == pytest.approx(rho, rel=1e-15)
    assert np.degrees(rho) == pytest.approx(61.64, abs=0.01)
    cam = PinholeCamera.from_fov(200, 160, fov_x_deg=30.0)
    axis = np.array([-np.cos(rho), np.sin(rho), 0.0])
    T = look_at(np.zeros(3), axis, np.array([0.0, 0.0, 1.0]))
    bg = earth.background(cam, T, (0, 0, 200, 160), [1.0, 0.0, 0.0])   # Sun at the zenith: the whole cap lit
    uu, vv = np.meshgrid(np.arange(200.0), np.arange(160.0))
    d_C = np.stack([(uu - cam.cx) / cam.fx, (vv - cam.cy) / cam.fy, np.ones_like(uu)], -1)
    d_H = d_C @ T[:3, :3]
    angle = np.arccos(-d_H[..., 0] / np.linalg.norm(d_H, axis=-1))
    clear = np.abs(angle - rho) > 1e-6
    assert np.array_equal((bg > 0)[clear], (angle < rho)[clear])
    assert 0.2 < (bg > 0).mean() < 0.8
    # 1e-9 rad either side of the limb, rays from the target
    d = np.array([[-np.cos(rho - 1e-9), np.sin(rho - 1e-9), 0], [-np.cos(rho + 1e-9), np.sin(rho + 1e-9), 0]])
    hit, m, t = earth.intersect(np.zeros(3), d)
    assert hit.tolist() == [True, False]
    assert t[0] == pytest.approx(np.sqrt(R_ORBIT**2 - R_E**2), rel=1e-4)      # about the tangent length
    assert np.linalg.norm(m[0]) == pytest.approx(1.0)


def test_black_sky_looking_away_from_the_earth_and_a_dark_night_side(earth):
    cam = PinholeCamera.from_fov(128, 128, fov_x_deg=60.0)
    up = look_at(np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))
    assert not earth.background(cam, up, (0, 0, 128, 128), [1.0, 0.0, 0.0]).any()
    down = look_at(np.zeros(3), np.array([-1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))
    assert (earth.background(cam, down, (0, 0, 128, 128), [1.0, 0.0, 0.0]) > 0.02).all()
    assert not earth.background(cam, down, (0, 0, 128, 128), [-1.0, 0.0, 0.0]).any()   # midnight below


def test_texture_is_seeded_and_its_mean_is_the_albedo(earth):
    w, _ = earth._cap_directions()
    hit, m, _ = earth.intersect(np.zeros(3), w)
    a = earth.surface_albedo(m[hit], np.full(hit.sum(), 1e3))
    assert a.mean() == pytest.approx(0.3, abs=0.08)
    assert a.min() >= 0.05 and a.max() <= 0.9 and a.std() > 0.05
    again = EarthScene(R_ORBIT, np.random.default_rng(7)).surface_albedo(m[hit], 1e3)
    other = EarthScene(R_ORBIT, np.random.default_rng(8)).surface_albedo(m[hit], 1e3)
    assert np.array_equal(a, again) and not np.allclose(a, other)
    half = EarthScene(R_ORBIT, np.random.default_rng(7), albedo=0.15).surface_albedo(m[hit], 1e3)
    np.testing.assert_allclose(half, 0.5 * a, rtol=1e-6)


@pytest.mark.parametrize("altitude_m", [400e3, 870e3, 2000e3])
def test_albedo_irradiance_on_a_nadir_plate_is_the_lambert_sphere_integral(altitude_m):
    e = EarthScene(R_E + altitude_m, np.random.default_rng(0), albedo=0.3)
    E = e.albedo_irradiance([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [1.0, 0.0, 0.0])
    assert E[0] == pytest.approx(_plate_irradiance_sun_at_zenith(R_E + altitude_m, 0.3), rel=5e-4)
    assert E[0] < 0.3 * (R_E / (R_E + altitude_m)) ** 2     # below the uniform-disc bound A sin²ρ
    assert E[1] == 0.0                                          # facing the zenith: no Earth light
    assert e.albedo_irradiance([[-1.0, 0.0, 0.0]], [-1.0, 0.0, 0.0])[0] == 0.0   # night below


def test_albedo_light_brightens_the_face_toward_the_earth_by_the_lambert_amount(earth, target):
    # camera between the target and the Earth, looking up at the bus's nadir face; the direct Sun off
    cam = PinholeCamera.from_fov(256, 256, fov_x_deg=20.0)
    T = look_at(np.array([-30.0, 0.0, 0.3]), np.zeros(3), np.array([0.0, 0.0, 1.0]))
    opts = dict(rng=3, sun_visible_fraction=0.0, specular=False)
    r_albedo = render(cam, T, target, Q_IDENTITY, [1.0, 0.0, 0.0], ambient=1.0, **opts)   # radiance = albedo
    r_earth = render(cam, T, target, Q_IDENTITY, [1.0, 0.0, 0.0], earth=earth, **opts)
    normals = target.triangle_normals_T[r_earth.triangle_id[r_earth.mask]]
    nadir_face = np.abs(normals[:, 0]) > 1 - 1e-9
    assert nadir_face.sum() > 500
    ratio = r_earth.radiance[r_earth.mask][nadir_face] / r_albedo.radiance[r_albedo.mask][nadir_face]
    np.testing.assert_allclose(ratio, _plate_irradiance_sun_at_zenith(R_ORBIT, 0.3), rtol=1e-3)
    # the sky above the target stays black behind it (the camera looks away from the Earth)
    assert not r_earth.radiance[r_earth.roi_slices][~r_earth.mask[r_earth.roi_slices]].any()


def _down_view(range_m: float = 40.0):
    cam = PinholeCamera.from_fov(512, 512, fov_x_deg=20.0)
    eye = range_m * np.array([0.8, 0.36, 0.48])
    return cam, look_at(eye, np.zeros(3), np.array([0.0, 0.0, 1.0]))


def test_background_pixels_never_carry_body_point_truth(earth, target):
    cam, T = _down_view()
    q = np.array([0.9, 0.1, 0.3, 0.2]) / np.linalg.norm([0.9, 0.1, 0.3, 0.2])
    r = render(cam, T, target, q, [0.7, 0.5, 0.4], rng=1, earth=earth)
    rs = r.roi_slices
    background = ~r.mask[rs]
    assert (r.radiance[rs][background] > 0.01).mean() > 0.9                # the Earth fills the ROI around it
    assert np.isnan(r.X_T[rs][background]).all() and (r.triangle_id[rs][background] == -1).all()
    assert not r.lit[rs][background].any() and np.isnan(r.depth_z_m[rs][background]).all()
    rows, cols = np.nonzero(background)
    far = distance_transform_edt(background)[rows, cols] > 3        # more than 3 px off the silhouette
    uv = np.stack([cols[far] + r.roi[0], rows[far] + r.roi[1]], 1)[::97].astype(float)
    X, z = cast_body_points(cam, T, target, q, uv)
    assert np.isnan(X).all() and np.isnan(z).all()
    assert np.isnan(r.body_points_at(uv)).all()


def test_default_and_an_earthless_view_are_bit_identical_to_the_black_sky(target):
    # a camera below the target looking up: the Earth is out of view; with no albedo light every output
    # array equals the black-sky render's, through render and render_batch
    cam = PinholeCamera.from_fov(256, 256, fov_x_deg=20.0)
    T = look_at(np.array([-30.0, 5.0, 3.0]), np.zeros(3), np.array([0.0, 0.0, 1.0]))
    dark = EarthScene(R_ORBIT, np.random.default_rng(1), albedo=0.0)
    q = np.array([0.8, 0.2, -0.3, 0.1]) / np.linalg.norm([0.8, 0.2, -0.3, 0.1])
    sun = [-0.2, 0.6, 0.7]
    a = render(cam, T, target, q, sun, rng=5)
    b = render(cam, T, target, q, sun, rng=5, earth=dark)
    c = render_batch([cam], T[None], target, q, sun, rngs=[np.random.default_rng(5)], earth=dark)[0]
    assert a.mask.any()
    for name in ("image", "radiance", "depth_z_m", "mask", "X_T", "triangle_id", "lit"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        np.testing.assert_array_equal(getattr(a, name), getattr(c, name), err_msg=name)
    assert a.exposure_s == b.exposure_s == c.exposure_s


def test_render_batch_with_the_earth_equals_render(earth, target):
    cam, T = _down_view(80.0)
    q = np.array([0.5, 0.5, 0.5, 0.5])
    sun = [0.8, -0.3, 0.5]
    one = render(cam, T, target, q, sun, rng=np.random.default_rng(2), earth=earth)
    batch = render_batch([cam], T[None], target, q, sun, rngs=[np.random.default_rng(2)], earth=earth)[0]
    np.testing.assert_array_equal(one.image, batch.image)
    np.testing.assert_array_equal(one.radiance, batch.radiance)
    assert (one.radiance[one.roi_slices][~one.mask[one.roi_slices]] > 0).any()


@pytest.mark.parametrize(("kwargs", "match"), [
    (dict(orbit_radius_m=R_E - 1.0), "orbit_radius_m"),
    (dict(orbit_radius_m=R_ORBIT, albedo=1.2), "albedo"),
    (dict(orbit_radius_m=R_ORBIT, quadrature=(0, 4)), "quadrature"),
])
def test_bad_earth_scene_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        EarthScene(rng=np.random.default_rng(0), **kwargs)
