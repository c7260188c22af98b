"""Maps of an envelope sweep of the 001 pose solver, drawn from the stored sweep only.

Range on the horizontal axis, cube edge on the vertical, one row per pixel noise (any other swept key
gives one file per value).  Errors on a log colour scale (log10 of the value; each cell is labelled
with the value itself), ratios to the Cramér–Rao bound on a shared 0.5–2 range, rates on 0–1.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

from experiments.plotting import (  # noqa: E402
    check_format,
    clipped_extend,
    figure_path,
    plot_map,
    readable_text_color,
    save,
    shared_range,
    sweep_overview_figures,
)
from experiments.scenarios.rodrigues.envelope import (  # noqa: E402
    ENVELOPE_REASONS,
    ENVELOPE_SOLVERS,
    GROSS_MAHALANOBIS,
    envelope_statistics,
)

__all__ = ["plot_sweep", "RATIO_RANGE"]

#: colour range of the error/bound maps
RATIO_RANGE = (0.5, 2.0)
_X, _Y, _ROW = "range_m", "cube_edge_m", "noise_px"
_SHORT = {"too_few_points": "few", "rank_deficient": "rank", "behind_camera": "behind", "gibbs_singular": "gibbs",
          "diverged": "div", "not_converged": "nc", "opencv_failed": "cvfail", "opencv_error": "cverr"}


def _fmt(v: float) -> str:
    return "" if not np.isfinite(v) else (f"{v:.2g}" if abs(v) < 100 else f"{v:.0f}")


def _label_cells(ax, mesh, texts: np.ndarray, x: np.ndarray, y: np.ndarray, colour_values: np.ndarray) -> None:
    """Write ``texts[j, i]`` in each cell, black or white by the cell's colour."""
    for (j, yy), (i, xx) in itertools.product(enumerate(y), enumerate(x)):
        if texts[j, i]:
            c = colour_values[j, i]
            face = mesh.cmap(mesh.norm(float(c))) if np.isfinite(c) else (1, 1, 1, 1)
            ax.text(xx, yy, texts[j, i], ha="center", va="center", fontsize=6.5, color=readable_text_color(face))


def _grid(ax, values: np.ndarray, x, y, *, vmin, vmax, cmap, title, texts=None):
    plot_map(values, np.arange(len(x)), np.arange(len(y)), ax=ax, vmin=vmin, vmax=vmax, cmap=cmap, title=title,
             xlabel="range [m]", ylabel="cube edge [m]", colorbar=False)
    ax.set_xticks(range(len(x)), [f"{v:g}" for v in x], fontsize=7)
    ax.set_yticks(range(len(y)), [f"{v:g}" for v in y], fontsize=7)
    if texts is not None:
        _label_cells(ax, ax.collections[0], texts, np.arange(len(x)), np.arange(len(y)), values)


def _panels(st: xr.Dataset, rows: list, columns: list, value, *, name: str, suptitle: str, cmap: str, cbar: str,
            log: bool, fig_dir: Path, format: str, fixed: tuple[float, float] | None = None,
            texts=None) -> Path:
    """One figure: ``rows`` (selections) × ``columns`` (``(title, key)``); ``value(sel, key) -> map``."""
    x, y = st[_X].values, st[_Y].values
    maps = [[value(r, c[1]) for c in columns] for r in rows]
    shown = [np.log10(np.where(m > 0, m, np.nan)) if log else m for row in maps for m in row]
    fig, axes = plt.subplots(len(rows), len(columns), figsize=(3.9 * len(columns), 3.1 * len(rows) + 0.6),
                             layout="constrained", squeeze=False)
    for ci, (ctitle, key) in enumerate(columns):
        col = [shown[ri * len(columns) + ci] for ri in range(len(rows))]
        vmin, vmax = fixed if fixed else shared_range(*col)
        for ri, r in enumerate(rows):
            tag = ", ".join(f"{k} = {v:g}" for k, v in r.items())
            m = maps[ri][ci]
            t = texts(r, key) if texts else np.vectorize(_fmt, otypes=[str])(m)
            _grid(axes[ri, ci], col[ri], x, y, vmin=vmin, vmax=vmax, cmap=cmap, texts=t,
                  title=f"{ctitle}" + (f"\n{tag}" if tag else ""))
        fig.colorbar(axes[0, ci].collections[0], ax=axes[:, ci].tolist(), label=cbar if fixed else
                     f"{'log10 ' if log else ''}{ctitle}", extend=clipped_extend(np.concatenate(
                         [c.ravel() for c in col]), vmin, vmax) if fixed else "neither")
    fig.suptitle(suptitle, fontsize=10)
    return save(fig, figure_path(fig_dir, name, format))


