"""The Cramér–Rao bound of the attitude increment against the angle between the views, and a Monte Carlo.

Three cameras 40 m from a FY-1-like target look at it from the symmetric cone of paper 003 with an
angle γ between adjacent optical axes.  For each γ, ``formation.quality.crlb_score`` predicts the
smallest RMS error with which any unbiased method can measure a 0.87° attitude increment from two
noisy views of the same surface points (``reconstruction.accuracy``).  A small Monte Carlo does it:
the points are projected with 0.5 px noise at both epochs, triangulated with their covariances, and
registered by covariance-aware maximum likelihood; its RMS error should lie on the bound, which it
attains to first order.  Narrow baselines fix the points' depths poorly, so the bound grows as γ
shrinks (slowly here: a rotation about the line of sight needs no depth); at the narrowest angle the
Monte Carlo leaves the bound, where the first-order theory stops holding.

Run it:  ``python examples/crlb_baseline.py`` (seconds) → ``docs/figures/gallery/crlb_baseline.png``
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter

from attitude.quaternion import (
    matrix_from_quat,
    quat_from_matrix,
    quat_from_rotvec,
    rotvec_from_quat,
)
from formation.geometry import symmetric_views
from formation.quality import camera_poses_at_target, crlb_score
from reconstruction import fit_rigid_ml, triangulate
from vision.camera import PinholeCamera
from vision.geometric import surface_features
from vision.target import fy1_target

NAME = "crlb_baseline"
GALLERY = Path(__file__).resolve().parents[1] / "docs" / "figures" / "gallery"
PIXEL_SIGMA_PX = 0.5
DISTANCE_M = 40.0


def monte_carlo_rms_deg(camera: PinholeCamera, X_H: np.ndarray, r_CT_H: np.ndarray, R_delta: np.ndarray, *,
                        trials: int, rng: np.random.Generator) -> float:
    """RMS attitude-increment error of triangulation + maximum-likelihood registration, degrees.

    Parameters
    ----------
    camera : PinholeCamera
        Every view's camera.
    X_H : (M, 3) ndarray
        Surface points at the first epoch, H, m.
    r_CT_H : (n, 3) ndarray
        Camera positions relative to the target's centre, H, m (each looks at the centre).
    R_delta : (3, 3) ndarray
        The target's rotation between the two epochs, in H.
    trials : int
        Monte Carlo trials.
    rng : numpy.random.Generator
        Source of the pixel noise.
    """
    T_CW = camera_poses_at_target(r_CT_H)  # the poses the bound is computed for
    K = np.broadcast_to(camera.K, (len(r_CT_H), 3, 3))
    clouds = []
    for X in (X_H, X_H @ R_delta.T):
        uv, _ = camera.project_world(X[:, None, :], T_CW[None])  # (M, n, 2)
        noisy = uv + PIXEL_SIGMA_PX * rng.standard_normal((trials,) + uv.shape)
        clouds.append(triangulate(noisy, K, T_CW, pixel_sigma_px=PIXEL_SIGMA_PX))
    reg = fit_rigid_ml(clouds[0].X_W, clouds[1].X_W, clouds[0].cov_W, clouds[1].cov_W, robust=False)
    error_rad = np.linalg.norm(rotvec_from_quat(quat_from_matrix(R_delta @ np.swapaxes(reg.R, -1, -2))), axis=-1)
    return float(np.degrees(np.sqrt(np.mean(error_rad[np.asarray(reg.ok)] ** 2))))


def main(*, out_dir: Path = GALLERY, small: bool = True, seed: int = 0) -> dict[str, Any]:
    """Bound and Monte Carlo over the axis angles, drawn; returns the key numbers, the arrays and the figure's path.

    Parameters
    ----------
    out_dir : Path
        Folder for ``crlb_baseline.png``.
    small : bool
        5 angles × 60 trials (seconds); ``False``: 12 angles × 400 trials.
    seed : int
        Seed of the surface points and the pixel noise.
    """
    # 1. configure: camera, surface points, the increment, the angles between the views
    ss_points, ss_noise = np.random.SeedSequence(seed).spawn(2)
    camera = PinholeCamera.from_fov(1024, 1024, fov_x_deg=20.0)
    X_H = surface_features(fy1_target(), n_features=150, rng=np.random.default_rng(ss_points)).X_T
    step_rotvec_H = np.deg2rad([0.5, 0.5, 0.5])
    R_delta = matrix_from_quat(quat_from_rotvec(step_rotvec_H))
    axis_angle_deg = np.array([2.0, 5.0, 10.0, 20.0, 40.0]) if small else np.geomspace(1.0, 60.0, 12)
    trials = 60 if small else 400
    r_CT_H = np.stack([symmetric_views(3, DISTANCE_M, a).r_CT_H for a in axis_angle_deg])  # (S, 3, 3)

    # 2. run: the bound for every geometry at once, then the Monte Carlo geometry by geometry
    score = crlb_score(camera, X_H, pixel_sigma_px=PIXEL_SIGMA_PX, increment_rotvec_H=step_rotvec_H)
    crlb_deg = np.degrees(score(r_CT_H[None]))[0]
    rng = np.random.default_rng(ss_noise)
    mc_deg = np.array([monte_carlo_rms_deg(camera, X_H, r, R_delta, trials=trials, rng=rng) for r in r_CT_H])

    # 3. pull the outputs: the ratio, and the spread expected of an RMS over `trials` 3-D errors
    ratio = mc_deg / crlb_deg
    rel_sd = 1.0 / np.sqrt(2.0 * 3 * trials)  # χ² with 3·trials degrees of freedom, square-rooted

    # 4. plot
    fig = Figure(figsize=(9.0, 3.6), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    ax1.semilogx(axis_angle_deg, crlb_deg, "-", label="Cramér–Rao bound")
    ax1.semilogx(axis_angle_deg, mc_deg, "o", label=f"Monte Carlo, {trials} trials (ML registration)")
    ax1.set(xlabel="angle between adjacent optical axes γ [deg]", ylabel="RMS increment error [deg]",
            title=f"3 views at {DISTANCE_M:.0f} m, {PIXEL_SIGMA_PX} px noise, {len(X_H)} points")
    ax1.legend(fontsize=8)
    ax2.semilogx(axis_angle_deg, ratio, "o")
    ax2.axhline(1.0, color="k", lw=1)
    ax2.fill_between(axis_angle_deg, 1 - 2 * rel_sd, 1 + 2 * rel_sd, color="0.85", label="±2σ of an RMS")
    ax2.set(xlabel="γ [deg]", ylabel="Monte Carlo / bound", ylim=(0.7, 1.3), title="efficiency")
    ax2.legend(fontsize=8)
    for ax in (ax1, ax2):
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xticks(axis_angle_deg, [f"{a:.3g}" for a in axis_angle_deg])
    ax1.set_ylim(bottom=0.0)
    fig.suptitle("Cramér–Rao bound of the attitude increment vs the formation's baseline angle")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figure = out_dir / f"{NAME}.png"
    fig.savefig(figure, dpi=110)
    return {"figure": figure, "trials": trials, "max_ratio": float(ratio.max()), "min_ratio": float(ratio.min()),
            "axis_angle_deg": axis_angle_deg, "crlb_deg": crlb_deg, "monte_carlo_deg": mc_deg, "camera": camera,
            "X_H": X_H, "r_CT_H": r_CT_H, "R_delta": R_delta, "pixel_sigma_px": PIXEL_SIGMA_PX}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, default=GALLERY, help="folder for the figure")
    parser.add_argument("--full", action="store_true", help="12 angles × 400 trials instead of 5 × 60")
    args = parser.parse_args()
    res = main(out_dir=args.out_dir, small=not args.full)
    for a, b, m in zip(res["axis_angle_deg"], res["crlb_deg"], res["monte_carlo_deg"], strict=True):
        print(f"γ = {a:5.1f} deg: bound {b:.4f} deg, Monte Carlo {m:.4f} deg (ratio {m / b:.3f})")
    print(f"figure: {res['figure']}")
