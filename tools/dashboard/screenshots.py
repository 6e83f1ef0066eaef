"""Screenshots of a dashboard recording, taken by Rerun's own viewer on an X display.

``python -m tools.dashboard.screenshots RECORDING.rrd OUT_DIR [--profile P]`` copies the
recording once per layout with that layout as its default blueprint (the time cursor at the
recording's end), opens the copy in the viewer, lets the viewer save a PNG itself
(``--screenshot-to``), and shrinks it with ImageMagick's ``convert`` (the viewer renders at
twice the window size under Xvfb) to ``OUT_DIR/<prefix>_<layout>.png``. (A layout given to the
viewer as a separate ``.rbl`` file starts its tracking eye several times further away than the
same layout inside the recording, which is how the dashboard sends it.) Layouts: ``overview``
(the dashboard's default layout), ``robot`` (the 3D view alone) and ``timing`` (the timing
panels and state lanes). Needs ``DISPLAY`` (e.g. ``Xvfb :77 &``; software Vulkan:
``mesa-vulkan-drivers``).
docs/dashboard.md says how the committed ones were made.
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import rerun.blueprint as rrb

from tools.dashboard.blueprint import build_blueprint, robot_view, timing_views

APPLICATION_ID = "cassie_dashboard"  # the dashboard's recordings (tools/dashboard/__init__.py)
LAYOUTS = ("overview", "robot", "timing")


def layout(name: str, loops: list[tuple[str, str, float | None]] | None) -> rrb.Blueprint:
    """The blueprint of one screenshot; all of them with the cursor at the recording's end."""
    panel = rrb.TimePanel(timeline="sim_time", play_state="following")
    if name == "overview":
        return build_blueprint(
            loops=loops, robot_meshes=True, play_state="following", collapse_panels=True
        )
    if name == "robot":
        return rrb.Blueprint(robot_view(robot_meshes=True), panel, collapse_panels=True)
    if name == "timing":
        timing, lanes = timing_views(loops=loops)
        return rrb.Blueprint(
            rrb.Vertical(timing, lanes, row_shares=[3.0, 1.0]), panel, collapse_panels=True
        )
    raise ValueError(f"no layout {name!r}; one of {', '.join(LAYOUTS)}")


def _free_port() -> int:
    """A TCP port nobody listens on: the viewer's own server must not find another viewer
    (it would hand the recording to it and exit)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def viewer() -> str:
    """The native viewer binary of the installed SDK (the ``rerun`` script's target)."""
    import rerun_cli

    return str(Path(rerun_cli.__file__).with_name("rerun"))


def shoot(
    recording: Path, blueprint: rrb.Blueprint, out: Path, size: str, timeout_s: float = 300.0
) -> None:
    """One screenshot of ``recording`` in ``blueprint`` to ``out`` (PNG, at ``size``)."""
    import rerun as rr

    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / "copy.rrd"
        rec = rr.RecordingStream(APPLICATION_ID)
        rec.save(copy, default_blueprint=blueprint)
        rec.send_chunks(rr.chunk.RrdReader(recording).stream())
        rec.flush()
        rec.disconnect()
        raw = Path(tmp) / "raw.png"
        subprocess.run(
            [
                viewer(),
                "--port",
                str(_free_port()),
                "--window-size",
                size,
                "--screenshot-to",
                str(raw),
                str(copy),
            ],
            check=True,
            timeout=timeout_s,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        # down to the window's size, a palette of 255 colours (undithered: dithering the
        # dark background triples the file): a dashboard PNG of ~100-300 KB
        subprocess.run(
            [
                "convert",
                str(raw),
                "-resize",
                size,
                "-dither",
                "None",
                "-colors",
                "255",
                "-define",
                "png:compression-level=9",
                f"PNG8:{out}",
            ],
            check=True,
        )


def main(argv: list[str] | None = None) -> int:
    """Take the screenshots; returns 0, or 2 without a display."""
    p = argparse.ArgumentParser(prog="python -m tools.dashboard.screenshots")
    p.add_argument("recording", type=Path)
    p.add_argument("out_dir", type=Path)
    p.add_argument(
        "--profile", default=None, help="the launch profile of the recording (its per-loop panels)"
    )
    p.add_argument("--prefix", default="dashboard")
    p.add_argument("--size", default="1600x1000", help="window size (logical points)")
    p.add_argument("--layouts", default=",".join(LAYOUTS))
    args = p.parse_args(argv)
    if not os.environ.get("DISPLAY"):
        print("needs an X display: e.g. `Xvfb :77 &` and DISPLAY=:77", file=sys.stderr)
        return 2
    loops = None
    if args.profile:
        from runtime.config import load_profile

        prof = load_profile(args.profile)
        loops = [(n, n, prof.processes[n].deadline_ms) for n in prof.launch]
    args.out_dir.mkdir(parents=True, exist_ok=True)
    for name in args.layouts.split(","):
        out = args.out_dir / f"{args.prefix}_{name}.png"
        shoot(args.recording, layout(name, loops), out, args.size)
        print(f"{out}: {out.stat().st_size // 1024} KB", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
