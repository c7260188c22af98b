"""The Earth-background / glints study (experiments.studies.earth_scenes) on one small cell."""

from __future__ import annotations

import numpy as np
import pytest

from experiments.studies.earth_scenes import SCENES, SceneSpec, format_table, measure, scene_figure

SPEC = SceneSpec(targets=("fy1",), ranges_m=(40.0,), attitudes=1, image_px=384)


@pytest.fixture(scope="module")
def rows():
    return measure(SPEC)


def test_only_the_earth_scene_has_background_keypoints_and_counts_are_consistent(rows):
    assert sorted((r["scene"], r["views"]) for r in rows) == sorted((s, n) for s in SCENES for n in (2, 3))
    by = {(r["scene"], r["views"]): r for r in rows}
    for n in (2, 3):
        assert by["black", n]["kp_background"] == 0 and by["glints", n]["kp_background"] == 0
        assert by["earth", n]["kp_background"] > 0
        assert by["black", n]["kp_target"] > 0
    for r in rows:
        assert r["epochs"] == 1
        assert 0 <= r["false_background"] <= r["false"] <= r["tracks"]
        assert 0 <= r["assoc_false"] <= r["assoc"]
        assert r["views"] == 2 or r["assoc"] == 0
    table = format_table(rows)
    assert table.count("\n") == 1 + len(rows) and "| fy1 | 40 m | 3 | earth |" in table


def test_the_figure_is_three_images_side_by_side(tmp_path):
    import cv2

    path = tmp_path / "scenes.png"
    scene_figure(str(path), SPEC)
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    assert image is not None and image.shape[1] > 2 * image.shape[0] / 3
    third = (image.shape[1] - 16) // 3
    black, earth = image[:, :third], image[:, third + 8:2 * third + 8]
    assert np.mean(earth > 10) > np.mean(black > 10) + 0.3         # the Earth fills the background
