"""Perception: depth back-projection and the robot-centric elevation map (Section VII-A/B).

Typical use in the mapping thread (the process shell owns the camera thread and LCM)::

    params = runtime.params.load(ElevationMapParams, "hw_config/gains/elevation_map.yaml")
    emap = ElevationMap(params)                      # (no variant: the simulation column)
    emap.recenter(pelvis_xy)                         # robot-centred, whole cells
    emap.apply_drift_correction(stance_foot_world)   # VII-B, before each point-cloud update
    status = emap.update_from_depth(depth_m, fx, fy, cx, cy, cam_pos, cam_quat_wxyz,
                                    leg_boxes, time_s=t)   # 'ok' or why the frame was skipped
    emap.layers                                      # elevation, variance, time, lowest
"""

from processes.perception.elevation_map import (
    CropBox,
    ElevationMap,
    ElevationMapParams,
    backproject,
    crop_boxes,
    quat_to_rotmat,
    transform_points,
)

__all__ = [
    "CropBox",
    "ElevationMap",
    "ElevationMapParams",
    "backproject",
    "crop_boxes",
    "quat_to_rotmat",
    "transform_points",
]
