"""The documentation site: its generated pages cover the code and the configs, and it builds offline.

The generators of ``docs/gen_*.py`` are checked against independent readers: the shipped config
files read with ``tomllib``, the public names read from
the imported packages' ``__all__``; then the whole site is built with ``mkdocs build --strict`` with
the network closed, and every API name is checked to have its anchor in the HTML.  The bounds and
choices the config reference shows are checked by validating values at and beside them.
"""

from __future__ import annotations

import importlib
import math
import os
import pkgutil
import re
import subprocess
import sys
import tomllib
import typing
from pathlib import Path
from typing import Annotated

import numpy as np
import pydantic
import pytest
from pydantic.fields import FieldInfo

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))

gen_api = pytest.importorskip("gen_api", reason="the docs extra (griffe) is not installed")
import gen_config_reference  # noqa: E402
import gen_gallery  # noqa: E402

from experiments.config import KINDS, kind_module  # noqa: E402


@pytest.fixture(scope="module")
def rows():
    return gen_config_reference.reference_rows()


def _flatten(table: dict, prefix: str, known: set[str], free: set[str]) -> list[str]:
    """Dotted keys of a TOML table: arrays of tables as ``key[].sub``, user-named keys as ``<key>``."""
    keys = []
    for name, value in table.items():
        key = f"{prefix}{name}"
        keys.append(key)
        if isinstance(value, dict):
            if key in free:
                for sub, v in value.items():
                    keys.append(f"{key}.{gen_config_reference.FREE_KEY}")
                    if isinstance(v, dict):
                        keys += _flatten(v, f"{key}.{gen_config_reference.FREE_KEY}.", known, free)
                    del sub
            else:
                keys += _flatten(value, f"{key}.", known, free)
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for item in value:
                keys += _flatten(item, f"{key}[].", known, free)
    return keys


def test_config_reference_lists_every_key_of_every_shipped_config(rows):
    configs = sorted((ROOT / "experiments" / "configs").glob("*.toml"))
    assert len(configs) >= 9
    for path in configs:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
        kind_rows = rows[raw["kind"]]
        known = {r.key for r in kind_rows}
        free = {r.key for r in kind_rows if r.free}
        missing = [k for k in _flatten(raw, "", known, free) if k not in known]
        assert not missing, f"{path.name}: keys missing from the config reference: {missing}"
        # the swept keys are config keys too
        for key in raw.get("sweep", {}).get("grid", {}):
            assert key in known, f"{path.name}: swept key {key} is not in the config reference"


def _field(model: type[pydantic.BaseModel], key: str) -> FieldInfo:
    """The pydantic field of a dotted key (``a.b``, ``a[].b``) of a config model."""
    models = [model]
    info = None
    for part in key.split("."):
        if info is not None:  # a union of tables (``SweepConfig | SweepSpec``): the one holding the key
            models = [m for m in _classes(info.annotation) if issubclass(m, pydantic.BaseModel)]
        name = part.removesuffix("[]")
        info = next(m.model_fields[name] for m in models if name in m.model_fields)
    return info


def _classes(tp: object) -> list[type]:
    args = typing.get_args(tp)
    return [tp] if isinstance(tp, type) and not args else [c for a in args for c in _classes(a)]


def _step(value: float, toward: float, integer: bool) -> float:
    return value + (1 if toward > value else -1) if integer else float(np.nextafter(value, toward))


def test_config_reference_ranges_and_choices_are_what_validation_accepts(rows):
    """Each shown bound: the bound itself passes or fails as its operator says, the next value inward
    passes; each shown choice passes and another string fails (validated by the field's own type)."""
    checked = 0
    for kind, kind_rows in rows.items():
        model = kind_module(kind).Config
        for r in kind_rows:
            if gen_config_reference.FREE_KEY in r.key or r.table or r.type.startswith(("list", "[")):
                continue
            info = _field(model, r.key)
            tp = Annotated[(info.annotation, *info.metadata)] if info.metadata else info.annotation
            adapter = pydantic.TypeAdapter(tp)
            integer = info.annotation is int
            for op, text in re.findall(r"(?:^|, )([><≥≤]) (-?[\d.e+]+)", r.range):
                bound = int(text) if integer else float(text)
                inward = _step(bound, math.inf if op in "≥>" else -math.inf, integer)
                adapter.validate_python(inward)
                if op in "≥≤":
                    adapter.validate_python(bound)
                else:
                    with pytest.raises(pydantic.ValidationError):
                        adapter.validate_python(bound)
                outward = _step(bound, -math.inf if op in "≥>" else math.inf, integer)
                with pytest.raises(pydantic.ValidationError):
                    adapter.validate_python(outward if op in "≥≤" else bound)
                checked += 1
            for choice in re.findall(r'"([^"]*)"', r.type) if r.type.startswith("one of") else []:
                adapter.validate_python(choice)
                with pytest.raises(pydantic.ValidationError):
                    adapter.validate_python(choice + "-not-a-choice")
                checked += 1
    assert checked > 150


