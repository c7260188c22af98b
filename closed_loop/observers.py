"""Observers: how the cameras see the target at one epoch (rendered images or the geometric model).

An :class:`Observer` turns camera poses, the target's attitude in H and the Sun direction into a
:class:`vision.observation.Observation` (multi-view feature tracks).  :data:`OBSERVERS` lists the
alternatives by the names the configs use.
"""

from __future__ import annotations

import functools
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from closed_loop.registry import Registry
from vision.camera import PinholeCamera
from vision.observation import Observation
from vision.target import Target

__all__ = ["Observer", "RenderedObserver", "GeometricObserver", "OBSERVERS"]


def _unit(sun_H: np.ndarray) -> np.ndarray:
    sun = np.asarray(sun_H, dtype=float)
    return sun / np.linalg.norm(sun)


class Observer(ABC):
    """One epoch seen by ``n`` identical cameras aimed at the target."""

    camera: PinholeCamera
    target: Target

    @abstractmethod
    def observe(self, T_CW: np.ndarray, q_HT: np.ndarray, sun_H: np.ndarray, *, rng: np.random.Generator,
                sun_visible_fraction: float = 1.0) -> Observation:
        """Observe the target once.

        Parameters
        ----------
        T_CW : ndarray (n, 4, 4)
            Camera poses (H → camera frame C), m.
        q_HT : ndarray (4,)
            Target attitude in H, scalar-first ``[w, x, y, z]``.
        sun_H : ndarray (3,)
            Direction to the Sun in H (any length; normalised here).
        rng : numpy.random.Generator
            The epoch's random stream (split per camera inside the observation).
        sun_visible_fraction : float
            Fraction of the solar disc visible from the target (0 in Earth's shadow).

        Returns
        -------
        vision.observation.Observation
            The tracks of the epoch (an empty, flagged observation when nothing is seen).
        """


@dataclass(frozen=True)
class RenderedObserver(Observer):
    """Ray-cast images, a feature detector and multi-view matching (:func:`vision.rendered.observe`).

    Attributes
    ----------
    camera : vision.camera.PinholeCamera
    target : vision.target.Target
    pixel_sigma_px : float
        Feature localisation noise σ given to the tracks, px.
    detector : str
        ``"sift"``, ``"orb"``, ``"akaze"`` or ``"surf"``.
    noise_model : str
        ``"fixed"``: every keypoint gets ``pixel_sigma_px``; ``"calibrated"``: each keypoint the σ
        measured for its SIFT size, scaled by its epoch's variance factor (:mod:`vision.calibration`,
        :mod:`vision.epoch_variance`).
    earth_background : bool
        The Earth behind the target and its albedo light (:class:`vision.earth.EarthScene`, drawn once
        from ``earth_seed`` for a target ``orbit_radius_m`` from the Earth's centre, mean albedo ``earth_albedo``).
    glints : bool
        Glint lobes on MLI and solar cells (:func:`vision.glints.with_glints`).
    """

    camera: PinholeCamera
    target: Target
    pixel_sigma_px: float = 0.5
    detector: str = "sift"
    noise_model: str = "fixed"
    earth_background: bool = False
    earth_albedo: float = 0.3
    glints: bool = False
    orbit_radius_m: float = 6_378_137.0 + 870e3
    earth_seed: int = 0

    def __post_init__(self):
        # every camera-frame allocates and frees image-sized buffers: keep them in the process
        # (vision.allocator; how memory is reused, not what is computed)
        from vision.allocator import retain_freed_memory

        retain_freed_memory()

    def observe(self, T_CW: np.ndarray, q_HT: np.ndarray, sun_H: np.ndarray, *, rng: np.random.Generator,
                sun_visible_fraction: float = 1.0) -> Observation:
        """Render every camera's image and match the features across the views (see :meth:`Observer.observe`)."""
        from vision.rendered import observe

        earth = _earth(self.orbit_radius_m, self.earth_albedo, self.earth_seed) if self.earth_background else None
        target = _glint_target(self.target) if self.glints else self.target
        return observe(self.camera, T_CW, target, q_HT, _unit(sun_H), rng=rng, detector=self.detector,
                       pixel_sigma_px=self.pixel_sigma_px, sun_visible_fraction=sun_visible_fraction,
                       noise_model=self.noise_model, earth=earth)


@functools.lru_cache(maxsize=4)
def _earth(orbit_radius_m: float, albedo: float, seed: int):
    from vision.earth import EarthScene

    return EarthScene(orbit_radius_m, np.random.default_rng(seed), albedo=albedo)


@functools.lru_cache(maxsize=4)
def _glint_target(target: Target) -> Target:
    from vision.glints import with_glints

    return with_glints(target)


@functools.lru_cache(maxsize=4)
def _surface_features(target: Target, n_features: int, surface: str = "all"):
    from vision.geometric import surface_features

    return surface_features(target, n_features=n_features, surface=surface)


@functools.lru_cache(maxsize=8)
def _site_features(target: Target, footprint_m_per_px: float, n_fillers: int):
    from vision.texture_sites import site_features

    fillers = _surface_features(target, n_fillers, "outer") if n_fillers > 0 else None
    return site_features(target, footprint_m_per_px, fillers=fillers)


