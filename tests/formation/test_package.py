"""The formation package's face: light to import, every public name resolves to its submodule."""

import subprocess
import sys

import formation


def test_import_formation_leaves_casadi_unloaded():
    code = "import sys, formation; print('casadi' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_every_public_name_of_formation_resolves_lazily_to_its_submodule():
    for name in formation.__all__:
        assert getattr(formation, name).__module__.startswith("formation."), name
    assert not set(formation.__all__) & set(formation._SUBMODULES)   # a submodule import would shadow it
