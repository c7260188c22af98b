"""A simulated two-camera measuring rig of paper 004 §4 and its end-to-end calibration.

The rig is the simulation truth (camera hardware and true poses); :func:`calibrate_system` runs the
turntable intrinsic calibration and the control-point extrinsic calibration of
:mod:`chaser.cylindrical.calibration` on it, and :func:`rig_detections` renders one frame of line
signals and detects its spots (:mod:`vision.cylindrical`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import qmc

from chaser.cylindrical._arrays import as_points
from chaser.cylindrical.calibration import (
    ExtrinsicCalibration,
    TurntableSamples,
    calibrate_extrinsics,
    fit_intrinsic_rbf,
    simulate_turntable_calibration,
    tracker_sigma_m,
)
from chaser.cylindrical.intersection import CalibratedCamera
from vision.cylindrical import (
    CylindricalCamera,
    LineSpots,
    angles_from_points,
    detect_spots,
    measure_spot_centres,
    render_line_signals,
)

__all__ = [
    "CylindricalRig",
    "paper_rig",
    "control_points_in_cube",
    "SystemCalibration",
    "calibrate_system",
    "rig_detections",
]


@dataclass(frozen=True, eq=False)
class CylindricalRig:
    """Simulation truth of a measuring rig: the camera hardware and their true poses.

    Attributes
    ----------
    cameras : tuple of CylindricalCamera
    R_CW : (C, 3, 3) ndarray
    t_CW : (C, 3) ndarray
        True extrinsics, ``x_C = R_CW X_W + t_CW`` (m).
    """

    cameras: tuple[CylindricalCamera, ...]
    R_CW: np.ndarray
    t_CW: np.ndarray

    @property
    def n_cameras(self) -> int:
        """Number of cameras C."""
        return len(self.cameras)

    @property
    def centres_W(self) -> np.ndarray:
        """Camera centres ``(C, 3)`` in the world frame, ``−R_CWᵀ t_CW`` (m)."""
        return -np.einsum("cji,cj->ci", self.R_CW, self.t_CW)

    def true_angles(self, X_W: ArrayLike) -> np.ndarray:
        """True ``(α, β)`` of world points ``(..., 3)`` in every camera: ``(..., C, 2)``."""
        X = as_points(X_W, "X_W")
        Xc = np.einsum("cij,...j->...ci", self.R_CW, X) + self.t_CW
        return angles_from_points(Xc)

    def true_pixels(self, X_W: ArrayLike) -> np.ndarray:
        """True spot centres ``(..., C, 2)`` (NaN outside a camera's field)."""
        ab = self.true_angles(X_W)
        return np.stack([cam.pixels_from_angles(ab[..., c, :]) for c, cam in enumerate(self.cameras)], -2)


def paper_rig(
    *,
    baseline_m: float = 2.0,
    convergence_deg: float = 30.0,
    camera: CylindricalCamera | None = None,
    camera_spread: float = 1.0,
) -> CylindricalRig:
    """The two-camera rig of 004 §4: baseline 2 m, optical axes converging at 30°.

    World frame (laser-tracker frame): ``x`` along the baseline, ``y`` forward (depth), ``z`` up.
    Camera 1 is at the origin and camera 2 at ``(baseline, 0, 0)``; each is turned inwards by half the
    convergence angle, so the axes meet at ``(baseline/2, baseline/2 / tan(conv/2), 0)`` (3.73 m
    for the paper's values).  The second camera's lens differs from the first (principal points and
    distortion changed by ``camera_spread`` × a few per cent), as two real units would.
    """
    if not baseline_m > 0:
        raise ValueError(f"baseline_m: must be positive, got {baseline_m!r}")
    if not 0 < convergence_deg < 120:
        raise ValueError(f"convergence_deg: must be in (0, 120), got {convergence_deg!r}")
    cam1 = camera if camera is not None else CylindricalCamera()
    sp = camera_spread
    cam2 = replace(
        cam1,
        principal_px=(cam1.principal_px[0] - 6.3 * sp, cam1.principal_px[1] + 4.1 * sp),
        k1=(cam1.k1[0] * (1 + 0.08 * sp), cam1.k1[1] * (1 - 0.06 * sp)),
        k2=(cam1.k2[0] * (1 - 0.1 * sp), cam1.k2[1] * (1 + 0.1 * sp)),
        bow=(cam1.bow[0] * (1 + 0.1 * sp), cam1.bow[1] * (1 - 0.1 * sp)),
        line_tilt_rad=(cam1.line_tilt_rad[0] - 0.7e-3 * sp, cam1.line_tilt_rad[1] + 0.5e-3 * sp),
    )
    h = np.deg2rad(convergence_deg) / 2.0
    Rs, ts = [], []
    for centre, yaw in (((0.0, 0.0, 0.0), h), ((baseline_m, 0.0, 0.0), -h)):
        z_c = np.array([np.sin(yaw), np.cos(yaw), 0.0])   # boresight, turned towards the middle
        x_c = np.array([np.cos(yaw), -np.sin(yaw), 0.0])  # right
        y_c = np.cross(z_c, x_c)                          # down
        R_CW = np.stack([x_c, y_c, z_c])
        Rs.append(R_CW)
        ts.append(-R_CW @ np.asarray(centre))
    return CylindricalRig((cam1, cam2), np.stack(Rs), np.stack(ts))


def control_points_in_cube(n: int, *, centre_W: ArrayLike, edge_m: float = 1.0,
                           rng: np.random.Generator | int | None = None) -> np.ndarray:
    """``n`` control points spread uniformly over a cube (Latin hypercube sample, ``scipy.stats.qmc``).

    Returns ``(n, 3)`` world points (m).
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n: must be a positive integer, got {n!r}")
    if not edge_m > 0:
        raise ValueError(f"edge_m: must be positive, got {edge_m!r}")
    c = np.asarray(centre_W, dtype=float)
    if c.shape != (3,):
        raise ValueError(f"centre_W: expected shape (3,), got {c.shape}")
    sample = qmc.LatinHypercube(d=3, rng=np.random.default_rng(rng)).random(int(n))
    return c + (sample - 0.5) * edge_m


@dataclass(frozen=True, eq=False)
class SystemCalibration:
    """What :func:`calibrate_system` produced: the calibrated cameras and the calibration records."""

    cameras: tuple[CalibratedCamera, ...]
    samples: tuple[TurntableSamples, ...]
    extrinsics: tuple[ExtrinsicCalibration, ...]
    control_points_W: np.ndarray
    control_points_measured_W: np.ndarray



def calibrate_system(
    rig: CylindricalRig,
    control_points_W: ArrayLike,
    *,
    rng: np.random.Generator | int | None = None,
    turntable: dict | None = None,
    rbf: dict | None = None,
    n_scans: int = 20,
    extrinsic_method: str = "rotvec",
    method: str = "threshold_centroid",
) -> SystemCalibration:
    """Calibrate every camera of a simulated rig: turntable RBF intrinsics, then control-point extrinsics.

    The control points are measured by the laser tracker (at the world origin, error
    :func:`tracker_sigma_m` of their distance) and, lit one at a time, by every camera (spot centres
    averaged over ``n_scans`` scans, mapped to angles by the camera's fresh RBF calibration).

    Parameters
    ----------
    rig : CylindricalRig
    control_points_W : (n, 3) array
        True control-point positions (m).
    turntable, rbf : dict, optional
        Keyword options for :func:`simulate_turntable_calibration` and :func:`fit_intrinsic_rbf`.
    """
    rng = np.random.default_rng(rng)
    X = as_points(control_points_W, "control_points_W")
    seeds = rng.spawn(2 * rig.n_cameras + 1)
    X_meas = X + seeds[-1].standard_normal(X.shape) * tracker_sigma_m(np.linalg.norm(X, axis=-1))[..., None]
    uv_true = rig.true_pixels(X)
    cams, samples, extr = [], [], []
    for c, hw in enumerate(rig.cameras):
        s = simulate_turntable_calibration(hw, rng=seeds[2 * c], method=method, **(turntable or {}))
        intr = fit_intrinsic_rbf(s.uv_px, s.alpha_beta_rad, rng=seeds[2 * c], **(rbf or {}))
        uv = measure_spot_centres(hw, uv_true[:, c, :], rng=seeds[2 * c + 1], n_scans=n_scans, method=method)
        ab = intr.angles_from_pixels(uv)
        seen = np.isfinite(ab).all(-1)
        e = calibrate_extrinsics(X_meas[seen], ab[seen], method=extrinsic_method)
        cams.append(CalibratedCamera(intr, e.R_CW, e.t_CW))
        samples.append(s)
        extr.append(e)
    return SystemCalibration(tuple(cams), tuple(samples), tuple(extr), X, X_meas)


def rig_detections(
    rig: CylindricalRig,
    X_W: ArrayLike,
    *,
    rng: np.random.Generator | int | None = None,
    lit: ArrayLike | None = None,
    method: str = "threshold_centroid",
) -> list[tuple[LineSpots, LineSpots]]:
    """One frame of the rig: full line signals of every CCD with all lit targets, and their spots.

    Parameters
    ----------
    X_W : (K, 3) array
        Target (LED) positions (m).
    lit : (K,) bool array, optional
        Which targets are on (sequential lighting); default all.

    Returns
    -------
    list over cameras of (spots on CCD1, spots on CCD2)
    """
    rng = np.random.default_rng(rng)
    X = as_points(X_W, "X_W")
    uv = rig.true_pixels(X)  # (K, C, 2)
    if lit is not None:
        on = np.asarray(lit, dtype=bool)
        uv = np.where(on[:, None, None], uv, np.nan)
    out = []
    for c, cam in enumerate(rig.cameras):
        sig = render_line_signals(cam, uv[:, c, :], rng=rng)
        out.append((detect_spots(sig[0], method=method), detect_spots(sig[1], method=method)))
    return out