@dataclass(frozen=True)
class GeometricObserver(Observer):
    """Surface features projected with noise, occlusion and false matches (:mod:`vision.geometric`).

    Attributes
    ----------
    camera : vision.camera.PinholeCamera
    target : vision.target.Target
    pixel_sigma_px : float
        Feature localisation noise σ, px.
    false_match_fraction : float
        Fraction of tracks that are false matches.
    n_features : int
        Surface features sampled on the target (sampled once per target and count, then reused);
        the calibrated model raises it to what the measured detection density needs.
    noise_model : str
        ``"fixed"``: ``pixel_sigma_px`` and ``false_match_fraction``; ``"calibrated"``: detection,
        σ per keypoint size, match and association survival and false rates as measured on rendered
        images (:mod:`vision.geometric_calibrated`).
    calibrated_features : str
        Where the calibrated model's features lie: ``"texture"`` (default) on the SIFT keypoint sites
        of the target's textures at the cameras' image footprint (:mod:`vision.texture_sites`),
        ``"uniform"`` spread uniformly by area over the outer surface (the model before the sites).
    """

    camera: PinholeCamera
    target: Target
    pixel_sigma_px: float = 0.5
    false_match_fraction: float = 0.02
    n_features: int = 2000
    noise_model: str = "fixed"
    calibrated_features: str = "texture"

    def observe(self, T_CW: np.ndarray, q_HT: np.ndarray, sun_H: np.ndarray, *, rng: np.random.Generator,
                sun_visible_fraction: float = 1.0) -> Observation:
        """Project the visible features into every camera (see :meth:`Observer.observe`)."""
        return self.observe_epochs(np.asarray(T_CW)[None], np.asarray(q_HT)[None], _unit(sun_H)[None], rng=rng,
                                   sun_visible_fraction=sun_visible_fraction)[0]

    def observe_epochs(self, T_CW: np.ndarray, q_HT: np.ndarray, sun_H: np.ndarray, *, rng: np.random.Generator,
                       sun_visible_fraction: float | np.ndarray = 1.0) -> Sequence[Observation]:
        """``E`` epochs in one batched call (:func:`vision.geometric.observe_epochs`).

        Parameters
        ----------
        T_CW : ndarray (E, n, 4, 4)
            Camera poses per epoch.
        q_HT : ndarray (E, 4)
            Target attitudes in H.
        sun_H : ndarray (E, 3)
            Unit directions to the Sun in H (used as given).
        rng : numpy.random.Generator
            One stream for the whole call: the draws depend on all the epochs, so a call must cover
            one trial's epochs only.
        sun_visible_fraction : float or ndarray (E,)

        Returns
        -------
        list of vision.observation.Observation
            One per epoch.
        """
        from vision.geometric import observe_epochs

        return observe_epochs(self.camera, T_CW, self.target, q_HT, sun_H, rng=rng, features=self._features(T_CW),
                              pixel_sigma_px=self.pixel_sigma_px, false_match_fraction=self.false_match_fraction,
                              sun_visible_fraction=sun_visible_fraction, noise_model=self.noise_model)

    def observe_trials(self, T_CW: np.ndarray, q_HT: np.ndarray, sun_H: np.ndarray, *,
                       rngs: Sequence[np.random.Generator]) -> list[list[Observation]]:
        """R independent trials of E epochs (``T_CW (R, E, n, 4, 4)``, ``q_HT (R, E, 4)``, unit ``sun_H
        (R, E, 3)``), one generator per trial: trial r gives what :meth:`observe_epochs` gives with
        ``rngs[r]``; the calibrated model batches the trials' geometry (:func:`vision.geometric.observe_trials`)."""
        from vision.geometric import observe_trials

        return observe_trials(self.camera, T_CW, self.target, q_HT, sun_H, rngs=rngs, features=self._features(T_CW),
                              pixel_sigma_px=self.pixel_sigma_px, false_match_fraction=self.false_match_fraction,
                              noise_model=self.noise_model)

    def _features(self, T_CW: np.ndarray):
        """The surface features the poses ``T_CW (..., 4, 4)`` need: ``n_features`` over the whole surface;
        with the calibrated model the texture sites at the poses' median image footprint (distance to the
        target's centre over the focal length, :func:`vision.texture_sites.site_features`) and the uniform
        fillers they need (:func:`vision.geometric_calibrated.filler_feature_count`), or with
        ``calibrated_features="uniform"`` as many as its densest bin asks on the outer surface
        (:mod:`vision.outer_surface`)."""
        if self.noise_model != "calibrated":
            return _surface_features(self.target, int(self.n_features), "all")
        if self.calibrated_features == "texture":
            from vision.geometric_calibrated import filler_feature_count
            from vision.texture_sites import footprint_level, texture_sites

            T = np.asarray(T_CW, dtype=float)
            distance_m = np.linalg.norm(np.einsum("...ji,...j->...i", T[..., :3, :3], T[..., :3, 3]), axis=-1)
            f_px = float(np.sqrt(self.camera.K[0, 0] * self.camera.K[1, 1]))
            level = footprint_level(float(np.median(distance_m)) / f_px)
            n_fill = filler_feature_count(self.camera, self.target, T, texture_sites(self.target, level))
            return _site_features(self.target, level, n_fill)
        if self.calibrated_features != "uniform":
            raise ValueError(f"calibrated_features must be 'texture' or 'uniform', got {self.calibrated_features!r}")
        from vision.geometric_calibrated import calibrated_feature_count

        n = max(int(self.n_features), calibrated_feature_count(self.camera, self.target, np.asarray(T_CW)))
        return _surface_features(self.target, n, "outer")


#: observation mode (config ``observation.mode``) → observer class
OBSERVERS: Registry[type[Observer]] = Registry("observer", {"rendered": RenderedObserver,
                                                            "geometric": GeometricObserver})
