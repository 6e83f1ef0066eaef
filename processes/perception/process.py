"""The perception process: depth frames -> robot-centric elevation map (Section VII-A/B).

Two threads, as on the robot: a receive thread (``Node.receive_thread``, the RealSense polling
thread's part) keeps taking depth frames, states and contacts into the port buffers, the
newest frame in a one-slot shared buffer, while the mapping thread (``tick``) updates the map
from the newest frame; frames that arrive during an update replace each other there and are
counted as skipped. For each frame: the camera pose comes from the *estimated* pelvis
pose (the laptop's robot state nearest in time) and the camera mount, or from the frame itself
(``camera_pose: frame``, the simulator's true pose); the robot's own legs are cropped with boxes
around the leg links; the stance foot corrects the map's height drift (Section VII-B); the map
is re-centred on the robot and published with the frame's ``utime``, so the latency from depth
frame to footholds can be measured downstream. The first time both feet are on the ground, the
unknown cells around them take the feet's height (the initial submap, see
``ElevationMap.initialize_submap``): the camera never sees the ground the robot starts on.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from lcmtypes import depth_frame_t, elevation_map_t, robot_state_t
from processes.kinematics import AlipKinematics
from processes.perception.elevation_map import CropBox, ElevationMap, ElevationMapParams
from processes.perception.robot_view import RobotView
from runtime.codecs import MAP_NO_DATA, MAP_OK, MAP_STALE, elevation_map_to_msg
from runtime.config_types import ProcessConfig, Profile
from runtime.node import Node
from runtime.params import spec
from runtime.robot import CAMERA_MOUNT_POS_M, CAMERA_PITCH_DOWN_DEG

LAYERS = ("elevation", "variance", "lowest")
class PerceptionNode(Node):
    """Depth frame in, elevation map out; see the module docstring."""

    name = "perception"
    inputs = {"depth": depth_frame_t, "state": robot_state_t}  # contacts: state.in_contact
    outputs = {"elevation_map": elevation_map_t}
    trigger_role = "depth"
    receive_thread = True  # frames keep arriving while the map updates (see the docstring)

    def __init__(
        self,
        params: ElevationMapParams,
        camera_pose: str,
        mount_pos: np.ndarray,
        pitch_down_deg: float,
        crop_legs: bool,
        drift_correction: bool,
    ) -> None:
        self.map = ElevationMap(params)
        self.camera_pose = camera_pose
        self.crop_legs = crop_legs
        self.drift_correction = drift_correction
        self.kin = AlipKinematics()
        self.robot = RobotView(self.kin, mount_pos, pitch_down_deg)
        self.status_text = "no frame yet"
        self.frames = 0
        self.rejected = 0

    def tick(self, ctx: Any, inbox: Any) -> None:
        frame: depth_frame_t = inbox.trigger()
        state = inbox.latest("state")
        status = self._update(frame, state)
        self.frames += 1
        if status != "ok":
            self.rejected += 1
        self.status_text = status
        ctx.publish("elevation_map", self._message(frame.header.utime, status))

    def _update(self, frame: depth_frame_t, state: robot_state_t | None) -> str:
        n = frame.width * frame.height
        if n <= 0 or len(frame.data) != 2 * n:
            return f"malformed frame: {frame.width}x{frame.height} with {len(frame.data)} bytes"
        depth = np.frombuffer(frame.data, dtype="<u2").reshape(frame.height, frame.width)
        depth_m = depth.astype(np.float32) * np.float32(frame.depth_scale)
        depth_m[depth == 0] = np.nan
        boxes: list[CropBox] = []
        have_state = (
            state is not None
            and len(state.q) == self.kin.m.nq
            and np.isfinite(state.q).all()
            and np.isfinite(state.v).all()
        )
        if have_state:
            self.kin.update(np.asarray(state.q), np.asarray(state.v))
        if self.camera_pose == "estimated":
            if not have_state:
                return "no robot state yet: cannot place the camera"
            cam_pos, cam_quat = self.robot.camera_pose()
        else:
            cam_pos = np.asarray(frame.camera_pos, dtype=float)
            cam_quat = np.asarray(frame.camera_quat, dtype=float)
        if have_state:
            self.map.recenter(self.kin.com[:2])
            if (seed := self.robot.seed(state.in_contact)) is not None:
                self.map.initialize_submap(*seed)
            if self.crop_legs:
                boxes = self.robot.leg_boxes()
            if self.drift_correction:
                foot = self.robot.drift_foot(state.in_contact, state.alip_stance)
                if foot is not None:
                    self.map.apply_drift_correction(foot)
        return self.map.update_from_depth(
            depth_m,
            frame.fx,
            frame.fy,
            frame.cx,
            frame.cy,
            cam_pos,
            cam_quat,
            leg_boxes=boxes,
            time_s=frame.header.utime * 1e-6,
        )

    def _message(self, utime: int, status: str) -> elevation_map_t:
        """The map's layers as published: ok, stale (this frame not fused) or no data."""
        m = self.map
        layers = m.layers
        known = np.isfinite(layers["elevation"]).any()
        code = MAP_OK if status == "ok" and known else (MAP_NO_DATA if not known else MAP_STALE)
        return elevation_map_to_msg({n: layers[n] for n in LAYERS if n in layers},
                                    m.params.resolution_m, m.origin, utime, code, status)

    def status(self) -> str:
        return f"{self.frames} frames, {self.rejected} not fused; last: {self.status_text}"


#: the gains file (hw_config/gains/elevation_map.yaml): Table VIII, in ``Params.variant``
Gains = ElevationMapParams


@dataclass(frozen=True)
class Params:
    """Perception's ``params:`` (hw_config/processes.yaml, and the profiles' overrides)."""

    variant: str = "simulation"  # the column of Table VIII: a variant of the gains file
    #: where the camera is: ``estimated`` (the estimated pelvis pose times the robot's camera
    #: mount, runtime.robot) or ``frame`` (the pose in the frame: the simulator's true pose)
    camera_pose: str = spec("estimated", choices=("estimated", "frame"))
    crop_legs: bool = True  # drop the points on the robot's own legs (boxes around the links)
    drift_correction: bool = True  # the stance foot corrects the map's height (Section VII-B)


def make_node(proc: ProcessConfig, profile: Profile, params: Params,
              gains: ElevationMapParams) -> Node:
    """Perception from hw_config: map parameters (gains file), params, and the camera's
    mount on the pelvis from the robot description (runtime.robot, as the sim's camera)."""
    return PerceptionNode(
        gains,
        params.camera_pose,
        np.asarray(CAMERA_MOUNT_POS_M, dtype=float),
        CAMERA_PITCH_DOWN_DEG,
        params.crop_legs,
        params.drift_correction,
    )
