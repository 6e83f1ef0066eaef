"""``cassie spy``'s classpath holds every type of the stack, and lcm-spy's own type database
decodes every message of a real launch's log with it (the check lcm-spy makes for each
message it shows; lcm-spy itself is a window, and this machine has no display)."""

from __future__ import annotations

import importlib
import re
import shutil
import subprocess
from pathlib import Path

import lcm
import pytest

from tests.conftest import PROFILES, cassie
from tools.types import build_java, lcm_jar, type_names

pytestmark = pytest.mark.skipif(shutil.which("javac") is None, reason="needs a JDK (javac)")

HERE = Path(__file__).parent


def test_the_jar_holds_every_type(tmp_path: Path) -> None:
    jar = build_java(tmp_path)
    listing = subprocess.run(["jar", "tf", str(jar)], capture_output=True, text=True,
                             check=True).stdout.split()
    classes = {n.removesuffix(".class").replace("/", ".") for n in listing
               if n.endswith(".class")}
    assert set(type_names()) <= classes, set(type_names()) - classes


def test_spy_print_names_the_jar_and_one_spy_per_domain(tmp_path: Path) -> None:
    out = subprocess.run(
        ["cassie", "spy", str(PROFILES.parent.parent / "hw_config" / "sim.yaml"), "--print"],
        capture_output=True, text=True, check=True, env={**_env(tmp_path)}).stdout
    cp = re.search(r"CLASSPATH=(\S+)", out)
    assert cp is not None and cp.group(1).split(":")[0].endswith("lcmtypes.jar"), out
    assert re.search(r"^network: \S*lcm-spy --lcm-url=udpm://", out, re.M), out
    assert re.search(r"^nuc: \S*lcm-spy --lcm-url=udpm://", out, re.M), out


def test_lcm_spys_type_database_decodes_every_channel_of_a_launch(
        lcm_url: str, procs: list, tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    sup = cassie("launch", str(PROFILES / "supervised.yaml"), "--no-live", "--duration", "4",
                 "--log", "--log-dir", str(logs))
    procs.append(sup)
    sup.communicate(timeout=120)
    # and one message of every type of the stack, as its channels carry them (a launch of
    # the whole stack takes a minute; the bytes are the same lcm-gen encoding)
    log = lcm.EventLog(str(logs / "all_types.log"), "w")
    for name in type_names():
        msg = getattr(importlib.import_module(name), name.split(".")[1])()
        log.write_event(0, f"ALL_{name.split('.')[1]}", msg.encode())
    log.close()
    jar = build_java(tmp_path / "types")
    classes = tmp_path / "classes"
    subprocess.run(["javac", "-nowarn", "-cp", str(lcm_jar()), "-d", str(classes),
                    str(HERE / "SpyDecodeCheck.java")], check=True)
    cp = ":".join([str(classes), str(jar), str(lcm_jar())])
    # lcm-spy's database finds the types through the CLASSPATH variable, as lcm-spy does
    out = subprocess.run(["java", "-cp", cp, "SpyDecodeCheck", str(logs / "lcm.log"),
                          str(logs / "all_types.log")],
                         capture_output=True, text=True, check=True,
                         env={"CLASSPATH": cp, "PATH": "/usr/bin:/bin"}).stdout
    print(out)
    rows = [line.split() for line in out.splitlines()]
    assert not [r for r in rows if r[0] == "UNDECODED"], out
    decoded = {r[0]: r[1] for r in rows}
    assert {"TIMING", "SUPERVISOR_STATUS"} <= set(decoded), out
    assert decoded["TIMING"] == "lcmtypes.loop_timing_t"
    for name in type_names():
        assert decoded.get(f"ALL_{name.split('.')[1]}") == name, (name, out)


def _env(tmp_path: Path) -> dict[str, str]:
    import os

    return {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache")}
