"""The closed_loop package's face: light to import, every public name resolves to its submodule."""

import subprocess
import sys

import pytest

import closed_loop


def test_import_closed_loop_leaves_casadi_numba_and_opencv_unloaded():
    code = "import sys, closed_loop; print(sorted(m for m in ('casadi', 'numba', 'cv2', 'open3d') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_every_public_name_resolves_lazily_to_its_submodule():
    for name in closed_loop.__all__:
        value = getattr(closed_loop, name)
        module = getattr(value, "__module__", None) or type(value).__module__
        assert module.startswith("closed_loop."), name
    assert not set(closed_loop.__all__) & set(closed_loop._SUBMODULES)


def test_unknown_attribute_is_an_attribute_error():
    with pytest.raises(AttributeError, match="closed_loop attribute Nothing"):
        closed_loop.Nothing  # noqa: B018
