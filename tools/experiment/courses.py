"""A trial's course: its terrain file (the paper's stairs at a tread depth, its beam at a
width, random stepping stones of a d_min and a seed, QuadPiPS' ramped stones and winding beam,
a chasm of a width) and the experiment profile that runs the stack on it (with the SLIP guide
or without)."""

from __future__ import annotations

from collections.abc import Callable
from itertools import pairwise
from pathlib import Path
from typing import Any

import yaml

from runtime.config import HW_CONFIG_DIR, load_profile, safe_load
from runtime.config_types import Profile

#: tread depth of ``cassie experiment stairs --perception`` (the paper's Fig. 11, bottom)
PERCEPTION_STAIRS_DEPTH_M = 0.40
#: ... and the beam's width with perception (the same figure)
PERCEPTION_BEAM_WIDTH_M = 0.35


#: the terrain parameter a course's ``size`` sets (Fig. 11: the stairs' tread depth, the
#: beam's width; the winding beam's too)
SIZE_PARAM = {"stairs": "depth", "beam": "width", "winding_beam": "width"}
#: the courses of Table I's random stepping stones: ``dmin`` sets their d_min
DMIN_COURSES = ("stones", "ramped_stones")
#: the random courses whose terrain is the trial's seed's
SEEDED_COURSES = ("stones", "ramped_stones", "winding_beam")
#: the courses with an end: their last box is the far platform or the stairs' landing
COURSES_WITH_END = ("stones", "beam", "stairs", *SEEDED_COURSES)
#: the guide process's name in processes.yaml (``--guide``)
GUIDE_PROCESS = "slip_guide"


def _chasm_file(width: float, work: Path) -> str:
    """hw_config/terrains/chasm.yaml with its end platform moved for a gap of ``width``."""
    doc = safe_load((HW_CONFIG_DIR / "terrains" / "chasm.yaml").read_text())
    start, end = doc["boxes"]
    near_edge = start["center"][0] + 0.5 * start["size"][0]
    end["center"][0] = near_edge + float(width) + 0.5 * end["size"][0]
    path = work / "chasm.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return str(path)


def _terrain_file(name: str, dmin: float | None, seed: int, work: Path,
                  size: float | None = None) -> str:
    """The trial's terrain file: hw_config/terrains/NAME.yaml, or a copy of it in ``work``
    with the trial's seed (random courses), d_min (stones) or size (``SIZE_PARAM``: Fig. 11's
    27 cm treads and 23 cm beam with ground truth, 40 cm and 35 cm with perception)."""
    src = HW_CONFIG_DIR / "terrains" / f"{name}.yaml"
    changes: dict[str, float] = {}
    if name in SIZE_PARAM and size is not None:
        changes[SIZE_PARAM[name]] = float(size)
    if name == "chasm" and size is not None:
        return _chasm_file(size, work)
    if name in DMIN_COURSES and dmin is not None:
        changes["d_min"] = float(dmin)
    if not changes and name not in SEEDED_COURSES:
        return str(src)
    doc = safe_load(src.read_text())
    doc["params"] = {**(doc.get("params") or {}), **changes}
    if name in SEEDED_COURSES:
        doc["seed"] = int(seed)
    path = work / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return str(path)


#: ``--planner``: the MPFC, or the DCM planner (Xiang et al.) and its ablations B-D
PLANNERS = ("mpfc", "dcm", "dcm-B", "dcm-C", "dcm-D")
#: ``--segmenter``: S3 + convex decomposition, the DCM planner's contour front end, or QuadPiPS'
#: superpixel planar regions
SEGMENTERS = ("s3", "contours", "superpixels")


def planner_params(planner: str) -> dict[str, str]:
    """The footstep-planner process's params for a ``PLANNERS`` name."""
    if planner not in PLANNERS:
        raise ValueError(f"planner {planner!r}: one of {', '.join(PLANNERS)}")
    if planner == "mpfc":
        return {"planner": "mpfc"}
    return {"planner": "dcm", "dcm_variant": planner.partition("-")[2] or "A"}


def _fixed_timing_gains(mpfc_gains: Path, work: Path) -> Path:
    """The MPFC's gains with its step-timing optimisation off (the paper's Fixed-T): the
    single-stance bounds t_min = t_max = T_ss, at the top and in every variant that sets them,
    so the stance time is the nominal one whichever variant runs."""
    doc = safe_load(mpfc_gains.read_text())
    for block in (doc, *(doc.get("variants") or {}).values()):
        if not isinstance(block, dict):
            continue
        nominal = block.get("t_ss_s", doc.get("t_ss_s"))
        if block is doc or any(k in block for k in ("t_ss_s", "t_ss_min_s", "t_ss_max_s")):
            block["t_ss_min_s"] = block["t_ss_max_s"] = nominal
    path = work / "mpfc_fixed_timing.yaml"
    path.write_text(f"# {mpfc_gains} with t_ss_min_s = t_ss_max_s = t_ss_s (Fixed-T)\n"
                    + yaml.safe_dump(doc, sort_keys=False))
    return path


