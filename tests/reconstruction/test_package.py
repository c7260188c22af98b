"""The package face: a light ``import reconstruction`` and every public name reachable from it."""

from __future__ import annotations

import subprocess
import sys


def test_import_reconstruction_loads_no_heavy_dependency_until_a_name_is_used():
    code = (
        "import sys, reconstruction as r\n"
        "heavy = [m for m in ('numba', 'scipy', 'open3d', 'cv2', 'pycolmap') if m in sys.modules]\n"
        "assert not heavy, heavy\n"
        "assert sorted(dir(r)) == sorted(r.__all__)\n"
        "for name in r.__all__:\n"
        "    assert getattr(r, name).__name__ == name, name\n"
        "assert 'open3d' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


def test_registration_package_keeps_the_public_names_of_the_former_module():
    import reconstruction.registration as reg

    assert set(reg.__all__) == {"RigidRegistration", "fit_rigid", "fit_rigid_robust",
                                "fit_rigid_ml", "register_icp", "register_fpfh_ransac"}
    for name in reg.__all__:
        assert callable(getattr(reg, name))
