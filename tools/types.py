"""`cassie types`: the stack's LCM types for the languages a user brings, built from
``lcmtypes/defs/*.lcm`` with the lcm-gen of the installed LCM.

* Java: ``lcmtypes.jar`` (lcm-gen -j, javac against LCM's own ``lcm.jar``, jar), what lcm-spy
  needs on its classpath to decode the channels (``cassie spy``).
* C++: the headers (lcm-gen -x), for a process of one's own in C++ (``tools/cpp_example``:
  subscribes to the state, publishes a command), as a dairlib user would swap one in.

Built once per version of the definitions, into the user's cache folder
(``$XDG_CACHE_HOME/cassie/lcmtypes/<hash>``; ``--out`` to choose), and printed.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
DEFS = REPO_ROOT / "lcmtypes" / "defs"


def definitions() -> list[Path]:
    """The message definitions, in name order."""
    return sorted(DEFS.glob("*.lcm"))


def type_names() -> list[str]:
    """Every type's full name (``lcmtypes.robot_state_t``...), one per definition file."""
    return [f"lcmtypes.{p.stem}" for p in definitions()]


def _tool(name: str) -> str:
    """An LCM tool of this environment (the venv's ``bin`` first: pip's lcm installs there)."""
    here = Path(sys.executable).parent / name
    found = str(here) if here.exists() else shutil.which(name)
    if found is None:
        raise SystemExit(f"{name} not found: install the project (pip install -e .) so LCM's "
                         "tools are on the PATH")
    return found


def _lcm_prefix() -> Path:
    """Where the lcm wheel put its files (``share/java``, ``include``, ``lib``)."""
    import lcm

    return Path(lcm.__file__).resolve().parents[1]


def lcm_jar() -> Path:
    """LCM's own Java library (installed with the lcm wheel, beside its lcm-spy)."""
    for base in (_lcm_prefix(), Path(sys.prefix)):
        jar = base / "share" / "java" / "lcm.jar"
        if jar.exists():
            return jar
    raise SystemExit("lcm.jar not found beside the lcm package: reinstall lcm (pip install lcm)")


def cache_dir() -> Path:
    """Where the built types go by default: per user, per version of the definitions."""
    digest = hashlib.sha256()
    for p in definitions():
        digest.update(p.name.encode() + b"\0" + p.read_bytes())
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "cassie" / "lcmtypes" / digest.hexdigest()[:12]


def build_java(out: Path) -> Path:
    """``out/lcmtypes.jar``, built unless there already."""
    jar = out / "lcmtypes.jar"
    if jar.exists():
        return jar
    for tool in ("javac", "jar"):
        if shutil.which(tool) is None:
            raise SystemExit(f"{tool} not found: the Java types need a JDK (e.g. apt install "
                             "default-jdk-headless)")
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="cassie-java-") as tmp:
        src, classes = Path(tmp) / "src", Path(tmp) / "classes"
        _run([_tool("lcm-gen"), "-j", "--jpath", str(src), *map(str, definitions())])
        java = sorted(str(p) for p in src.rglob("*.java"))
        _run(["javac", "-nowarn", "-cp", str(lcm_jar()), "-d", str(classes), *java])
        partial = out / "lcmtypes.jar.tmp"
        _run(["jar", "cf", str(partial), "-C", str(classes), "."])
        partial.replace(jar)  # whole or not at all: a later run never sees half a jar
    return jar


def build_cpp(out: Path) -> Path:
    """``out/cpp/lcmtypes/*.hpp``, generated unless there already; returns ``out/cpp`` (the
    include folder)."""
    inc = out / "cpp"
    if (inc / "lcmtypes" / "robot_state_t.hpp").exists():
        return inc
    tmp = out / "cpp.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    _run([_tool("lcm-gen"), "-x", "--cpp-hpath", str(tmp), *map(str, definitions())])
    shutil.rmtree(inc, ignore_errors=True)
    tmp.replace(inc)
    return inc


def lcm_include_and_lib() -> tuple[Path, Path]:
    """LCM's C/C++ headers and library folder, as the lcm wheel installs them."""
    base = _lcm_prefix()
    inc, lib = base / "include", base / "lib"
    if not (inc / "lcm" / "lcm-cpp.hpp").exists() or not any(lib.glob("liblcm.so*")):
        raise SystemExit(f"LCM's C++ headers or library not found under {base}")
    return inc, lib


def _run(cmd: list[str]) -> None:
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{Path(cmd[0]).name} failed ({done.returncode}):\n"
                         f"{done.stdout}{done.stderr}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="cassie types", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=None,
                   help="build into this folder (default: the user's cache, per version)")
    p.add_argument("--java", action="store_true", help="only the Java jar")
    p.add_argument("--cpp", action="store_true", help="only the C++ headers")
    args = p.parse_args(argv)
    out = args.out or cache_dir()
    both = not (args.java or args.cpp)
    if args.java or both:
        print(f"java: {build_java(out)}  (lcm-spy: CLASSPATH=<it> lcm-spy, or `cassie spy`)")
    if args.cpp or both:
        inc, lib = lcm_include_and_lib()
        print(f"c++:  {build_cpp(out)}  (g++ -I<it> -I{inc} ... -L{lib} -llcm; "
              "tools/cpp_example)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
