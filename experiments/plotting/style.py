"""House style of every coobs figure: colour maps, units, legends, shaded spans, output formats.

One place decides what the figures share, so that they can be checked (``tests/experiments/test_figures*.py``):

- colour maps come from :data:`SEQUENTIAL_CMAPS` (perceptually uniform) or, for signed quantities
  only, :data:`DIVERGING_CMAPS`; grey images use ``"gray"``;
- units are written in square brackets after the quantity, one way everywhere (:data:`UNITS`):
  ``"time [s]"``, ``"attitude error [deg]"``;
- legends sit outside the data (:func:`legend_below`, :func:`legend_right`);
- figures are written as PNG, PDF or SVG, chosen by the file's suffix (:func:`save`) or by a
  ``format`` argument (:func:`figure_path`), with no timestamps in PDF or SVG files.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.legend import Legend  # noqa: E402

__all__ = [
    "SEQUENTIAL_CMAPS",
    "DIVERGING_CMAPS",
    "IMAGE_CMAPS",
    "ALLOWED_CMAPS",
    "UNITS",
    "FORMATS",
    "ENVELOPE_COLOR",
    "ECLIPSE_COLOR",
    "ECLIPSE_HATCH",
    "GAP_COLOR",
    "check_cmap",
    "check_format",
    "figure_path",
    "label",
    "legend_below",
    "legend_right",
    "readable_text_color",
    "relative_luminance",
    "save",
    "shade_spans",
]

#: perceptually uniform sequential colour maps (and their reverses)
SEQUENTIAL_CMAPS = frozenset({"viridis", "viridis_r", "cividis", "cividis_r"})
#: diverging colour maps, for signed quantities only
DIVERGING_CMAPS = frozenset({"coolwarm", "RdBu_r"})
#: colour maps of grey images (camera frames, amplitude images)
IMAGE_CMAPS = frozenset({"gray"})
ALLOWED_CMAPS = SEQUENTIAL_CMAPS | DIVERGING_CMAPS | IMAGE_CMAPS
#: the unit strings written in labels, inside square brackets
UNITS = ("s", "m", "mm", "deg", "deg/s", "mdeg", "px", "DN", "%", "µs", "m/s", "mm/s", "orbits", "min")
#: output formats of every plot entry point
FORMATS = ("png", "pdf", "svg")
#: fill of the ±3σ envelope, shading of eclipse epochs, shading of epochs without a measurement
ENVELOPE_COLOR = "#5ec962"
ECLIPSE_COLOR = "0.75"
#: hatch of eclipse spans (tells them from the envelope in grey print)
ECLIPSE_HATCH = "///"
GAP_COLOR = "#fde725"


def check_cmap(cmap: str) -> str:
    """``cmap`` if it is in :data:`ALLOWED_CMAPS`; ``ValueError`` naming the allowed ones otherwise."""
    if cmap not in ALLOWED_CMAPS:
        raise ValueError(f"cmap: {cmap!r} is not perceptually uniform; use one of {', '.join(sorted(ALLOWED_CMAPS))}")
    return cmap


def check_format(format: str) -> str:
    """``format`` if it is one of :data:`FORMATS`; a one-line ``ValueError`` naming the value otherwise."""
    if format not in FORMATS:
        raise ValueError(f"format: must be one of {', '.join(FORMATS)}, got {format!r}")
    return format


def figure_path(fig_dir: Path, stem: str, format: str = "png") -> Path:
    """``fig_dir / f"{stem}.{format}"`` after checking ``format``."""
    return Path(fig_dir) / f"{stem}.{check_format(format)}"


def label(quantity: str, unit: str = "") -> str:
    """``"quantity [unit]"`` (just ``quantity`` without a unit): the one way units are written."""
    return f"{quantity} [{unit}]" if unit else quantity


def save(fig: Figure, path: Path, *, dpi: int = 150) -> Path:
    """Write ``fig`` in the format of ``path``'s suffix (``.png``, ``.pdf`` or ``.svg``) and close it.

    PDF and SVG files carry no creation date (and SVG ids come from a fixed salt), so the same
    figure gives the same bytes.  ``dpi`` applies to PNG files and to images inside PDF/SVG;
    ``matplotlib.rcParams["savefig.dpi"]``, when set to a number, overrides it (one resolution
    for a whole batch of figures, e.g. a journal's or a test's).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    fmt = check_format(path.suffix.lstrip(".").lower())
    path.parent.mkdir(parents=True, exist_ok=True)
    metadata = {"png": {"Software": None}, "pdf": {"CreationDate": None, "ModDate": None, "Producer": None},
                "svg": {"Date": None}}[fmt]
    rc_dpi = matplotlib.rcParams["savefig.dpi"]
    dpi = rc_dpi if isinstance(rc_dpi, int | float) else dpi
    with matplotlib.rc_context({"svg.hashsalt": "coobs"}):
        fig.savefig(path, dpi=dpi, format=fmt, metadata=metadata)
    plt.close(fig)
    return path


def relative_luminance(rgba: Iterable[float]) -> float:
    """WCAG relative luminance (0 black … 1 white) of an sRGB colour."""
    c = np.asarray(tuple(rgba)[:3], dtype=float)
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return float(lin @ [0.2126, 0.7152, 0.0722])


def readable_text_color(background) -> str:
    """``"k"`` or ``"w"``, whichever contrasts more with ``background`` (WCAG contrast ratio)."""
    y = relative_luminance(to_rgba(background))
    return "k" if (y + 0.05) / 0.05 >= 1.05 / (y + 0.05) else "w"


def legend_below(fig: Figure, handles=None, labels=None, *, ncol: int | None = None, fontsize: float = 8) -> Legend:
    """One legend for the whole figure, below the axes (needs a constrained layout): never over data.

    Without ``handles``, the labelled artists of all axes are collected (duplicates once).
    """
    if handles is None:
        seen: dict[str, object] = {}
        for ax in fig.axes:
            for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
                seen.setdefault(lab, h)
        labels, handles = list(seen), list(seen.values())
    n = len(handles)
    return fig.legend(handles, labels, loc="outside lower center", ncol=ncol or min(max(n, 1), 4),
                      fontsize=fontsize, frameon=False)


def legend_right(ax: Axes, *, fontsize: float = 7, title: str | None = None) -> Legend:
    """The axes' legend outside on its right (never over the data)."""
    return ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=fontsize,
                     title=title, title_fontsize=fontsize, frameon=False)


def shade_spans(ax: Axes, t: np.ndarray, mask: np.ndarray, *, color: str, label: str = "", hatch: str | None = None,
                alpha: float = 1.0) -> int:
    """Shade the epochs of ``t`` where ``mask`` is true, each epoch up to the next one; returns the span count.

    Only the first span carries ``label`` (one legend entry); spans sit behind the data (``zorder=0``).
    """
    t = np.asarray(t, dtype=float)
    m = np.asarray(mask, dtype=bool)
    if t.size == 0 or not m.any():
        return 0
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    right = np.append(t[1:], t[-1] + dt)
    starts = np.flatnonzero(m & ~np.r_[False, m[:-1]])
    ends = np.flatnonzero(m & ~np.r_[m[1:], False])
    for n, (i, j) in enumerate(zip(starts, ends, strict=True)):
        ax.axvspan(t[i], right[j], facecolor=color, edgecolor="none" if hatch is None else "0.5", hatch=hatch,
                   alpha=alpha, linewidth=0, zorder=0, label=label if n == 0 and label else None)
    return len(starts)
