"""The dashboard draws Cassie from the menagerie model's meshes, posed per frame by body poses
only, and its 3D view's eye follows the pelvis (real MuJoCo model, recordings read back)."""

from __future__ import annotations

import time
from pathlib import Path

import mujoco
import numpy as np
import pytest
import rerun as rr
import rerun.blueprint as rrb

from tests.dashboard import fake_stack
from tests.dashboard.rrd import Recording
from tools.dashboard.blueprint import LEGS_ENTITY, TRACKED_ENTITY, build_blueprint
from tools.dashboard.robot import (
    FRAME_PREFIX,
    FRAMES_ENTITY,
    MESH_ROOT,
    VISIBLE_GROUPS,
    Skeleton,
    load_skeleton,
)

T0 = time.monotonic_ns()


@pytest.fixture(scope="module")
def meshed() -> Skeleton:
    sk = load_skeleton(meshes=True)
    if sk is None:
        pytest.skip("the menagerie Cassie model is not available (MENAGERIE_ROOT)")
    return sk


def _gt_batches(
    qs: list[list[float]], utime0: int = 1_000_000, step_us: int = 40_000
) -> list[dict[str, list[bytes]]]:
    """One GROUND_TRUTH message per q, 40 ms of sim time apart (above the 30 Hz robot rate),
    one batch each."""
    out = []
    seqs: dict[str, int] = {}
    for k, q in enumerate(qs):
        gt = fake_stack.ground_truth(utime0 + k * step_us)
        gt.q = list(q)
        out.append(fake_stack.stamp_all([("GROUND_TRUTH", gt)], T0 + k * 40_000_000, 0, seqs))
    return out


def _record(
    tmp_path: Path, skeleton: Skeleton | None, batches: list[dict[str, list[bytes]]]
) -> Recording:
    """The dashboard's static set-up and batcher into a recording, read back."""
    from tests.dashboard.test_batcher import _run

    return _run(tmp_path, batches, skeleton=skeleton)


def _visible_mesh_geoms(model: mujoco.MjModel) -> list[int]:
    """The geoms MuJoCo's viewer draws as meshes on the robot (not the world body)."""
    return [
        g
        for g in range(model.ngeom)
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
        and model.geom_bodyid[g] != 0
        and model.geom_group[g] in VISIBLE_GROUPS
        and model.geom_rgba[g, 3] > 0
    ]


def test_one_static_mesh_per_visual_geom_with_finite_vertices(
    meshed: Skeleton, tmp_path: Path
) -> None:
    rec = _record(tmp_path, meshed, [])
    meshes = {
        e: cols
        for e, cols in rec.values.items()
        if e.startswith(f"/{MESH_ROOT}/") and "Mesh3D:vertex_positions" in cols
    }
    geoms = _visible_mesh_geoms(meshed.model)
    assert len(geoms) >= 20  # Cassie's pelvis and both legs
    assert len(meshes) == len(geoms)
    for entity, cols in meshes.items():
        assert rec.timelines[entity] == set(), entity  # static: on no timeline
        assert rec.rows[entity] == 1, entity  # logged once
        verts = np.asarray(cols["Mesh3D:vertex_positions"][0], np.float64)
        tris = np.asarray(cols["Mesh3D:triangle_indices"][0], np.int64)
        normals = np.asarray(cols["Mesh3D:vertex_normals"][0], np.float64)
        assert verts.ndim == 2 and verts.shape[1] == 3 and len(verts) >= 3, entity
        assert np.isfinite(verts).all() and np.isfinite(normals).all(), entity
        assert len(normals) == len(verts)
        assert tris.min() >= 0 and tris.max() < len(verts), entity
        # in its body's frame: a Cassie part is within half a metre of its body's origin
        assert np.abs(verts).max() < 0.6, entity
        body = entity.split("/")[-2]
        assert cols["CoordinateFrame:frame"] == [[FRAME_PREFIX + body]]
        colored = ("Mesh3D:vertex_colors" in cols and cols["Mesh3D:vertex_colors"][0]) or (
            "Mesh3D:albedo_factor" in cols
        )
        assert colored, entity


def test_meshes_in_body_frames_reproduce_mujocos_geom_poses(meshed: Skeleton) -> None:
    """Each part's vertices, moved by its body's pose, land where MuJoCo puts that geom's
    mesh (``geom_xpos``/``geom_xmat`` on the raw mesh vertices) for a bent-legged qpos."""
    m = meshed.model
    q = np.array(fake_stack.HOME_Q)
    q[7:] += 0.15
    pose = meshed.pose(q)
    d = mujoco.MjData(m)
    d.qpos[:] = q
    mujoco.mj_kinematics(m, d)
    for part in meshed.parts:
        b = meshed.bodies.index(part.body)
        x, y, z, w = pose.body_quat[b]
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, np.array([w, x, y, z]))
        ours = part.positions.astype(np.float64) @ rot.reshape(3, 3).T + pose.body_pos[b]
        mesh = m.geom_dataid[part.geom]
        raw = m.mesh_vert[m.mesh_vertadr[mesh] : m.mesh_vertadr[mesh] + m.mesh_vertnum[mesh]]
        theirs = raw @ d.geom_xmat[part.geom].reshape(3, 3).T + d.geom_xpos[part.geom]
        # vertices are re-indexed per (position, normal, texcoord) corner: compare extents
        assert ours.min(axis=0) == pytest.approx(theirs.min(axis=0), abs=1e-5)
        assert ours.max(axis=0) == pytest.approx(theirs.max(axis=0), abs=1e-5)


