"""The rendered mode's measured statistics (``coobs calibrate``) and the model that reads them.

``rendered_sift.json`` (package data) holds what ``experiments.studies.rendered_calibration``
measured on rendered images against the renderer's per-pixel truth: SIFT keypoint localisation σ
per keypoint size, detection density per m² of visible surface (by range, view angle and Sun
incidence), the size distribution of tracked keypoints, cross-view match survival and false-match
rate, inter-epoch association survival and false-association rate, with its provenance.
:class:`SiftCalibration` interpolates them; :func:`load_calibration` picks the calibration of a
target.
"""

from vision.calibration.model import (
    COS_VIEW_EDGES,
    PHASE_EDGES_DEG,
    SIZE_EDGES_PX,
    SUN_BIN_EDGES,
    TRACK_CLASSES,
    CalibrationTableEmpty,
    SiftCalibration,
    calibration_path,
    load_calibration,
    track_class,
)

__all__ = [
    "COS_VIEW_EDGES",
    "PHASE_EDGES_DEG",
    "SIZE_EDGES_PX",
    "SUN_BIN_EDGES",
    "TRACK_CLASSES",
    "CalibrationTableEmpty",
    "SiftCalibration",
    "calibration_path",
    "load_calibration",
    "track_class",
]
