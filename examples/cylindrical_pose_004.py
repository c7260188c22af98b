"""Paper 004: 3-D points and attitude measured by orthogonal cylindrical imaging (two linear-CCD cameras).

Each camera of the rig has two linear CCDs behind cylindrical lenses, so a lit LED gives two spot
positions and hence two planes; the two cameras' four planes intersect at the LED.  The rig of
004 §4 (2 m baseline, optical axes converging at 30°) is calibrated on control points in a 1 m cube,
LEDs in that cube are measured point by point (the spot centres with the CCDs' noise), and three of
them give the attitude of the object carrying them.

Run it:  ``python examples/cylindrical_pose_004.py`` (seconds) → ``docs/figures/gallery/cylindrical_pose_004.png``
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from chaser.cylindrical import (
    attitude_from_three_points,
    calibrate_system,
    control_points_in_cube,
    measure_points,
    paper_rig,
)
from vision.cylindrical import measure_spot_centres

NAME = "cylindrical_pose_004"
GALLERY = Path(__file__).resolve().parents[1] / "docs" / "figures" / "gallery"


def main(*, out_dir: Path = GALLERY, small: bool = True, seed: int = 1) -> dict[str, Any]:
    """Calibrate, measure, compare with the truth, draw; returns key numbers, arrays and the figure's path.

    Parameters
    ----------
    out_dir : Path
        Folder for ``cylindrical_pose_004.png``.
    small : bool
        20 measured points (seconds); ``False``: 200.
    seed : int
        Seed of the control points, the calibration and the spot noise.
    """
    # 1. configure: the rig, its calibration, the LEDs to measure
    ss_cal, ss_ctrl, ss_pts, ss_spot = np.random.SeedSequence(seed).spawn(4)
    rig = paper_rig()
    centre_W = np.array([1.0, 3.5, 0.0])  # a 1 m cube 3.0–4.0 m in front of the baseline
    cal = calibrate_system(rig, control_points_in_cube(30, centre_W=centre_W, rng=np.random.default_rng(ss_ctrl)),
                           rng=np.random.default_rng(ss_cal))
    n_points = 20 if small else 200
    leds_W = centre_W + np.array([[0.2, 0.0, 0.1], [0.0, 0.0, 0.0], [-0.1, 0.3, 0.0]])
    X_true_W = np.concatenate([leds_W, centre_W + np.random.default_rng(ss_pts).uniform(-0.5, 0.5, (n_points - 3, 3))])

    # 2. run: the spot centres of every LED on both cameras (20 scans averaged), then the plane intersections
    spot_rngs = [np.random.default_rng(s) for s in ss_spot.spawn(rig.n_cameras)]
    uv_px = np.stack([measure_spot_centres(rig.cameras[c], rig.true_pixels(X_true_W)[:, c], rng=spot_rngs[c],
                                           n_scans=20) for c in range(rig.n_cameras)], axis=1)
    fix = measure_points(cal.cameras, uv_px)
    attitude = attitude_from_three_points(*fix.X_W[:3])
    attitude_true = attitude_from_three_points(*leds_W)

    # 3. pull the outputs: point errors, attitude error
    error_W_mm = 1e3 * (fix.X_W - X_true_W)
    error_mm = np.linalg.norm(error_W_mm, axis=1)
    c = (np.trace(attitude.R_OS @ attitude_true.R_OS.T) - 1.0) / 2.0
    attitude_error_deg = float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))

    # 4. plot: the rig and the points from above, the error distribution
    fig = Figure(figsize=(9.5, 3.8), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    centres = rig.centres_W
    ax1.plot(centres[:, 0], centres[:, 1], "ks", ms=8, label="cameras")
    ax1.plot(X_true_W[:, 0], X_true_W[:, 1], ".", color="tab:blue", label="LEDs")
    ax1.plot(leds_W[:, 0], leds_W[:, 1], "o", mfc="none", color="tab:red", ms=9, label="attitude LEDs")
    ax1.set(xlabel="x_W [m]", ylabel="y_W [m]", aspect="equal", title="rig and measured points, from above")
    ax1.legend(fontsize=8, loc="lower right")
    for k in range(3):
        ax2.plot(np.full(n_points, k) + np.linspace(-0.2, 0.2, n_points), error_W_mm[:, k] * 1e3, "o", ms=4)
    ax2.axhline(0.0, color="0.6", lw=1)
    ax2.set(xticks=[0, 1, 2], xticklabels=["x", "y", "z"], ylabel="measured − true [µm]",
            title=f"point errors: RMS {np.sqrt(np.mean(error_mm ** 2)) * 1e3:.0f} µm")
    fig.suptitle(f"004 orthogonal cylindrical imaging: {n_points} points, attitude from 3 LEDs "
                 f"within {attitude_error_deg:.3f} deg")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figure = out_dir / f"{NAME}.png"
    fig.savefig(figure, dpi=110)
    return {"figure": figure, "points": n_points, "points_ok": int(np.sum(fix.ok)),
            "rms_error_mm": float(np.sqrt(np.mean(error_mm ** 2))), "attitude_error_deg": attitude_error_deg,
            "X_true_W": X_true_W, "X_measured_W": fix.X_W, "R_OS": attitude.R_OS}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, default=GALLERY, help="folder for the figure")
    parser.add_argument("--full", action="store_true", help="200 points instead of 20")
    args = parser.parse_args()
    res = main(out_dir=args.out_dir, small=not args.full)
    print(f"{res['points_ok']}/{res['points']} points; RMS error {res['rms_error_mm']:.4f} mm; attitude error "
          f"{res['attitude_error_deg']:.4f} deg")
    print(f"figure: {res['figure']}")
