"""Pose measurement by orthogonal cylindrical imaging with linear CCDs (paper 004)."""

from chaser.cylindrical.attitude import (
    N_S_BODY,
    ThreePointAttitude,
    attitude_from_three_points,
    sigma_from_vector_pairs,
    virtual_point,
    yaw_roll_pitch_from_matrix,
    yaw_roll_pitch_from_sigma,
)
from chaser.cylindrical.calibration import (
    ExtrinsicCalibration,
    IntrinsicCalibration,
    TurntableSamples,
    calibrate_extrinsics,
    fit_intrinsic_rbf,
    simulate_turntable_calibration,
    tracker_sigma_m,
)
from chaser.cylindrical.intersection import (
    CalibratedCamera,
    PlaneIntersection,
    intersect_planes,
    measure_points,
)
from chaser.cylindrical.rig import (
    CylindricalRig,
    SystemCalibration,
    calibrate_system,
    control_points_in_cube,
    paper_rig,
    rig_detections,
)
from chaser.cylindrical.tracking import (
    FrameTrack,
    TrackerSettings,
    TrackState,
    initialise_tracks,
    track_frame,
    track_predict,
)

__all__ = [
    "TurntableSamples",
    "simulate_turntable_calibration",
    "IntrinsicCalibration",
    "fit_intrinsic_rbf",
    "ExtrinsicCalibration",
    "calibrate_extrinsics",
    "CalibratedCamera",
    "PlaneIntersection",
    "intersect_planes",
    "measure_points",
    "CylindricalRig",
    "paper_rig",
    "tracker_sigma_m",
    "control_points_in_cube",
    "SystemCalibration",
    "calibrate_system",
    "rig_detections",
    "TrackerSettings",
    "TrackState",
    "FrameTrack",
    "initialise_tracks",
    "track_predict",
    "track_frame",
    "virtual_point",
    "sigma_from_vector_pairs",
    "yaw_roll_pitch_from_sigma",
    "yaw_roll_pitch_from_matrix",
    "ThreePointAttitude",
    "attitude_from_three_points",
    "N_S_BODY",
]
