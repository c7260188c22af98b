"""Three cameras on the 003 §3.1 cone around +x of H (shared by the geometric-mode tests)."""

import numpy as np

from vision.camera import look_at


def three_cameras(d: float = 50.0, gamma_deg: float = 10.0) -> np.ndarray:
    """Poses ``(3, 4, 4)`` of three cameras at range ``d`` with pairwise optical-axis angle ``gamma_deg``."""
    phi = np.arcsin(2 / np.sqrt(3) * np.sin(np.radians(gamma_deg) / 2))
    eyes = [d * np.array([np.cos(phi), np.sin(phi) * np.cos(a), np.sin(phi) * np.sin(a)])
            for a in 2 * np.pi * np.arange(3) / 3]
    return np.stack([look_at(e, np.zeros(3)) for e in eyes])
