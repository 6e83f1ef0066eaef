"""The simulated D455 reports the top of a box at the distance geometry predicts, within 1 cm
at every pixel that sees it, and the LCM frame carries the image, intrinsics and pose."""

from __future__ import annotations

import time

import mujoco
import numpy as np

from lcmtypes import depth_frame_t
from runtime.cassie_packets import OutputPacket, encode_input
from sim.camera import AsyncDepthRenderer, CameraConfig, DepthCamera, ProcessDepthRenderer
from sim.model import build_model, standing_pose
from sim.terrain import Box, from_boxes

BOX = Box(center=(1.0, 0.0, 0.1), size=(1.2, 2.0, 0.2))  # top face at z = 0.2 m


def _expected_depth(cam: DepthCamera, top_z: float) -> tuple[np.ndarray, np.ndarray]:
    """z-depth of each pixel's ray on the plane z = top_z, and whether it lands on the box top
    with 2 cm to spare (computed from the mount and intrinsics, independent of ray casting)."""
    cfg = cam.cfg
    fx, fy, cx, cy = cfg.decimated_intrinsics()
    u, v = np.meshgrid(np.arange(cfg.out_width), np.arange(cfg.out_height))
    rays_cam = np.stack([(u - cx) / fx, (v - cy) / fy, np.ones(u.shape)], axis=-1)  # z = 1
    r_wc = cam.r_wc  # pelvis is level at the standing pose
    rays_w = rays_cam @ r_wc.T
    t = (top_z - cam.pnt[2]) / rays_w[..., 2]  # metres of z-depth, since ray z_cam = 1
    hit = cam.pnt + t[..., None] * rays_w
    half = np.array(BOX.size[:2]) / 2 - 0.02
    on_top = (t > 0) & (np.abs(hit[..., 0] - BOX.center[0]) < half[0]) & (
        np.abs(hit[..., 1] - BOX.center[1]) < half[1])
    return t, on_top


def test_depth_camera_reports_a_box_at_its_known_distance() -> None:
    terrain = from_boxes([BOX], ground_z=0.0)
    m = build_model(terrain)
    q = standing_pose(m)
    cam = DepthCamera(m, CameraConfig(see_robot=False))
    frame = cam.render(q, utime=1234)
    assert frame.depth.shape == (60, 106) and frame.depth.dtype == np.uint16
    depth_m = frame.depth * cam.cfg.depth_scale
    expected, on_top = _expected_depth(cam, BOX.top_z)
    assert on_top.sum() > 2000  # most of the image sees the box top
    err = np.abs(depth_m[on_top] - expected[on_top])
    assert err.max() < 0.01, f"max depth error {err.max():.4f} m"
    assert err.max() <= 0.0006  # in fact: z16 quantization (1 mm) only
    # camera pose at capture: the mount on the pelvis, pitched 50 degrees down
    d = mujoco.MjData(m)
    d.qpos[:] = q
    mujoco.mj_kinematics(m, d)
    np.testing.assert_allclose(frame.pos, q[:3] + np.array(cam.cfg.mount_pos), atol=1e-9)
    optical_z = np.zeros(9)
    mujoco.mju_quat2Mat(optical_z, frame.quat)
    np.testing.assert_allclose(optical_z.reshape(3, 3)[:, 2],
                               [np.cos(np.radians(50)), 0.0, -np.sin(np.radians(50))], atol=1e-9)


def test_noise_and_dropout_and_the_background_renderers() -> None:
    terrain = from_boxes([BOX], ground_z=0.0)
    m = build_model(terrain)
    q = standing_pose(m)
    clean = DepthCamera(m, CameraConfig(see_robot=False)).render(q).depth.copy()
    noisy_cam = DepthCamera(m, CameraConfig(see_robot=False, noise_std_at_1m=0.005, dropout=0.1))
    noisy = noisy_cam.render(q).depth
    holes = (noisy == 0) & (clean != 0)
    assert 0.05 < holes.mean() < 0.15
    both = (noisy != 0) & (clean != 0)
    diff = noisy[both].astype(float) - clean[both]
    assert 1.0 < diff.std() < 20.0  # millimetres
    cfg = CameraConfig(see_robot=False)
    for renderer in (AsyncDepthRenderer(DepthCamera(m, cfg)),
                     ProcessDepthRenderer((terrain, 10.0, (0.01, 1.0)), cfg)):
        try:
            if isinstance(renderer, ProcessDepthRenderer):
                assert renderer.wait_ready(60.0)
            assert renderer.request(q, 99)
            # a request while a frame renders is dropped and counted (if the render already
            # finished, the request is simply accepted): never queued, never lost silently
            accepted = renderer.request(q, 100)
            assert accepted != (renderer.dropped == 1)
            frame = None
            for _ in range(2000):
                frame = renderer.poll()
                if frame is not None:
                    break
                time.sleep(0.005)
            # the newest finished frame: 99, or 100 when the second request was accepted and
            # rendered before the first poll (same pose, same image); a dropped one never comes
            assert frame is not None and frame.utime in ((99, 100) if accepted else (99,))
            np.testing.assert_array_equal(frame.depth, clean)  # same image, other thread/process
            np.testing.assert_allclose(frame.pos, q[:3] + np.array(cfg.mount_pos), atol=1e-12)
        finally:
            renderer.close()


def test_node_publishes_depth_frames_at_30_hz_with_sim_time(driver_factory) -> None:
    drv = driver_factory("lockstep", {"terrain": "flat"})
    state = OutputPacket()
    for k in range(140):  # 70 ms of sim time
        state.decode(drv.sent["robot_output"][-1])
        drv.tick(command=encode_input(k, state.seq, np.zeros(10)))
    frames = [depth_frame_t.decode(b) for b in drv.sent["depth"]]
    # captured at the first 0.5 ms step at or after each 1/30 s mark
    assert [f.header.utime for f in frames] == [0, 33500, 67000]
    f = frames[-1]
    assert (f.width, f.height, f.num_bytes) == (106, 60, 106 * 60 * 2)
    img = np.frombuffer(f.data, dtype="<u2").reshape(60, 106)
    assert f.depth_scale == 0.001 and 0.5 < np.median(img[img > 0]) * f.depth_scale < 3.0
    assert abs(f.fx - 426.0 / 8) < 1e-12
