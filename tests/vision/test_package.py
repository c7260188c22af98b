"""The vision package's face: light to import, every public name resolves to its submodule."""

import subprocess
import sys

import vision

HEAVY = ("open3d", "cv2", "pycolmap")


def test_import_vision_and_its_target_models_leave_open3d_opencv_and_pycolmap_unloaded():
    code = ("import sys, vision, vision.target, vision.observation, vision.camera; "
            f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_every_public_name_of_vision_resolves_lazily_to_its_submodule():
    for name in vision.__all__:
        obj = getattr(vision, name)
        assert obj.__module__.startswith("vision."), name
    assert set(vision.__all__) <= set(dir(vision))
    assert not set(vision.__all__) & set(vision._SUBMODULES)   # a submodule import would shadow it