def _cell_maps(s: xr.Dataset, rows: list, suffix: str, fig_dir: Path, format: str) -> list[Path]:
    """The five map figures of one value of the keys other than range, size and noise."""
    paths: list[Path] = []
    pick = lambda r, var, solver="rodrigues": s[var].sel(solver=solver, **r).values  # noqa: E731
    paths.append(_panels(
        s, rows, [("along-LOS RMS error [m]", "rms_along_los"), ("across-LOS RMS error [m]", "rms_across_los"),
                  ("attitude RMS error [deg]", "rms_attitude")],
        lambda r, k: pick(r, k), name=f"envelope_errors{suffix}", log=True, cmap="viridis", cbar="",
        suptitle="001 solver (switching) over its envelope: RMS errors over random attitudes", fig_dir=fig_dir,
        format=format))
    paths.append(_panels(
        s, rows, [("along LOS", "ratio_along_los"), ("across LOS", "ratio_across_los"),
                  ("attitude", "ratio_attitude")],
        lambda r, k: pick(r, k), name=f"envelope_bound_ratio{suffix}", log=False, cmap="cividis",
        cbar="RMS error / Cramer-Rao bound", fixed=RATIO_RANGE, fig_dir=fig_dir, format=format,
        suptitle="001 solver: measured RMS error / Cramer-Rao bound (1 = efficient)"))
    paths.append(_panels(
        s, rows, [(sv, sv) for sv in ENVELOPE_SOLVERS],
        lambda r, k: np.fmax.reduce([pick(r, v, k) for v in ("ratio_along_los", "ratio_across_los",
                                                              "ratio_attitude")]),
        name=f"envelope_bound_ratio_solvers{suffix}", log=False, cmap="cividis", fixed=RATIO_RANGE,
        cbar="worst RMS error / Cramer-Rao bound", fig_dir=fig_dir, format=format,
        suptitle="worst of the three error/bound ratios per solver, same frames"))

    def fail_text(r, k):
        f = s["failures"].sel(solver=k, **r)  # (reason, y, x)
        rate = s["failure_rate"].sel(solver=k, **r).values
        top = f["reason"].values[f.argmax("reason").values]
        return np.where(rate > 0, np.vectorize(lambda a, b: f"{a:.2f}\n{_SHORT[b]}", otypes=[str])(rate, top),
                        "0")

    paths.append(_panels(
        s, rows, [(sv, sv) for sv in ENVELOPE_SOLVERS], lambda r, k: pick(r, "failure_rate", k),
        name=f"envelope_failures{suffix}", log=False, cmap="cividis", fixed=(0.0, 1.0),
        cbar="fraction of trials without a pose", texts=fail_text, fig_dir=fig_dir, format=format,
        suptitle="no pose returned (fraction; main reason: " + ", ".join(
            f"{v} = {k}" for k, v in _SHORT.items() if float(s["failures"].sel(reason=k).sum()) > 0) + ")"))
    paths.append(_panels(
        s, rows, [(sv, sv) for sv in ENVELOPE_SOLVERS], lambda r, k: pick(r, "gross_rate", k),
        name=f"envelope_gross_errors{suffix}", log=False, cmap="cividis", fixed=(0.0, 1.0),
        cbar="fraction of trials", fig_dir=fig_dir, format=format,
        suptitle=f"gross errors: pose returned with Mahalanobis distance > {GROSS_MAHALANOBIS:g} under the bound"))
    return paths


def plot_sweep(dataset: xr.Dataset, fig_dir: Path, *, format: str = "png") -> list[Path]:
    """Envelope maps of a ``rodrigues_001`` sweep: errors, error/bound, failures and gross errors.

    Falls back to the generic overview when the grid lacks ``range_m`` or ``cube_edge_m``.
    """
    check_format(format)
    ds = dataset
    grid = [d for d in ds["done"].dims]
    if not {_X, _Y} <= set(grid) or "failed" not in ds:
        return sweep_overview_figures(ds, fig_dir, format=format)
    st = envelope_statistics(ds).transpose(..., _Y, _X)
    row_dim = [_ROW] if _ROW in grid else []
    other = [d for d in grid if d not in (_X, _Y, *row_dim)]
    paths: list[Path] = []
    for combo in itertools.product(*(st[d].values.tolist() for d in other)):
        sel0 = dict(zip(other, combo, strict=True))
        suffix = "".join(f"_{k}{v:g}" for k, v in sel0.items())
        s = st.sel(sel0) if sel0 else st
        rows = [{_ROW: v} for v in s[_ROW].values.tolist()] if row_dim else [{}]
        paths += _cell_maps(s, rows, suffix, fig_dir, format)
    totals = st["failures"].sum([d for d in st["failures"].dims if d not in ("solver", "reason")])
    fig, ax = plt.subplots(figsize=(7.5, 3.4), layout="constrained")
    w = 0.8 / len(ENVELOPE_SOLVERS)
    for k, sv in enumerate(ENVELOPE_SOLVERS):
        ax.bar(np.arange(len(ENVELOPE_REASONS)) + (k - 1) * w, totals.sel(solver=sv).values, w, label=sv)
    ax.set_xticks(range(len(ENVELOPE_REASONS)), ENVELOPE_REASONS, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("failed trials, whole sweep [1]")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    ax.grid(axis="y", alpha=0.3)
    paths.append(save(fig, figure_path(fig_dir, "envelope_failure_reasons", format)))
    return paths