def test_per_frame_only_body_poses_are_sent_and_they_move_with_qpos(
    meshed: Skeleton, tmp_path: Path
) -> None:
    bent = list(fake_stack.HOME_Q)
    knee = mujoco.mj_name2id(meshed.model, mujoco.mjtObj.mjOBJ_JOINT, "left-knee")
    bent[meshed.model.jnt_qposadr[knee]] -= 0.5
    qs = [fake_stack.HOME_Q, bent, fake_stack.HOME_Q]
    rec = _record(tmp_path, meshed, _gt_batches(qs))
    nb = len(meshed.bodies)
    assert rec.rows[f"/{FRAMES_ENTITY}"] == 3 * nb  # one row per body and frame
    cols = rec.values[f"/{FRAMES_ENTITY}"]
    child = [r[0] for r in cols["Transform3D:child_frame"]]
    assert child == [FRAME_PREFIX + b for b in meshed.bodies] * 3
    assert {r[0] for r in cols["Transform3D:parent_frame"]} == {"tf#/world"}
    pos = np.array([r[0] for r in cols["Transform3D:translation"]]).reshape(3, nb, 3)
    # the pelvis frame is the floating base of q
    pelvis = meshed.bodies.index("cassie-pelvis")
    assert pos[:, pelvis] == pytest.approx(np.array([q[:3] for q in qs]), abs=1e-6)
    # bending the left knee moves the left foot, not the right one
    lf, rf = meshed.bodies.index("left-foot"), meshed.bodies.index("right-foot")
    assert np.linalg.norm(pos[1, lf] - pos[0, lf]) > 0.05
    assert pos[1, rf] == pytest.approx(pos[0, rf], abs=1e-6)
    assert pos[2] == pytest.approx(pos[0], abs=1e-6)  # and back again
    # the meshes are never re-sent per frame
    assert all(rec.rows[e] == 1 for e in rec.rows if e.startswith(f"/{MESH_ROOT}/"))
    assert rec.timelines[f"/{FRAMES_ENTITY}"] == {"sim_time", "wall_time"}


def test_without_meshes_the_legs_are_the_stick_skeleton(meshed: Skeleton, tmp_path: Path) -> None:
    sticks = Skeleton(meshed.model, meshes=False)
    assert not sticks.has_meshes
    rec = _record(tmp_path, sticks, _gt_batches([fake_stack.HOME_Q] * 3))
    assert rec.rows["/world/robot/legs"] == 3
    assert f"/{FRAMES_ENTITY}" not in rec.rows
    assert not any(e.startswith(f"/{MESH_ROOT}") for e in rec.rows)


def _blueprint_columns(tmp_path: Path, **kw: object) -> dict[str, list[object]]:
    """Every component column of the stored default blueprint of ``build_blueprint(**kw)``."""
    path = tmp_path / "bp.rrd"
    rec = rr.RecordingStream("dashboard_blueprint_test")
    rec.save(path, default_blueprint=build_blueprint(**kw))  # type: ignore[arg-type]
    rec.disconnect()
    reader = rr.chunk.RrdReader(path)
    cols: dict[str, list[object]] = {}
    for chunk in reader.stream(store=reader.blueprints()[0]):
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if ":" in name:
                cols.setdefault(name, []).extend(batch.column(name).to_pylist())
    return cols


def test_the_3d_views_eye_tracks_the_pelvis(tmp_path: Path) -> None:
    cols = _blueprint_columns(tmp_path, robot_meshes=True)
    assert [r[0] for r in cols["EyeControls3D:tracking_entity"]] == [TRACKED_ENTITY]
    assert [r[0] for r in cols["EyeControls3D:kind"]] == [rrb.Eye3DKind.Orbital.value]
    # the tracked entity is a child of the pelvis (so it moves with every robot frame), logged
    # once by log_static, centred on the pelvis; the viewer frames it from 1.5 times its
    # bounding radius, which is where the eye starts as well
    assert TRACKED_ENTITY.startswith("world/robot/pelvis/")
    rec = _record(tmp_path, None, [])
    pts = np.array(rec.column(f"/{TRACKED_ENTITY}", "Points3D:positions")[0])
    assert rec.timelines[f"/{TRACKED_ENTITY}"] == set()
    assert pts.mean(axis=0) == pytest.approx([0.0, 0.0, 0.0])
    radius = 0.5 * np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))
    start = np.array(cols["EyeControls3D:position"][0][0])
    target = np.array(cols["EyeControls3D:look_target"][0][0])
    assert np.linalg.norm(start - target) == pytest.approx(1.5 * radius, rel=1e-3)
    assert 3.0 < 1.5 * radius < 6.0  # Cassie (1 m tall) and the ground ahead in view


def test_the_stick_skeleton_leaves_the_3d_view_only_when_meshes_are_drawn(
    tmp_path: Path,
) -> None:
    def queries(meshes: bool) -> list[str]:
        got = _blueprint_columns(tmp_path, robot_meshes=meshes)["ViewContents:query"]
        return [q for row in got for q in row if "world/robot" in q]

    assert queries(True) == [f"- /{LEGS_ENTITY}"]
    assert queries(False) == []
