"""What drawing the robot costs the dashboard per frame: ``python -m tools.dashboard.bench_robot``.

Times ``Batcher._send_robot`` (forward kinematics and the sends of one batch) on a walking-like
joint trajectory, into a recording file, for the meshed robot, the stick skeleton and the
pelvis alone; prints mean and p99 per frame (wall time of the dashboard's thread) and the
process CPU per frame (the SDK's encoder and file threads included), plus the one-time cost
of logging the static meshes. ``--baseline REV`` times that revision's batcher as well (its
``convert.py`` run against this tree's model code) with the stick skeleton, side by side.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import tempfile
import time
import types
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from tools.dashboard.channels import Channels
from tools.dashboard.convert import Batcher
from tools.dashboard.robot import Skeleton, load_skeleton, log_meshes

REPO = Path(__file__).resolve().parents[2]


def baseline_batcher(rev: str) -> type:
    """The ``Batcher`` class of ``tools/dashboard/convert.py`` at git revision ``rev``."""
    src = subprocess.run(
        ["git", "show", f"{rev}:tools/dashboard/convert.py"],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    mod = types.ModuleType(f"convert_at_{rev}")
    exec(compile(src, f"{rev}:tools/dashboard/convert.py", "exec"), mod.__dict__)
    return mod.Batcher


def trajectory(q0: np.ndarray, frames: int, hz: float = 30.0) -> np.ndarray:
    """``frames`` qpos rows: the pelvis walking +x at 0.4 m/s, every joint swinging."""
    t = np.arange(frames) / hz
    q = np.tile(q0, (frames, 1))
    q[:, 0] += 0.4 * t
    q[:, 7:] += 0.3 * np.sin(2 * np.pi * 1.5 * t[:, None] + np.arange(len(q0) - 7)[None, :])
    return q


def time_case(
    name: str,
    skeleton: Skeleton | None,
    qs: np.ndarray,
    per_batch: int,
    folder: Path,
    batcher: type = Batcher,
) -> dict[str, Any]:
    """Send ``qs`` ``per_batch`` frames at a time; per-frame wall and CPU figures (us)."""
    rec = rr.RecordingStream("bench_robot")
    rec.save(folder / f"{name}_{per_batch}.rrd")
    static_ms = 0.0
    if skeleton is not None and skeleton.has_meshes:
        t0 = time.perf_counter()
        log_meshes(rec, skeleton)
        static_ms = (time.perf_counter() - t0) * 1e3
    b = batcher(rec, Channels(), skeleton=skeleton)
    t0_ns = time.monotonic_ns()
    per_frame: list[float] = []
    warm = 20
    cpu0 = 0.0
    for k in range(0, len(qs), per_batch):
        if k == warm * per_batch:
            cpu0 = time.process_time()
        rows = qs[k : k + per_batch]
        sim = (np.arange(k, k + len(rows)) * 33_333).astype(np.int64)
        wall = t0_ns + sim * 1000
        t = time.perf_counter()
        b._send_robot(sim, wall, list(rows), None)
        if k >= warm * per_batch:
            per_frame.append((time.perf_counter() - t) / len(rows) * 1e6)
    rec.flush()
    cpu_us = (time.process_time() - cpu0) / (len(per_frame) * per_batch) * 1e6
    rec.disconnect()
    a = np.array(per_frame)
    return {
        "case": name,
        "frames_per_batch": per_batch,
        "frames": int(len(a) * per_batch),
        "mean_us": float(a.mean()),
        "p99_us": float(np.percentile(a, 99)),
        "max_us": float(a.max()),
        "cpu_per_frame_us": float(cpu_us),
        "static_log_ms": static_ms,
    }


def main(argv: list[str] | None = None) -> int:
    """Run the cases and print one line each (``--json FILE`` writes them too)."""
    p = argparse.ArgumentParser(prog="python -m tools.dashboard.bench_robot")
    p.add_argument("--frames", type=int, default=1000)
    p.add_argument("--json", default=None, metavar="FILE")
    p.add_argument(
        "--baseline",
        default=None,
        metavar="REV",
        help="also time this git revision's batcher (stick skeleton)",
    )
    args = p.parse_args(argv)
    meshed = load_skeleton(meshes=True)
    if meshed is None:
        print("no Cassie model (MENAGERIE_ROOT?)")
        return 2
    sticks = Skeleton(meshed.model, meshes=False)
    qs = trajectory(np.asarray(meshed.model.qpos0), args.frames + 100)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for per_batch in (1, 3):  # live: 30 Hz batches of one pose; headless: 10 Hz of three
            cases: list[tuple[str, Skeleton | None, type]] = [
                ("meshes", meshed, Batcher),
                ("skeleton", sticks, Batcher),
                ("pelvis_only", None, Batcher),
            ]
            if args.baseline:
                cases.append((f"{args.baseline}_skeleton", sticks, baseline_batcher(args.baseline)))
            for name, sk, cls in cases:
                n = (args.frames // per_batch + 20) * per_batch
                results.append(time_case(name, sk, qs[:n], per_batch, Path(tmp), cls))
                r = results[-1]
                print(
                    f"{name:12s} {per_batch} frame(s)/batch: mean {r['mean_us']:7.1f} us, "
                    f"p99 {r['p99_us']:7.1f} us, max {r['max_us']:7.1f} us per frame; "
                    f"process CPU {r['cpu_per_frame_us']:7.1f} us per frame"
                    + (
                        f"; static meshes logged in {r['static_log_ms']:.0f} ms"
                        if r["static_log_ms"]
                        else ""
                    ),
                    flush=True,
                )
    n_verts = sum(len(part.positions) for part in meshed.parts)
    n_tris = sum(len(part.triangles) for part in meshed.parts)
    print(
        f"{len(meshed.parts)} meshes, {len(meshed.bodies)} bodies, {n_verts} vertices, "
        f"{n_tris} triangles; cpus {os.cpu_count()}"
    )
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
