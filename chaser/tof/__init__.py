"""TOF-camera relative pose of a cooperative marker target (paper 000), in its corrected form."""

from chaser.tof.extraction import (
    ExtractionSettings,
    ExtractionThresholds,
    MarkerDetections,
    extract_markers,
    log_kernel,
)
from chaser.tof.matching import (
    MarkerMatch,
    MatchSettings,
    match_markers_hungarian,
    match_markers_mrf,
    match_markers_mrf_literal,
    verify_labels,
)
from chaser.tof.pipeline import MATCHERS, TofPoseResult, estimate_tof_pose
from chaser.tof.pose import RigidFit, pitch_yaw_roll_from_matrix, weighted_svd_pose
from chaser.tof.trials import MatchingTrials, random_matching_trials

__all__ = [
    "ExtractionSettings",
    "ExtractionThresholds",
    "MarkerDetections",
    "log_kernel",
    "extract_markers",
    "MatchSettings",
    "MarkerMatch",
    "match_markers_mrf",
    "match_markers_mrf_literal",
    "match_markers_hungarian",
    "verify_labels",
    "RigidFit",
    "weighted_svd_pose",
    "pitch_yaw_roll_from_matrix",
    "TofPoseResult",
    "estimate_tof_pose",
    "MATCHERS",
    "MatchingTrials",
    "random_matching_trials",
]
