"""``coobs tumble``: the truth motion of a tumbling target, printed as a table."""

from __future__ import annotations

import numpy as np
import typer
from rich.table import Table

from attitude.rigid_body import check_inertia
from coobs.cli._console import console, fail
from experiments.studies.tumble import tumble_history

__all__ = ["tumble"]


def _parse_triple(text: str, name: str) -> np.ndarray:
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        values = np.array([])
    if values.shape != (3,):
        raise fail(f"{name}: expected three comma-separated numbers, got {text!r}")
    return values


def tumble(
    inertia_kgm2: str = typer.Option("100,120,80", "--inertia-kgm2", help="Principal moments Jx,Jy,Jz in kg·m²."),
    omega_deg_s: str = typer.Option("5,5,5", "--omega-deg-s", help="Initial body rate in deg/s."),
    duration_s: float = typer.Option(300.0, "--duration-s", help="Duration in seconds."),
    step_s: float = typer.Option(30.0, "--step-s", help="Output step in seconds."),
) -> None:
    """Propagate a torque-free tumbling target exactly and print attitude (3-2-1 Euler), rate and invariants."""
    J = np.diag(_parse_triple(inertia_kgm2, "--inertia-kgm2"))
    try:
        check_inertia(J, name="--inertia-kgm2")
    except ValueError as exc:
        raise fail(str(exc)) from None
    if duration_s <= 0:
        raise fail(f"--duration-s: must be positive, got {duration_s}")
    if step_s <= 0:
        raise fail(f"--step-s: must be positive, got {step_s}")
    w0 = np.deg2rad(_parse_triple(omega_deg_s, "--omega-deg-s"))
    h = tumble_history(J, w0, duration_s=duration_s, step_s=step_s)
    table = Table(title="torque-free target (q_NT, omega_T); Euler 3-2-1 of R_NT")
    for col in ("t (s)", "yaw (deg)", "pitch (deg)", "roll (deg)", "wx (deg/s)", "wy (deg/s)", "wz (deg/s)"):
        table.add_column(col, justify="right")
    for k in range(h.t_s.size):
        table.add_row(f"{h.t_s[k]:.1f}", *(f"{v:.3f}" for v in np.rad2deg(h.ypr_rad[k])),
                      *(f"{v:.4f}" for v in np.rad2deg(h.omega_TN_T_rad_s[k])))
    console.print(table)
    console.print(f"|L_N| drift: {h.momentum_drift:.1e} (relative); "
                  f"energy drift: {h.energy_drift:.1e} (relative)")
