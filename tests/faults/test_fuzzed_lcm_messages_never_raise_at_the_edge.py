"""Fuzzed bytes on every LCM input never raise past the edge: each of the project's message
types is encoded, then mutated (bit flips, overwritten bytes, cut short, grown), and fed
through a ``Subscription`` with its edge check (``runtime.validate``), as a live port takes
it. Every input is decoded and admitted, or counted as malformed or rejected: nothing else.

2,000 inputs per type in the default run; 100,000 per type with ``pytest -m faults``.
"""

from __future__ import annotations

import importlib
import random
import time
from pathlib import Path

import pytest

from runtime.bus import Subscription
from runtime.validate import InputCheck

TYPES = sorted(p.stem for p in (Path(__file__).resolve().parents[2] / "lcmtypes").glob("*_t.py"))


def _sample(name: str) -> object:
    """A message of type ``name`` with every array one element long and numbers non-zero."""
    cls = getattr(importlib.import_module(f"lcmtypes.{name}"), name)
    m = cls()
    sizes: dict[str, int] = {}
    for field, tname, dims in zip(cls.__slots__, cls.__typenames__, cls.__dimensions__,
                                  strict=True):
        if tname.startswith("int") or tname == "byte":
            if any(field in (d or ()) for d in cls.__dimensions__ if d):
                sizes[field] = 2
                setattr(m, field, 2)
            elif dims is None:
                setattr(m, field, 1)
    for field, tname, dims in zip(cls.__slots__, cls.__typenames__, cls.__dimensions__,
                                  strict=True):
        if dims is None:
            if tname in ("double", "float"):
                setattr(m, field, 0.5)
            continue
        n = [sizes.get(d, d) if isinstance(d, str) else d for d in dims]
        if tname == "byte":
            setattr(m, field, bytes(range(n[0])))
        elif tname == "string":
            setattr(m, field, ["ab"] * n[0])
        elif "." in tname:
            sub = _sample(tname.rsplit(".", 1)[1])
            setattr(m, field, [sub] * n[0])
        elif len(n) == 2:
            setattr(m, field, [[0.5] * n[1] for _ in range(n[0])])
        elif tname == "boolean":
            setattr(m, field, [True] * n[0])
        else:
            setattr(m, field, [1 if tname.startswith("int") else 0.5] * n[0])
    return m


def _mutations(raw: bytes, rng: random.Random, count: int):  # type: ignore[no-untyped-def]
    for _ in range(count):
        b = bytearray(raw)
        kind = rng.randrange(5)
        if kind == 0:  # flip bits
            for _ in range(rng.randint(1, 4)):
                i = rng.randrange(len(b))
                b[i] ^= 1 << rng.randrange(8)
        elif kind == 1:  # overwrite a run of bytes
            i = rng.randrange(len(b))
            b[i:i + 8] = bytes(rng.randrange(256) for _ in range(8))
        elif kind == 2:  # cut short
            del b[rng.randrange(8, len(b)):]
        elif kind == 3:  # grow
            b += bytes(rng.randrange(256) for _ in range(rng.randint(1, 64)))
        else:  # a count field set huge: the first 4 bytes after the fingerprint region
            i = rng.randrange(8, max(9, len(b) - 4))
            b[i:i + 4] = b"\x7f\xff\xff\xff"
        yield bytes(b)


def _fuzz(name: str, count: int) -> tuple[int, int, int]:
    cls = getattr(importlib.import_module(f"lcmtypes.{name}"), name)
    raw = _sample(name).encode()
    port = Subscription(name.upper(), cls, "newest", capacity=4)
    port.check = InputCheck(cls)
    rng = random.Random(name)
    admitted = 0
    t0 = time.perf_counter()
    for data in _mutations(raw, rng, count):
        port._on_message(port.channel, data)  # must not raise
        if port.take() is not None:
            admitted += 1
    assert time.perf_counter() - t0 < 60.0 + count * 2e-3  # never hangs
    return admitted, port.decode_errors, port.rejected


@pytest.mark.faults
@pytest.mark.parametrize("name", TYPES)
def test_fuzzed_bytes_of_each_type_are_decoded_or_counted_never_raised(name):
    admitted, malformed, rejected = _fuzz(name, 2000)
    assert admitted + malformed + rejected == 2000


@pytest.mark.faults
@pytest.mark.slow
@pytest.mark.parametrize("name", TYPES)
def test_100k_fuzzed_inputs_per_decoder(name):
    admitted, malformed, rejected = _fuzz(name, 100_000)
    assert admitted + malformed + rejected == 100_000
    print(f"{name}: 100000 fuzzed: {admitted} admitted, {malformed} malformed, "
          f"{rejected} rejected at the edge, 0 raised")
