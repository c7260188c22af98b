"""Specular glints on MLI and solar cells: a target whose shiny materials reflect the Sun as they do in orbit.

The renderer's specular term is Blinn–Phong, ``ks · max(0, n·h)^ns`` on sunlit points, in units of
the radiance of a white Lambertian surface facing the full Sun (:mod:`vision.render`).  The
targets' default materials are mild (FY-1: MLI ``ks`` 0.25, ``ns`` 25; solar cells 0.35, 60; the
bundled meshes 0.1, 20): a highlight at most ≈ 1.5× the diffuse level, never saturating the sensor.
Real ones are not:

* a mirror reflecting the Sun has the Sun's radiance times its reflectance, ``R · π / Ω_sun ≈
  R · 4.6·10⁴`` white-Lambert units (``Ω_sun = 6.8·10⁻⁵ sr``), so any glint saturates a camera
  exposed for the diffuse surfaces;
* crinkled MLI (aluminised or goldised Kapton) reflects specularly with ``R ≈ 0.6`` into a lobe a
  few degrees wide set by its wrinkles;
* solar cells' cover glass reflects ``R ≈ 0.05`` (Fresnel, anti-reflection coated) into a lobe
  about a degree wide.

:func:`with_glints` gives these as normalised Blinn–Phong lobes: a half-vector lobe of angular σ
``1/√ns`` (MLI ``ns`` = 150, σ ≈ 4.7°; cells 3000, σ ≈ 1.0°) with the energy-conserving peak
``ks = R (ns + 8) / 8`` (MLI 11.9, cells 18.8: 20–40× the diffuse level, saturating under the
auto-exposure of :class:`vision.sensor.SensorModel`).  The lobe is still smooth per flat triangle:
the wrinkles' texture does not modulate it.
"""

from __future__ import annotations

import dataclasses

from vision.target import Material, Target

__all__ = ["GLINT_LOBES", "glint_material", "with_glints"]

#: material kind → (specular reflectance R, Blinn–Phong exponent ns) of the glint model
GLINT_LOBES: dict[str, tuple[float, float]] = {"mli": (0.6, 150.0), "solar_cells": (0.05, 3000.0)}


def glint_material(material: Material) -> Material:
    """``material`` with the glint lobe of its kind (unchanged when its kind has none)."""
    lobe = GLINT_LOBES.get(material.kind)
    if lobe is None:
        return material
    reflectance, ns = lobe
    return dataclasses.replace(material, specular=reflectance * (ns + 8.0) / 8.0, shininess=ns)


def with_glints(target: Target) -> Target:
    """A copy of ``target`` whose MLI and solar-cell materials have the glint lobes of :data:`GLINT_LOBES`
    (same mesh, texture, name and seed; its own ray-casting scene, built on first use)."""
    if not isinstance(target, Target):
        raise ValueError(f"target must be a Target, got {type(target).__name__}")
    materials = tuple(glint_material(m) for m in target.materials)
    return dataclasses.replace(target, materials=materials)