def test_config_reference_page_names_every_kind_and_value_type(rows):
    page = gen_config_reference.config_reference(ROOT)
    for kind in KINDS:
        assert f"\n## {kind}\n" in page
    for name, doc in gen_config_reference.value_types(ROOT):
        assert doc, f"value type {name} has no #: description"
        assert f"| `{name}` |" in page


def _runtime_exports(package: str) -> dict[str, object]:
    """``module.name`` → object for every name in the ``__all__`` of the package and its public modules."""
    pkg = importlib.import_module(package)
    modules = [pkg]
    for info in pkgutil.walk_packages(pkg.__path__, prefix=f"{package}."):
        hidden = any(info.name == h or info.name.startswith(h + ".") for h in gen_api.HIDDEN)
        if not hidden and not any(part.startswith("_") for part in info.name.split(".")):
            modules.append(importlib.import_module(info.name))
    found = {}
    for module in modules:
        for name in getattr(module, "__all__", []):
            obj = getattr(module, name)
            if not isinstance(obj, type(sys)):
                found[f"{module.__name__}.{name}"] = obj
    return found


def test_api_pages_render_every_name_of_every_public_all():
    pages = gen_api.api_pages(ROOT)
    assert [p.package for p in pages] == list(gen_api.PACKAGES)
    for page in pages:
        rendered = {}
        for path in page.names():
            module, _, name = path.rpartition(".")
            rendered.setdefault(name, []).append(getattr(importlib.import_module(module), name))
        for path, obj in _runtime_exports(page.package).items():
            name = path.rpartition(".")[2]
            assert any(o is obj for o in rendered.get(name, [])), f"{path} is not on the API page of {page.package}"


def test_gallery_page_shows_each_example_with_its_figure_and_source(tmp_path):
    (tmp_path / "examples").mkdir()
    (tmp_path / "docs" / "figures" / "gallery").mkdir(parents=True)
    (tmp_path / "examples" / "spin_up.py").write_text('"""Spin-up of a target.\n\nIt spins.\n"""\nx = 1\n')
    (tmp_path / "examples" / "_helpers.py").write_text("y = 2\n")
    (tmp_path / "docs" / "figures" / "gallery" / "spin_up.png").write_bytes(b"\x89PNG")
    page = gen_gallery.gallery_page(tmp_path)
    assert "## Spin-up of a target\n\nIt spins." in page
    assert "![Spin-up of a target](figures/gallery/spin_up.png)" in page
    assert "    x = 1" in page and "_helpers" not in page
    (tmp_path / "examples" / "bare.py").write_text("x = 1\n")
    with pytest.raises(ValueError, match="bare.py: no module docstring"):
        gen_gallery.gallery_page(tmp_path)


_NO_NETWORK = """
import socket, sys
def refuse(*args, **kwargs):
    raise OSError("network access during the docs build")
socket.socket.connect = refuse
socket.create_connection = refuse
sys.argv = ["mkdocs", "build", "--strict", "--site-dir", sys.argv[1]]
from mkdocs.__main__ import cli
cli()
"""


@pytest.mark.slow
def test_site_builds_strict_and_offline_with_an_anchor_for_every_api_name(tmp_path):
    pytest.importorskip("mkdocs")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "DISABLE_MKDOCS_2_WARNING": "true", "MPLBACKEND": "Agg"}
    site = tmp_path / "site"
    proc = subprocess.run([sys.executable, "-c", _NO_NETWORK, str(site)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "WARNING" not in proc.stderr, proc.stderr[-3000:]
    for page in gen_api.api_pages(ROOT):
        html = (site / "api" / f"{page.package}.html").read_text(encoding="utf-8")
        ids = set(re.findall(r'id="([^"]+)"', html))
        missing = sorted(page.names() - ids)
        assert not missing, f"api/{page.package}.html lacks {missing}"
    for name in ("index.html", "config-reference.html", "gallery.html", "cluster.html", "architecture.html"):
        assert (site / name).is_file()