def _write_profile(base_profile: Path, name: str, terrain: str, perception: bool, work: Path,
                   mode: str | None = None, fixed_timing: bool = False,
                   true_state: bool = False, planner: str = "mpfc", segmenter: str = "s3",
                   guide: bool = False) -> tuple[Path, list[str]]:
    """The experiment's profile: the base one on ``terrain``, perception joining or not, the
    MPFC's step timing optimised (Opt-T) or fixed (Fixed-T), the controllers on the
    estimator's state or (``true_state``: the paper's GT runs) on the sim's true state, and
    the footstep planner (``PLANNERS``) in the MPFC process's place, and with perception the
    foothold extraction (``SEGMENTERS``) in the S3 process's; with ``guide`` the SLIP guide
    joins (``GUIDE_PROCESS``, on the same footholds) and the MPFC follows it."""
    base = load_profile(base_profile)
    launch = [p for p in base.launch if (perception or p not in ("perception", "s3"))
              and (guide or p != GUIDE_PROCESS)]
    if perception:
        launch += [p for p in ("perception", "s3") if p not in launch]
    if guide and GUIDE_PROCESS not in launch:
        launch.append(GUIDE_PROCESS)
    sim_params: dict[str, Any] = {"terrain": terrain, "publish_footholds": not perception}
    # depth frames only feed perception; with it, rendered inline in the harness (sim-time
    # order, deterministic), as configured otherwise
    sim_params["camera_render"] = "off" if not perception else ("auto" if mode else "inline")
    doc: dict[str, Any] = {"include": [str(base_profile)], "profile": f"experiment_{name}"}
    if mode:
        doc["mode"] = mode
    doc["launch"] = launch
    doc["overrides"] = {"sim": {"params": sim_params},
                        "mpfc": {"params": {"footholds": "channel", **planner_params(planner),
                                            "guide": guide}}}
    if perception:
        doc["overrides"]["s3"] = {"params": {"method": segmenter}}
    if true_state:
        # the estimator publishes the sim's true pose and velocity of every step
        doc["overrides"]["state_estimator"] = {"params": {"truth_state": True},
                                               "inputs": {"ground_truth": "ground_truth"}}
        doc["overrides"]["sim"]["output_rate_hz"] = {"ground_truth": 2000}
    if fixed_timing:
        gains = base.processes["mpfc"].gains_file
        assert gains is not None  # (the builder requires one)
        doc["overrides"]["mpfc"]["gains"] = str(_fixed_timing_gains(Path(gains), work))
    prof_path = work / "experiment.yaml"
    prof_path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return prof_path, launch


def _prepare(base_profile: Path, name: str, dmin: float | None, seed: int, perception: bool,
             work: Path, mode: str | None = None, size: float | None = None,
             fixed_timing: bool = False, true_state: bool = False, planner: str = "mpfc",
             segmenter: str = "s3", guide: bool = False
             ) -> tuple[Path, Profile, list[str], list[Any], Callable[[float, float], float],
                        float | None, tuple[tuple[float, float], ...]]:
    """The trial's terrain and profile in ``work``: (profile path, profile, launched
    processes, the terrain's ground-truth footholds for the judge, its height, the course's
    end: the near edge in x of its last surface, None without one, and its centre line for
    the operator: ``Terrain.path``, empty for the x axis)."""
    from sim import terrain as terrain_mod

    terrain = _terrain_file(name, dmin, seed, work, size)
    prof_path, launch = _write_profile(base_profile, name, terrain, perception, work, mode,
                                       fixed_timing, true_state, planner, segmenter, guide)
    # a footstep is judged on the faces (less the margin), not on the footholds shrunk for
    # the foot that the controller aims within
    ter = terrain_mod.load_terrain(terrain)
    footholds = list(ter.landing_surfaces)
    return (prof_path, load_profile(prof_path), launch, footholds, ter.height_at,
            course_end_x(ter), ter.path)


def course_end_x(ter: Any) -> float | None:
    """Where a course ends: the near edge (x) of its last box, the far platform of the stones
    and beams (an untilted platform across the end of the winding beam's last segment), the
    stairs' landing or a chasm's end platform (hand-written boxes in a row along x, each
    beginning where the one before ends or beyond); None for a terrain without boxes (flat
    ground) or with its boxes not leading to a last one along x (``blocks``)."""
    if not ter.boxes:
        return None
    if ter.name == "boxes":
        spans = [(b.center[0] - 0.5 * b.size[0], b.center[0] + 0.5 * b.size[0])
                 for b in ter.boxes]
        if len(spans) < 2 or any(b[0] < a[1] - 1e-9 for a, b in pairwise(spans)):
            return None
    elif ter.name not in COURSES_WITH_END:
        return None
    last = ter.boxes[-1]
    return float(last.center[0] - 0.5 * last.size[0])


