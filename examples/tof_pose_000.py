"""Paper 000: the relative pose of a cooperative marker plate from one TOF-camera frame.

An SR4000-like time-of-flight camera (``vision.tof``) renders the amplitude and radial-range images
of a plate carrying six dark circular markers, 0.7 m away and turned a few degrees, with the
sensor's noise.  ``chaser.tof.estimate_tof_pose`` extracts the markers (LoG filter, thresholds,
contrast-weighted centroids), labels them against the plate model and fits the pose by weighted
SVD; the result is compared with the pose the frame was rendered at.

Run it:  ``python examples/tof_pose_000.py`` (seconds) → ``docs/figures/gallery/tof_pose_000.png``
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from attitude.euler import matrix_from_euler
from chaser.tof import estimate_tof_pose
from vision.tof import CooperativeTarget, render_tof_frame, sr4000

NAME = "tof_pose_000"
GALLERY = Path(__file__).resolve().parents[1] / "docs" / "figures" / "gallery"


def main(*, out_dir: Path = GALLERY, small: bool = True, seed: int = 1) -> dict[str, Any]:
    """Render, estimate, compare, draw; returns the key numbers, the truth, the estimate and the figure's path.

    Parameters
    ----------
    out_dir : Path
        Folder for ``tof_pose_000.png``.
    small : bool
        One frame; ``False``: 30 frames of the same pose (repeatability, as 000 Table 1).
    seed : int
        Seed of the sensor noise.
    """
    # 1. configure: camera, target, the true pose (3-2-1 angles of the plate relative to the camera)
    camera, target = sr4000(), CooperativeTarget()
    angles_321_rad = np.deg2rad([6.0, -4.0, 3.0])
    R_SC = matrix_from_euler(angles_321_rad, "321")
    r_CS_S = np.array([0.02, -0.015, 0.70])
    rng = np.random.default_rng(seed)

    # 2. run: render and estimate, frame by frame
    n_frames = 1 if small else 30
    frames, results = [], []
    for _ in range(n_frames):
        frames.append(render_tof_frame(camera, target, R_SC, r_CS_S, rng=rng))
        results.append(estimate_tof_pose(frames[-1], camera, target.plate))

    # 3. pull the outputs: position and attitude errors against the rendered pose
    ok = np.array([r.ok for r in results])
    position_error_mm = np.array([1e3 * np.linalg.norm(r.r_CS_S - r_CS_S) for r in results])
    attitude_error_deg = np.array([np.degrees(np.arccos(np.clip((np.trace(r.R_SC.T @ R_SC) - 1) / 2, -1, 1)))
                                   for r in results])

    # 4. plot: the amplitude image with the labelled markers, the range image
    frame, res = frames[0], results[0]
    fig = Figure(figsize=(9.0, 3.8), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    im = ax1.imshow(frame.amplitude_dn, cmap="gray")
    fig.colorbar(im, ax=ax1, label="amplitude [DN]", shrink=0.85)
    uv = res.detections.uv_px
    ax1.plot(uv[:, 0], uv[:, 1], "+", color="tab:orange", ms=10, mew=1.5)
    for (u, v), label in zip(uv, res.labels, strict=True):
        ax1.annotate(str(label), (u, v), xytext=(7, 5), textcoords="offset points", color="tab:red",
                     fontweight="bold", bbox={"boxstyle": "round,pad=0.1", "fc": "white", "lw": 0})
    ax1.set(title="amplitude, markers and their labels", xlabel="u [px]", ylabel="v [px]")
    rng_img = np.where(frame.valid, frame.range_m, np.nan)
    im = ax2.imshow(rng_img, cmap="viridis")
    fig.colorbar(im, ax=ax2, label="range [m]", shrink=0.85)
    ax2.set(title="radial range", xlabel="u [px]")
    fig.suptitle(f"000 TOF pose at 0.70 m: position error {position_error_mm[0]:.1f} mm, "
                 f"attitude error {attitude_error_deg[0]:.2f} deg ({res.n_matched} markers)")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figure = out_dir / f"{NAME}.png"
    fig.savefig(figure, dpi=110)
    return {"figure": figure, "frames": n_frames, "frames_ok": int(ok.sum()),
            "position_error_mm": float(np.max(position_error_mm)), "attitude_error_deg": float(np.max(attitude_error_deg)),
            "R_SC_true": R_SC, "r_CS_S_true": r_CS_S, "result": res, "plate": target.plate}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, default=GALLERY, help="folder for the figure")
    parser.add_argument("--full", action="store_true", help="30 frames instead of one")
    args = parser.parse_args()
    res = main(out_dir=args.out_dir, small=not args.full)
    print(f"{res['frames_ok']}/{res['frames']} frames ok; largest position error {res['position_error_mm']:.2f} mm, "
          f"attitude error {res['attitude_error_deg']:.3f} deg")
    print(f"figure: {res['figure']}")
