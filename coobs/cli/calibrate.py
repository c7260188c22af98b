"""``coobs calibrate``: measure the rendered mode's statistics and write the calibration file.

Runs :func:`experiments.studies.rendered_calibration.calibrate` and writes its JSON (by default the
shipped ``vision/calibration/rendered_sift.json``, which the calibrated geometric mode and the
rendered mode's σ per keypoint read), then prints the headline figures per target and range.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import typer
from rich.table import Table

from coobs.cli._console import console, fail, progress_bar
from experiments.studies.rendered_calibration import DEFAULT, QUICK, CalibrationSpec
from vision.calibration import CalibrationTableEmpty, calibration_path

__all__ = ["calibrate"]


def _fmt(v: object, spec: str = ".3g") -> str:
    return "-" if v is None else format(v, spec)


_NUMBER_LIST = re.compile(r"\[(?:\s*(?:-?[0-9.eE+-]+|null),)*\s*(?:-?[0-9.eE+-]+|null)\s*\]")


def _write(path: Path, data: dict) -> None:
    """The calibration as indented JSON with every innermost list of numbers on one line."""
    text = _NUMBER_LIST.sub(lambda m: "[" + ", ".join(x.strip() for x in m.group(0)[1:-1].split(",")) + "]",
                            json.dumps(data, indent=1))
    path.write_text(text + "\n", encoding="utf-8")


def _nees_only(path: Path, base: CalibrationSpec, attitudes: int | None, out: Path | None) -> None:
    from experiments.studies.nees_calibration import NeesSpec, add_triangulation_nees

    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise fail(f"--nees-only: no calibration file at {path}") from None
    n = int(attitudes) if attitudes is not None else base.nees_attitudes
    spec = NeesSpec(attitudes=n, angles_deg=tuple(base.nees_angles_deg))
    command = " ".join(["coobs calibrate --nees-only", *(["--quick"] if base is QUICK else []),
                        *([f"--attitudes {attitudes}"] if attitudes is not None else []),
                        *([f"--out {out}"] if out is not None else [])])
    total = len(data["targets"]) * max(len(t["ranges_m"]) for t in data["targets"].values()) * n
    update, stop = progress_bar()
    done = [0]

    def step() -> None:
        done[0] += 1
        update(done[0], total)

    try:
        data = add_triangulation_nees(data, spec, command=command, progress=step)
    finally:
        stop()
    _write(path, data)
    table = Table(title=f"triangulation σ² inflation ({data['provenance']['triangulation_nees']['wall_s']} s) -> {path}")
    for col in ("target", "range [m]", "angle [deg]", *(f"{c}: inflation (points)" for c in
                                                       data["targets"][next(iter(data["targets"]))]
                                                       ["triangulation_nees"]["classes"])):
        table.add_column(col, justify="right")
    for name, t in data["targets"].items():
        tn = t["triangulation_nees"]
        for r, range_m in enumerate(t["ranges_m"]):
            for a, ang in enumerate(tn["angle_deg"]):
                table.add_row(name, f"{range_m:g}", f"{ang:g}", *(f"{_fmt(v)} ({p})" for v, p in
                                                                 zip(tn["sigma2_inflation"][r][a],
                                                                     tn["points"][r][a], strict=True)))
    console.print(table)


def calibrate(
    out: Path = typer.Option(None, "--out", help="JSON file to write (default: the shipped "
                             "vision/calibration/rendered_sift.json)."),
    quick: bool = typer.Option(False, "--quick", help="One attitude per target and range and fewer angles (a test, ~10 s; too few samples "
                              "leave a table empty and are refused: add e.g. --attitudes 3)."),
    attitudes: int = typer.Option(None, "--attitudes", help="Random attitudes per target and range "
                                  f"(default {DEFAULT.attitudes})."),
    targets: str = typer.Option(",".join(DEFAULT.targets), "--targets",
                                help="Comma-separated targets: fy1 and bundled meshes (topex, hubble)."),
    ranges_m: str = typer.Option(",".join(f"{r:g}" for r in DEFAULT.ranges_m), "--ranges-m",
                                 help="Comma-separated camera ranges, m."),
    seed: int = typer.Option(DEFAULT.seed, "--seed", help="Root seed."),
    nees_only: bool = typer.Option(False, "--nees-only", help="Only (re)measure the triangulation σ² inflation "
                                   "(per track class, per surface material, and the errors' heavy-tail spread) "
                                   "of an existing calibration file (--out, default the shipped one) with its "
                                   "own targets, ranges and seed (--attitudes: its attitudes per target and range); the other "
                                   "tables are kept."),
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
    from vision.allocator import retain_freed_memory

    retain_freed_memory()                 # rendered frames: keep their freed buffers (vision.allocator)
    if nees_only:
        _nees_only(path, base, attitudes, out)
        return
    command = " ".join(["coobs calibrate", *(["--quick"] if quick else []),
                        *([f"--attitudes {attitudes}"] if attitudes is not None else []),
                        f"--targets {','.join(names)}", f"--ranges-m {','.join(f'{r:g}' for r in rng_m)}",
                        f"--seed {int(seed)}", *([f"--out {out}"] if out is not None else [])])
    update, stop = progress_bar()
    try:
        from experiments.studies.rendered_calibration import calibrate as run

        data = run(spec, command=command.strip(), progress=update)
    except CalibrationTableEmpty as exc:       # a table left without any measured value: too few samples
        raise fail(f"--attitudes: {spec.attitudes} per target and range left a table empty ({exc}); "
                   "use more attitudes") from None
    finally:
        stop()
    path.parent.mkdir(parents=True, exist_ok=True)
    _write(path, data)
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
