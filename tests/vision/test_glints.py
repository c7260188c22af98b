"""Glint lobes on MLI and solar cells (vision.glints): a mirror geometry saturates only with glints on."""

from __future__ import annotations

import numpy as np
import pytest

from attitude.quaternion import quat_from_rotvec
from vision.camera import PinholeCamera, look_at
from vision.glints import GLINT_LOBES, glint_material, with_glints
from vision.render import render
from vision.sensor import SensorModel
from vision.target import fy1_target


@pytest.fixture(scope="module")
def targets():
    t = fy1_target()
    return t, with_glints(t)


def test_glint_materials_are_normalised_blinn_phong_lobes(targets):
    plain, shiny = targets
    assert shiny.name == plain.name
    for before, after in zip(plain.materials, shiny.materials, strict=True):
        if before.kind in GLINT_LOBES:
            R, ns = GLINT_LOBES[before.kind]
            assert after.shininess == ns and after.specular == pytest.approx(R * (ns + 8) / 8)
            assert after.specular > 10 * before.specular
        else:
            assert after == before
        assert after.albedo == before.albedo
    assert glint_material(plain.materials[-1]) is plain.materials[-1]
    np.testing.assert_array_equal(shiny.texture, plain.texture)
    with pytest.raises(ValueError, match="target must be a Target"):
        with_glints("fy1")


def test_the_sun_mirrored_by_the_bus_saturates_the_sensor_only_with_glints(targets):
    plain, shiny = targets
    # the bus's +x MLI face toward H's x; camera and Sun 4° either side of its normal: half vector = normal
    cam = PinholeCamera.from_fov(256, 256, fov_x_deg=20.0)
    tilt = np.radians(4.0)
    eye = 40.0 * np.array([np.cos(tilt), np.sin(tilt), 0.0])
    sun = np.array([np.cos(tilt), -np.sin(tilt), 0.0])
    T = look_at(eye, np.zeros(3), np.array([0.0, 0.0, 1.0]))
    q = np.asarray(quat_from_rotvec(np.zeros(3)))
    fixed = SensorModel(auto_exposure=False)          # 1 ms: a white surface facing the Sun at 60 % of full scale
    a = render(cam, T, plain, q, sun, rng=4, sensor=fixed)
    b = render(cam, T, shiny, q, sun, rng=4, sensor=fixed)
    mli = np.isin(plain.triangle_material[b.triangle_id[b.mask]],
                  [i for i, m in enumerate(plain.materials) if m.kind == "mli"])
    assert mli.sum() > 300
    assert (a.image == 255).sum() == 0
    assert (b.image == 255)[b.mask][mli].mean() > 0.5                         # the glint fills the face
    assert b.radiance[b.mask][mli].max() > 10 * a.radiance[a.mask][mli].max()
    np.testing.assert_array_equal(a.mask, b.mask)
    np.testing.assert_array_equal(a.X_T, b.X_T)
    # under auto-exposure the glint sets the exposure: the rest of the target goes dark
    a_auto, b_auto = render(cam, T, plain, q, sun, rng=4), render(cam, T, shiny, q, sun, rng=4)
    assert b_auto.exposure_s < a_auto.exposure_s / 5
