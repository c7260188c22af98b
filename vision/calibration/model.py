"""Interpolation of the measured rendered-mode statistics (:class:`SiftCalibration`).

Every table is indexed by the calibrated ranges, converted to the pixel footprint ``z / f`` (m/px) so
that a camera with another focal length or range uses the same numbers at the same image scale.
Between calibrated footprints values are interpolated linearly in log footprint; beyond them the
detection density follows the power law of the two nearest footprints and the rates and sizes are
held at the nearest calibrated value (``docs/vision.md`` says where that matters).

The σ of a keypoint in a triangulated track (:meth:`SiftCalibration.track_sigma_px`) is its size σ
times the square root of the measured σ² inflation of its track's class (:data:`TRACK_CLASSES`),
its cameras' spread and image scale, where the file has that table (``triangulation_nees``, from
:mod:`experiments.studies.nees_calibration`); files without it give inflation 1.  Where the file has
the epoch tables, the inflation is the epoch's own variance factor (:mod:`vision.epoch_variance`)
times the inflation measured beyond it.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from vision.calibration.detection_factors import detection_tables
from vision.calibration.survival_factors import survival_factors
from vision.calibration.tables import CalibrationTableEmpty, bin_index
from vision.calibration.tables import fill_nearest as _fill_nearest
from vision.calibration.tables import table as _table

__all__ = ["COS_VIEW_EDGES", "PHASE_EDGES_DEG", "SIZE_EDGES_PX", "SUN_BIN_EDGES", "TRACK_CLASSES", "CalibrationTableEmpty",
           "SiftCalibration", "calibration_path", "load_calibration", "track_class"]

#: SIFT keypoint diameter bins, px (half octaves from 2√2 px)
SIZE_EDGES_PX = np.array([0.0, 2.83, 4.0, 5.66, 8.0, 11.3, 16.0, 22.6, 32.0, np.inf])
#: |cos| of the angle between the surface normal and the direction to the camera (90°, 75°, 60°, 45°, 30°, 0°)
COS_VIEW_EDGES = np.array([0.0, 0.26, 0.5, 0.71, 0.87, 1.0001])
#: Sun bins: bin 0 = not lit; bins 1.. = cosine of the Sun incidence on the lit side
SUN_BIN_EDGES = np.array([-1.0, 0.0, 0.26, 0.5, 0.71, 0.87, 1.0001])
#: Sun phase bins (the Sun's angle from the camera's, or a camera pair's mean, line of sight), degrees
PHASE_EDGES_DEG = np.array([0.0, 30.0, 60.0, 90.0, 120.0, 150.0, 180.0])
#: track classes of the σ inflation: a two-camera formation's tracks; a three-camera formation's tracks
#: matched in all three cameras, or in two of them
TRACK_CLASSES = ("2 of 2", "3 of 3", "2 of 3")
#: floor of a bin's σ (a bin whose least-squares σ² came out 0), px
_MIN_SIGMA_PX = 0.02
#: pairs a size bin needs at one range to use that range's own σ
_MIN_PAIRS_PER_BIN = 20


def calibration_path() -> Path:
    """The shipped calibration file, ``vision/calibration/rendered_sift.json``."""
    return Path(__file__).with_name("rendered_sift.json")


def _conditional(num: list, den: list) -> list:
    """``num / den`` per range and column (None where den is 0), at most 1."""
    return [[None if d <= 0 else min(1.0, n / d) for n, d in zip(rn, rd, strict=True)] for rn, rd in zip(num, den, strict=True)]


def _sigma_by_range(t: dict) -> np.ndarray:
    pooled = np.maximum(_fill_nearest(t["sigma_px"]), _MIN_SIGMA_PX)
    counts = np.asarray(t.get("sigma_pairs_per_bin_by_range", [[0] * len(pooled)] * len(t["ranges_m"])))
    rows = []
    for r, row in enumerate(t["sigma_px_by_range"]):
        v = np.array([np.nan if x is None else float(x) for x in row])
        ok = np.isfinite(v) & (counts[r] >= _MIN_PAIRS_PER_BIN) & (v >= _MIN_SIGMA_PX)
        rows.append(np.where(ok, v, pooled))
    return np.stack(rows)


def track_class(n_track_views: ArrayLike, n_cameras: int) -> np.ndarray:
    """Index into :data:`TRACK_CLASSES` of tracks seen in ``n_track_views`` of ``n_cameras`` cameras
    (formations of more than three cameras use the three-camera classes)."""
    k = np.asarray(n_track_views)
    if int(n_cameras) <= 2:
        return np.zeros(k.shape, dtype=int)
    return np.where(k >= min(int(n_cameras), 3), 1, 2)


def _inflation(t: dict) -> dict:
    """The σ² inflation table of a target (absent in files before it: inflation 1)."""
    nees = t.get("triangulation_nees")
    if nees is None:
        ones = np.ones((len(t["ranges_m"]), 1, len(TRACK_CLASSES)))
        return {"nees_angle_deg": np.array([10.0]), "sigma2_inflation": ones, "increment_sigma2_inflation": ones,
                "epoch_sigma2_inflation": None, "epoch_increment_sigma2_inflation": None,
                "material_sigma2_factor": None, "material_increment_sigma2_factor": None, "error_log_spread": None}

    def table(key: str) -> np.ndarray:
        rows = []
        for per_range in nees[key]:
            tab = np.array([[np.nan if v is None else float(v) for v in per_angle] for per_angle in per_range])
            for c in range(tab.shape[1]):  # an angle without data takes the nearest angle's value
                tab[:, c] = _fill_nearest(list(tab[:, c])) if np.isfinite(tab[:, c]).any() else np.nan
            # a class without data: the mean of the other classes at that angle
            rows.append(np.where(np.isfinite(tab), tab, np.nanmean(tab, axis=1, keepdims=True)))
        return np.stack(rows)

    beyond = {k: np.asarray(nees[k], dtype=float) if k in nees else None   # the errors beyond the class tables
              for k in ("material_sigma2_factor", "material_increment_sigma2_factor", "error_log_spread")}
    epoch = "epoch_sigma2_inflation" in nees          # files before the epoch factor have only the tables
    return {"nees_angle_deg": np.asarray(nees["angle_deg"], dtype=float), "sigma2_inflation": table("sigma2_inflation"),
            "increment_sigma2_inflation": table("increment_sigma2_inflation"),
            "epoch_sigma2_inflation": table("epoch_sigma2_inflation") if epoch else None,
            "epoch_increment_sigma2_inflation": table("epoch_increment_sigma2_inflation") if epoch else None, **beyond}


@dataclass(frozen=True, eq=False)
class SiftCalibration:
    """Measured SIFT statistics of one target (see :mod:`vision.calibration`).

    Attributes
    ----------
    target : str
        Calibration name (``"fy1"``, ``"topex"``).
    footprint_m_per_px : ndarray (R,)
        Calibrated image scales (range / focal length), m/px.
    sigma_px : ndarray (Z,)
        Keypoint localisation σ per axis for each size bin of :data:`SIZE_EDGES_PX`, px (all ranges).
    sigma_px_by_range : ndarray (R, Z)
        The same per calibrated footprint (a bin measured with too few pairs at one range takes
        the all-range value).
    density_per_m2 : ndarray (R, V, S)
        Keypoints per m² of visible surface by footprint, view bin and Sun bin.
    size_quantiles : ndarray (Q,), size_px_quantiles : ndarray (R, Q)
        Quantiles of the diameter of tracked keypoints, px.
    cross_view_deg : ndarray (A,), pair_survival, false_match_rate : ndarray (R, A)
        Cross-view match survival and false-match rate against the angle between the cameras.
    change_deg : ndarray (D,), association_survival, false_association_rate : ndarray (R, D)
        Inter-epoch association survival of re-detected tracked keypoints (correct associations
        over those detected again within the truth tolerance) and false-association rate against
        the viewpoint change.
    three_over_two_ratio : float
        Tracks of three cameras at the first cross-view angle over matches of two of them.
    three_view_track_share : float
        Of those tracks of three cameras, the share seen in all three (NaN in files without the count).
    material_factor : ndarray (R, P)
        Density of each of the target's P materials over the target's mean (area-weighted mean 1;
        1 for materials with less than 2 m² seen).
    pair_survival_phase_factor : ndarray (P,) or None
        Cross-view survival in each Sun phase bin of ``phase_edges_deg`` (the Sun's angle from the
        pair's mean line of sight) over the range-and-angle table's (None in files without it: no
        phase dependence).
    phase_edges_deg : ndarray (P + 1,)
    pair_survival_material_factor : ndarray (M,) or None
        The same per surface material of the keypoint (None in files without it).
    detection_brightness_factor : ndarray (R, B) or None
        Detection density per range and relative-brightness bin (:data:`vision.face_brightness.BRIGHTNESS_EDGES`)
        over what the density table and material factors give (None in files without it).
    pair_survival_brightness_factor : ndarray (B,) or None
        Cross-view survival by the first keypoint's bin over the table's, pooled (None without it).
    pair_survival_view_factor : ndarray (V,) or None
        The same by the keypoint's view-angle bin (only with the joint counts,
        :mod:`vision.calibration.survival_factors`).
    track_persistence : ndarray (R,)
        Fraction of the tracks of two cameras at the first cross-view angle that are tracks of the
        same cameras again after the first epoch change (NaN where not measured).
    measured_cell : ndarray (R, V, S) bool
        Density cells with enough surface seen to be measured (the others are the product of the
        view and Sun marginals).
    provenance : dict
    nees_angle_deg : ndarray (A,)
        Angles between the cameras at which the σ² inflation was measured, degrees.
    sigma2_inflation : ndarray (R, A, len(TRACK_CLASSES))
        σ² inflation per footprint, camera angle and track class that makes the triangulation NEES 3
        (ones where the file has none).
    increment_sigma2_inflation : ndarray (R, A, len(TRACK_CLASSES))
        The same for the change of a feature's triangulated body point between two epochs 1° apart
        (smaller: much of a keypoint's error is the same at both epochs and cancels in an increment).
    epoch_sigma2_inflation, epoch_increment_sigma2_inflation : ndarray (R, A, len(TRACK_CLASSES)) or None
        The same two over the epoch's variance factor (:func:`vision.epoch_variance.epoch_variance_factor`
        of the size σ): the σ² beyond what the epoch's residuals show (None in files without them).
    material_sigma2_factor, material_increment_sigma2_factor : ndarray (R, P) or None
        The NEES and increment NEES of keypoints on each of the target's P surface materials over what
        the class tables give them (None in files without them): how the errors depend on a surface
        no estimator sees (:meth:`material_noise_factors`).
    error_log_spread : ndarray (R,) or None
        Standard deviation of the log of a keypoint's σ² multiplier beyond the tables and the material
        factors (:mod:`vision.calibration.scale_mixture`; None in files without it).
    """

    target: str
    footprint_m_per_px: np.ndarray
    sigma_px: np.ndarray
    sigma_px_by_range: np.ndarray
    density_per_m2: np.ndarray
    size_quantiles: np.ndarray
    size_px_quantiles: np.ndarray
    cross_view_deg: np.ndarray
    pair_survival: np.ndarray
    false_match_rate: np.ndarray
    change_deg: np.ndarray
    association_survival: np.ndarray
    false_association_rate: np.ndarray
    three_over_two_ratio: float
    track_persistence: np.ndarray
    measured_cell: np.ndarray
    material_factor: np.ndarray
    provenance: dict
    nees_angle_deg: np.ndarray = field(default_factory=lambda: np.array([10.0]))
    sigma2_inflation: np.ndarray | None = None
    increment_sigma2_inflation: np.ndarray | None = None
    epoch_sigma2_inflation: np.ndarray | None = None
    epoch_increment_sigma2_inflation: np.ndarray | None = None
    material_sigma2_factor: np.ndarray | None = None
    material_increment_sigma2_factor: np.ndarray | None = None
    error_log_spread: np.ndarray | None = None
    pair_survival_phase_factor: np.ndarray | None = None
    phase_edges_deg: np.ndarray = field(default_factory=lambda: PHASE_EDGES_DEG.copy())
    pair_survival_material_factor: np.ndarray | None = None
    detection_brightness_factor: np.ndarray | None = None
    pair_survival_brightness_factor: np.ndarray | None = None
    pair_survival_view_factor: np.ndarray | None = None
    three_view_track_share: float = float("nan")

    @classmethod
    def from_dict(cls, data: dict, target: str) -> SiftCalibration:
        """Read one target's tables from the calibration file's dict."""
        if target not in data.get("targets", {}):
            raise ValueError(f"target: no calibration for {target!r}; calibrated: {sorted(data.get('targets', {}))}")
        t = data["targets"][target]
        dens, mat_f, bright_f, measured = detection_tables(t)     # vision.calibration.detection_factors
        q = [r for r in t["track_size_px_quantiles_by_range"]]
        qfill = next((r for r in q if r is not None), None)
        if qfill is None:
            raise CalibrationTableEmpty("calibration: no tracked keypoint sizes at any range")
        return cls(
            target=target,
            footprint_m_per_px=np.asarray(t["footprint_m_per_px"], dtype=float),
            sigma_px=np.maximum(_fill_nearest(t["sigma_px"]), _MIN_SIGMA_PX),
            sigma_px_by_range=_sigma_by_range(t),
            density_per_m2=np.nan_to_num(dens),
            size_quantiles=np.asarray(t["size_quantiles"], dtype=float),
            size_px_quantiles=np.asarray([r if r is not None else qfill for r in q], dtype=float),
            cross_view_deg=np.asarray(t["cross_view"]["angle_deg"], dtype=float),
            pair_survival=_table(t["cross_view"]["survival"]),
            false_match_rate=_table(t["cross_view"]["false_match_rate"]),
            change_deg=np.asarray(t["association"]["change_deg"], dtype=float),
            association_survival=_table(_conditional(t["association"]["correct"], t["association"]["redetected"])),
            false_association_rate=_table(t["association"]["false_rate"]),
            measured_cell=measured,
            track_persistence=np.array([np.nan if v is None else float(v) for v in
                                        t["cross_view"].get("persistence", [None] * len(t["ranges_m"]))]),
            material_factor=mat_f,
            detection_brightness_factor=bright_f,
            three_over_two_ratio=(float(sum(t["cross_view"]["three_view_tracks"]))
                                  / max(1.0, float(sum(t["cross_view"]["two_view_tracks"])))),
            three_view_track_share=(float(sum(t["cross_view"]["three_view_full_tracks"]))
                                    / max(1.0, float(sum(t["cross_view"]["three_view_tracks"]))))
            if "three_view_full_tracks" in t["cross_view"] else float("nan"),
            provenance=dict(data.get("provenance", {})),
            **{f"pair_survival_{by}_factor": f for by, f in survival_factors(t["cross_view"]).items()},
            phase_edges_deg=np.asarray(data.get("phase_edges_deg", PHASE_EDGES_DEG), dtype=float),
            **_inflation(t),
        )

    # -- interpolation helpers -------------------------------------------------------------------

    def _range_weights(self, footprint: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Lower index, upper index and weight of the upper one, linear in log footprint."""
        lf, dlf = self._log_footprint
        x = np.log(np.asarray(footprint, dtype=float))
        if lf.size == 1:
            z = np.zeros(x.shape, dtype=int)
            return z, z, np.zeros(x.shape)
        i = bin_index(lf, x, "left", 0, lf.size - 2)
        w = (x - np.take(lf, i)) / np.take(dlf, i)
        return i, i + 1, w

    @functools.cached_property
    def _log_footprint(self) -> tuple[np.ndarray, np.ndarray]:
        """log of the calibrated footprints and their differences."""
        lf = np.log(self.footprint_m_per_px)
        return lf, np.diff(lf)

    def _clipped_range_weights(self, footprint: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_range_weights` with the weight held at the nearest calibrated footprint beyond them."""
        i, j, w = self._range_weights(np.asarray(footprint, dtype=float))
        return i, j, np.clip(w, 0.0, 1.0)

    def _by_range(self, table: np.ndarray, footprint: ArrayLike, column: np.ndarray,
                  weights: tuple | None = None) -> np.ndarray:
        """``table[r, column]`` interpolated in footprint (held beyond the calibrated ones); ``weights``:
        :meth:`_clipped_range_weights` of ``footprint`` if already computed."""
        i, j, w = weights if weights is not None else self._clipped_range_weights(footprint)
        return (1.0 - w) * table[i, column] + w * table[j, column]

    # -- the measured statistics -----------------------------------------------------------------

    def sigma_for_size(self, size_px: ArrayLike, footprint_m_per_px: ArrayLike | None = None) -> np.ndarray:
        """Localisation σ per axis of keypoints of these diameters, px (NaN for NaN sizes): at the
        image scale ``footprint_m_per_px`` (interpolated in log footprint, held beyond the calibrated
        ones) when given, else pooled over the calibrated ranges."""
        s = np.asarray(size_px, dtype=float)
        b = bin_index(SIZE_EDGES_PX, np.nan_to_num(s), "right", 0, len(self.sigma_px) - 1)
        if footprint_m_per_px is None:
            return np.where(np.isfinite(s), self.sigma_px[b], np.nan)
        fp = np.broadcast_to(np.asarray(footprint_m_per_px, dtype=float), s.shape)
        return np.where(np.isfinite(s), self._by_range(self.sigma_px_by_range, fp, b), np.nan)

    def sigma_inflation(self, footprint_m_per_px: ArrayLike, angle_deg: ArrayLike, track_class: ArrayLike, *,
                        increment: bool = False, epoch: bool = False) -> np.ndarray:
        """σ² inflation of keypoints at this footprint, in tracks whose cameras are ``angle_deg`` apart
        (largest angle between two of them, about the target) of class ``track_class`` (index into
        :data:`TRACK_CLASSES`): linear in angle and log footprint, held beyond the calibrated ones.
        ``increment``: the inflation of an inter-epoch increment instead of a triangulated point;
        ``epoch``: the inflation over the epoch's variance factor (``epoch_sigma2_inflation``)."""
        if epoch and self.epoch_sigma2_inflation is None:
            raise ValueError("epoch: this calibration has no epoch_sigma2_inflation table (coobs calibrate --nees-only)")
        tab = {(False, False): self.sigma2_inflation, (True, False): self.increment_sigma2_inflation,
               (False, True): self.epoch_sigma2_inflation,
               (True, True): self.epoch_increment_sigma2_inflation}[(bool(increment), bool(epoch))]
        return self._inflation_at((tab,), footprint_m_per_px, angle_deg, track_class)[0]

    def sigma_inflations(self, footprint_m_per_px: ArrayLike, angle_deg: ArrayLike,
                         track_class: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`sigma_inflation` of a triangulated point and of an increment at the same keypoints
        (the interpolation weights computed once)."""
        return self._inflation_at((self.sigma2_inflation, self.increment_sigma2_inflation),
                                  footprint_m_per_px, angle_deg, track_class)

    def material_noise_factors(self, footprint_m_per_px: ArrayLike,
                               material: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """The σ² factors of a keypoint's error (triangulated point, increment) on this surface material
        at this image scale (interpolated in log footprint, held beyond the calibrated ones); ones where
        the file has none or ``material`` is outside its table."""
        fp, m = np.broadcast_arrays(np.asarray(footprint_m_per_px, dtype=float), np.asarray(material, dtype=int))
        tabs = (self.material_sigma2_factor, self.material_increment_sigma2_factor)
        if tabs[0] is None or tabs[1] is None:
            return np.ones(fp.shape), np.ones(fp.shape)
        inside = (m >= 0) & (m < tabs[0].shape[1])
        col = np.where(inside, m, 0)
        weights = self._clipped_range_weights(fp)
        return tuple(np.where(inside, self._by_range(t, fp, col, weights), 1.0) for t in tabs)

    def error_spread_at(self, footprint_m_per_px: ArrayLike) -> np.ndarray:
        """:attr:`error_log_spread` at this image scale (linear in log footprint, held beyond the
        calibrated ones); 0 where the file has none."""
        fp = np.asarray(footprint_m_per_px, dtype=float)
        if self.error_log_spread is None:
            return np.zeros(fp.shape)
        i, j, w = self._clipped_range_weights(fp)
        return (1.0 - w) * self.error_log_spread[i] + w * self.error_log_spread[j]

    def _inflation_at(self, tables: tuple, footprint_m_per_px: ArrayLike, angle_deg: ArrayLike,
                      track_class: ArrayLike) -> list[np.ndarray]:
        fp, ang, c = np.broadcast_arrays(np.asarray(footprint_m_per_px, dtype=float),
                                         np.asarray(angle_deg, dtype=float), np.asarray(track_class, dtype=int))
        grid = self.nees_angle_deg
        i, j, w = self._range_weights(fp)
        w = np.clip(w, 0.0, 1.0)
        if grid.size == 1:
            return [(1.0 - w) * tab[i, 0, c] + w * tab[j, 0, c] for tab in tables]
        k = bin_index(grid, ang, "left", 0, grid.size - 2)
        u = np.clip((ang - grid[k]) / (grid[k + 1] - grid[k]), 0.0, 1.0)

        def at(tab, r):
            return (1.0 - u) * tab[r, k, c] + u * tab[r, k + 1, c]

        return [(1.0 - w) * at(tab, i) + w * at(tab, j) for tab in tables]

    def track_sigma_px(self, obs, *, inflate: bool = True, increment: bool = False,
                       epoch_scale: bool = True) -> np.ndarray:
        """``(M, n)`` σ per track and view of an observation (NaN where a track is absent): the size σ
        of each keypoint at its view's image scale, times √(σ² inflation) of the track
        (:meth:`sigma_inflation`; its class from the views it has and the cameras, its angle the
        largest between two of its cameras about the origin of H, where the target is).  Where the file
        has the epoch tables and ``epoch_scale``, the inflation is the epoch's variance factor of the
        size σ (:func:`vision.epoch_variance.epoch_variance_factor`, from this observation's own
        epipolar residuals) times the inflation beyond it; otherwise the table's average inflation.
        ``increment``: the σ of the same keypoints for an inter-epoch increment (its Cramér–Rao bound),
        ``inflate=False``: the size σ alone."""
        fp = np.linalg.norm(obs.T_CW[:, :3, 3], axis=1) / np.sqrt(obs.K[:, 0, 0] * obs.K[:, 1, 1])
        sig = self.sigma_for_size(obs.keypoint_size_px, fp[None, :])
        if not inflate:
            return sig
        R = obs.T_CW[:, :3, :3]
        c = -np.einsum("nji,nj->ni", R, obs.T_CW[:, :3, 3])          # camera centres in H
        c /= np.linalg.norm(c, axis=1, keepdims=True)
        pair = np.degrees(np.arccos(np.clip(c @ c.T, -1.0, 1.0)))   # (n, n)
        seen = obs.seen
        both = seen[:, :, None] & seen[:, None, :]
        angle = np.max(np.where(both, pair[None], 0.0), axis=(1, 2))
        cls = track_class(seen.sum(axis=1), obs.n_views)
        epoch = bool(epoch_scale) and self.epoch_sigma2_inflation is not None
        infl = self.sigma_inflation(np.broadcast_to(fp[None, :], sig.shape), angle[:, None], cls[:, None],
                                    increment=increment, epoch=epoch)
        if epoch:
            from vision.epoch_variance import epoch_variance_factor

            infl = infl * epoch_variance_factor(obs.uv_px, obs.K, obs.T_CW, sig)
        return sig * np.sqrt(infl)

    def density(self, footprint_m_per_px: ArrayLike, cos_view: ArrayLike, sun_bin: ArrayLike,
                material: ArrayLike | None = None) -> np.ndarray:
        """Keypoints per m² of visible surface (``sun_bin`` 0: not lit; see :data:`SUN_BIN_EDGES`), times
        the factor of the surface ``material`` (index into the target's materials) when given."""
        return self.density_at(self.density_bins(footprint_m_per_px, cos_view), sun_bin, material)

    def density_bins(self, footprint_m_per_px: ArrayLike, cos_view: ArrayLike) -> tuple:
        """The footprint interpolation (lower and upper range index, weight) and the view bin of
        :meth:`density` at these points: computed once for several Sun bins or materials there
        (:meth:`density_at`)."""
        i, j, w = self._range_weights(np.asarray(footprint_m_per_px, dtype=float))
        return i, j, w, self.view_bin(cos_view)

    @staticmethod
    def view_bin(cos_view: ArrayLike) -> np.ndarray:
        """Index of the view-angle bin (:data:`COS_VIEW_EDGES`) of surfaces at this signed cosine."""
        return bin_index(COS_VIEW_EDGES, np.abs(cos_view), "right", 0, len(COS_VIEW_EDGES) - 2)

    def density_at(self, bins: tuple, sun_bin: ArrayLike, material: ArrayLike | None = None) -> np.ndarray:
        """:meth:`density` at the points of ``bins`` (:meth:`density_bins`): the power law in footprint
        between the tabulated logarithms of the bins' densities (:attr:`_log_density`)."""
        i, j, w, v = bins
        _, V, S = self.density_per_m2.shape
        cell = v * S + np.asarray(sun_bin, dtype=int)                    # flat index of (v, s[, m]) in a range's table
        if material is not None and self.material_factor.shape[1] > 1:
            P = self.material_factor.shape[1]
            flat, step, cell = self._log_density.reshape(-1), V * S * P, cell * P + np.asarray(material, dtype=int)
        else:
            flat, step = self._log_density_all.reshape(-1), V * S
        lo, hi = np.take(flat, i * step + cell), np.take(flat, j * step + cell)
        return np.exp((1.0 - w) * lo + w * hi)

    @functools.cached_property
    def _log_density_all(self) -> np.ndarray:
        """log of the density table ``(R, V, S)`` (floored at 1e-9 per m²), every material together."""
        return np.log(np.maximum(self.density_per_m2, 1e-9))

    @functools.cached_property
    def _log_density(self) -> np.ndarray:
        """log of the density table times each material's factor, ``(R, V, S, P)``."""
        return np.log(np.maximum(self.density_per_m2, 1e-9)[..., None] * self.material_factor[:, None, None, :])

    def brightness_factor_at(self, brightness: ArrayLike, footprint_m_per_px: ArrayLike) -> np.ndarray:
        """Detection factor of surfaces at this relative brightness (:mod:`vision.face_brightness`)
        and image scale (linear in log footprint between the calibrated ranges, held beyond them; 1
        without the table)."""
        from vision.face_brightness import brightness_bin

        f = self.detection_brightness_factor
        if f is None:
            return np.ones(np.broadcast_shapes(np.shape(brightness), np.shape(footprint_m_per_px)))
        return self._by_range(f, footprint_m_per_px, brightness_bin(brightness))

    def lit_and_unlit_factors_at(self, brightness: ArrayLike, footprint_m_per_px: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`brightness_factor_at` of ``brightness`` and of unlit surfaces (brightness 0) at the same
        footprints, sharing their interpolation weights."""
        from vision.face_brightness import brightness_bin

        f = self.detection_brightness_factor
        if f is None:
            one = np.ones(np.broadcast_shapes(np.shape(brightness), np.shape(footprint_m_per_px)))
            return one, one
        weights = self._clipped_range_weights(footprint_m_per_px)
        return (self._by_range(f, footprint_m_per_px, brightness_bin(brightness), weights),
                self._by_range(f, footprint_m_per_px, 0, weights))

    def survival_brightness_factor_at(self, brightness: ArrayLike) -> np.ndarray:
        """Cross-view survival factor of a keypoint at this relative brightness (1 without the table)."""
        from vision.face_brightness import brightness_bin

        f = self.pair_survival_brightness_factor
        return np.ones(np.shape(brightness)) if f is None else f[brightness_bin(brightness)]

    def survival_view_factor_at(self, cos_view: ArrayLike) -> np.ndarray:
        """Cross-view survival factor of a keypoint on a surface at this (signed) view-angle cosine (1 without the table)."""
        f = self.pair_survival_view_factor
        return np.ones(np.shape(cos_view)) if f is None else f[self.view_bin(cos_view)]

    @property
    def max_brightness_factor(self) -> float:
        """The largest detection factor of any relative brightness (1 without the table)."""
        f = self.detection_brightness_factor
        return 1.0 if f is None else float(np.max(f))

    def sun_bin(self, cos_sun: ArrayLike, lit: ArrayLike) -> np.ndarray:
        """Sun bin of surfaces with this Sun-incidence cosine (lit side) and lit flag."""
        b = bin_index(SUN_BIN_EDGES, cos_sun, "right", 1, len(SUN_BIN_EDGES) - 2)
        return np.where(np.asarray(lit, dtype=bool), b, 0)

    def max_density(self, footprint_m_per_px: float) -> float:
        """Largest measured density of a (view, Sun) cell at this footprint, per m² (cells with at least
        2 m² of surface seen; the power law of :meth:`density` between and beyond footprints)."""
        fp = float(footprint_m_per_px)
        i, j, w = self._range_weights(np.array(fp))
        lo = np.max(np.where(self.measured_cell[i], self.density_per_m2[i], 0.0)) * np.max(self.material_factor[i])
        hi = np.max(np.where(self.measured_cell[j], self.density_per_m2[j], 0.0)) * np.max(self.material_factor[j])
        return float(np.exp((1.0 - w) * np.log(max(lo, 1e-9)) + w * np.log(max(hi, 1e-9))))

    def size_px(self, footprint_m_per_px: ArrayLike, u: ArrayLike) -> np.ndarray:
        """Diameter of a tracked keypoint at quantile ``u`` ∈ [0, 1] of the size distribution, px."""
        fp = np.asarray(footprint_m_per_px, dtype=float)
        u = np.asarray(u, dtype=float)
        fp, u = np.broadcast_arrays(fp, u)
        i, j, w = self._range_weights(fp)
        w = np.clip(w, 0.0, 1.0)
        rows = [np.interp(u, self.size_quantiles, q) for q in self.size_px_quantiles]   # each range's (R ≤ 32)
        return np.exp((1.0 - w) * np.log(np.choose(i, rows)) + w * np.log(np.choose(j, rows)))

    def _rate(self, grid: np.ndarray, table: np.ndarray, footprint, x) -> np.ndarray:
        """``table (R, G)`` interpolated along ``grid`` at x and in footprint, clipped to [0, 1]: each
        range's row at x's own points and the footprint weights at the footprint's own, broadcast
        together by the choice of rows (R ≤ 32)."""
        rows = [np.interp(np.asarray(x, dtype=float), grid, row) for row in table]
        i, j, w = self._range_weights(np.asarray(footprint, dtype=float))
        w = np.clip(w, 0.0, 1.0)
        return np.clip((1.0 - w) * np.choose(i, rows) + w * np.choose(j, rows), 0.0, 1.0)

    def pair_survival_at(self, footprint_m_per_px: ArrayLike, angle_deg: ArrayLike,
                         phase_deg: ArrayLike | None = None, material: ArrayLike | None = None) -> np.ndarray:
        """Probability that a keypoint seen by a second camera ``angle_deg`` away is correctly matched;
        with ``phase_deg`` (the Sun's angle from the pair's mean line of sight) times the survival
        factor of that phase (:meth:`survival_phase_factor_at`), with ``material`` (the index of the
        keypoint's surface material) times that material's (``pair_survival_material_factor``)."""
        S = self._rate(self.cross_view_deg, self.pair_survival, footprint_m_per_px, angle_deg)
        if phase_deg is not None:
            S = S * self.survival_phase_factor_at(phase_deg)
        if material is not None and self.pair_survival_material_factor is not None:
            S = S * self.pair_survival_material_factor[np.asarray(material, dtype=np.int64)]
        return np.clip(S, 0.0, 1.0)

    def survival_phase_factor_at(self, phase_deg: ArrayLike) -> np.ndarray:
        """The cross-view survival factor of a Sun phase, degrees: linear between the phase bins' centres,
        held beyond them (1 where the file has no phase counts)."""
        ph = np.asarray(phase_deg, dtype=float)
        if self.pair_survival_phase_factor is None:
            return np.ones(ph.shape)
        e = self.phase_edges_deg
        return np.interp(ph, 0.5 * (e[:-1] + e[1:]), self.pair_survival_phase_factor)

    def false_match_rate_at(self, footprint_m_per_px: ArrayLike, angle_deg: ArrayLike) -> np.ndarray:
        """Fraction of cross-view matches that are wrong."""
        return self._rate(self.cross_view_deg, self.false_match_rate, footprint_m_per_px, angle_deg)

    def association_survival_at(self, footprint_m_per_px: ArrayLike, change_deg: ArrayLike) -> np.ndarray:
        """Probability that a track is associated with itself after a viewpoint change of ``change_deg``."""
        return self._rate(self.change_deg, self.association_survival, footprint_m_per_px, change_deg)

    def false_association_rate_at(self, footprint_m_per_px: ArrayLike, change_deg: ArrayLike) -> np.ndarray:
        """Fraction of inter-epoch associations that are wrong."""
        return self._rate(self.change_deg, self.false_association_rate, footprint_m_per_px, change_deg)


@functools.lru_cache(maxsize=4)
def _read(path: str) -> dict:
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def load_calibration(target: str, *, path: str | Path | None = None) -> SiftCalibration:
    """The calibration of a target: ``"fy1"`` for the FY-1-like target, ``"topex"`` for meshes.

    ``target`` is a calibration name or a :class:`vision.target.Target` name: the procedural
    FY-1-like target (``"FY-1-like"``) uses ``"fy1"``, every mesh the TOPEX/Poseidon calibration
    (meshes get the same procedural texture family). ``path`` defaults to the shipped file.
    """
    p = str(path if path is not None else calibration_path())
    try:
        data = _read(p)
    except FileNotFoundError:
        raise ValueError(f"calibration file not found: {p} (run 'coobs calibrate')") from None
    name = "fy1" if target in ("fy1", "FY-1-like") else target
    if name not in data.get("targets", {}):
        name = "topex"
    return _from_file(p, name)


@functools.lru_cache(maxsize=8)
def _from_file(path: str, name: str) -> SiftCalibration:
    """One target's calibration of a file read by :func:`_read`, built once (the joint survival fit)."""
    return SiftCalibration.from_dict(_read(path), name)
