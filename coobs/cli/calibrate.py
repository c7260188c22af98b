"""``coobs calibrate``: measure the rendered mode's statistics and write the calibration file.

Runs :func:`experiments.studies.rendered_calibration.calibrate` and writes its JSON (by default the
shipped ``vision/calibration/rendered_sift.json``, which the calibrated geometric mode and the
rendered mode's σ per keypoint read), then prints the headline figures per target and range.
"""

from __future__ import annotations

import json
from pathlib import Path

import typer
from rich.table import Table

from coobs.cli._console import console, fail, progress_bar
from experiments.studies.rendered_calibration import DEFAULT, QUICK, CalibrationSpec
from vision.calibration import calibration_path

__all__ = ["calibrate"]


def _fmt(v: object, spec: str = ".3g") -> str:
    return "-" if v is None else format(v, spec)


def calibrate(
    out: Path = typer.Option(None, "--out", help="JSON file to write (default: the shipped "
                             "vision/calibration/rendered_sift.json)."),
    quick: bool = typer.Option(False, "--quick", help="One attitude per target and range (a test, ~10 s)."),
    attitudes: int = typer.Option(None, "--attitudes", help="Random attitudes per target and range "
                                  f"(default {DEFAULT.attitudes})."),
    targets: str = typer.Option(",".join(DEFAULT.targets), "--targets",
                                help="Comma-separated targets: fy1 and bundled meshes (topex, hubble)."),
    ranges_m: str = typer.Option(",".join(f"{r:g}" for r in DEFAULT.ranges_m), "--ranges-m",
                                 help="Comma-separated camera ranges, m."),
    seed: int = typer.Option(DEFAULT.seed, "--seed", help="Root seed."),
) -> None:
    """Measure SIFT noise, detection density, match and association rates on rendered images against their truth."""
    base = QUICK if quick else DEFAULT
    try:
        rng_m = tuple(float(r) for r in ranges_m.split(","))
    except ValueError:
        raise fail(f"--ranges-m: expected comma-separated numbers, got {ranges_m!r}") from None
    names = tuple(t.strip() for t in targets.split(",") if t.strip())
    from vision.target import BUNDLED_MESHES

    bad = [t for t in names if t != "fy1" and t not in BUNDLED_MESHES]
    if bad:
        raise fail(f"--targets: unknown target {bad[0]!r}; known: fy1, {', '.join(sorted(BUNDLED_MESHES))}")
    if attitudes is not None and attitudes < 1:
        raise fail(f"--attitudes: must be >= 1, got {attitudes}")
    try:
        spec = CalibrationSpec(**{**base.__dict__, "targets": names, "ranges_m": rng_m, "seed": int(seed),
                                  **({"attitudes": int(attitudes)} if attitudes is not None else {})})
    except ValueError as exc:
        raise fail(f"--ranges-m/--targets: {exc}") from None
    path = Path(out) if out is not None else calibration_path()
    command = " ".join(["coobs calibrate", *(["--quick"] if quick else []),
                        *([f"--attitudes {attitudes}"] if attitudes is not None else []),
                        f"--targets {','.join(names)}", f"--ranges-m {','.join(f'{r:g}' for r in rng_m)}",
                        f"--seed {int(seed)}", *([f"--out {out}"] if out is not None else [])])
    update, stop = progress_bar()
    try:
        from experiments.studies.rendered_calibration import calibrate as run

        data = run(spec, command=command.strip(), progress=update)
    finally:
        stop()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    table = Table(title=f"rendered SIFT calibration ({data['provenance']['wall_s']} s) -> {path}")
    for col in ("target", "range [m]", "sigma small/large [px]", "keypoints [1/m^2]",
                "pair survival (first angle)", "false matches", "assoc. survival (first/last change)",
                "false assoc."):
        table.add_column(col, justify="right")
    for name, t in data["targets"].items():
        sig = [s for s in t["sigma_px"] if s is not None] or [None]
        for r, range_m in enumerate(t["ranges_m"]):
            kp = sum(map(sum, t["keypoints"][r]))
            area = sum(map(sum, t["visible_area_m2"][r]))
            cv, asc = t["cross_view"], t["association"]
            table.add_row(name, f"{range_m:g}", f"{_fmt(sig[0])}/{_fmt(sig[-1])}",
                          _fmt(kp / area if area else None), _fmt(cv["survival"][r][0]),
                          _fmt(cv["false_match_rate"][r][0]),
                          f"{_fmt(asc['survival'][r][0])}/{_fmt(asc['survival'][r][-1])}",
                          _fmt(asc["false_rate"][r][0]))
    console.print(table)
