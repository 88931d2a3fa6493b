"""The `Compensator` class replays the firmware's reference vectors (replay/vectors,
the files the host tests and the QEMU run check) bit for bit."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import List

import pytest
import qfa_thermal as q

from conftest import REPO

VECTORS = sorted((REPO / "replay" / "vectors").glob("*.vec"))

#: The vectors' error codes (replay: `sample_error_code`, `table_error_code`),
#: by the `kind` the exceptions carry.
SAMPLE_CODES = {
    "BusAllOnes": 0x11,
    "AllZero": 0x12,
    "Crc": 0x13,
    "Reserved": 0x14,
    "Config": 0x15,
    "PowerOn": 0x16,
    "OutOfRange": 0x17,
    "Time": 0x21,
    "PowerOnJump": 0x22,
    "Implausible": 0x23,
    "Missed": 0x24,
}
TABLE_CODES = {
    "Truncated": 0x31,
    "BadMagic": 0x32,
    "Version": 0x33,
    "AxisCount": 0x34,
    "Crc": 0x35,
    "Decode": 0x36,
    "TrailingBytes": 0x37,
    "NonFinite": 0x38,
    "OutOfRange": 0x39,
    "Grid": 0x3A,
    "ScaleFactorNotPositive": 0x3B,
    "RateWindow": 0x3C,
    "NoInputRecorded": 0x3D,
    "Input": 0x3E,
}


def bits(x: float) -> int:
    """The f32 bit pattern of a value the firmware computed (exact: f32 → Python float → f32)."""
    return struct.unpack("<I", struct.pack("<f", x))[0]


def step(c: q.Compensator, line: str) -> List[int]:
    tok = line.split()
    kind = tok[0]
    if kind == "table":
        try:
            c.load_table(bytes.fromhex(tok[1]))
            return [0]
        except q.TableError as e:
            return [TABLE_CODES[e.kind]]
    if kind in ("raw", "sp"):
        try:
            if kind == "raw":
                c.on_raw(int(tok[1]), int(tok[2]))
            else:
                c.on_scratchpad(int(tok[1]), bytes.fromhex(tok[2]))
        except q.SampleError as e:
            assert e.status == c.status
            return [SAMPLE_CODES[e.kind], c.status]
        est = c.estimate()
        assert est is not None
        ev = c.evaluations()
        return [0, c.status, bits(est[0]), bits(est[1])] + [bits(e[0]) for e in ev] + [bits(e[1]) for e in ev]
    dt, values = int(tok[1]), [int(v) for v in tok[2:5]]
    call = {"cycle": c.cycle, "count": c.cycle_counters, "samp": c.cycle_samples}[kind]
    out, status = call(values, dt)
    assert out.dtype.name == "float32"
    return [status] + [int(w) for w in out.view("uint32")]


@pytest.mark.parametrize("path", VECTORS, ids=[p.name for p in VECTORS])
def test_vectors_bit_exact(path: Path) -> None:
    c = q.Compensator(axes=3)
    n = 0
    for number, raw in enumerate(path.read_text().splitlines(), start=1):
        content = raw.split("#", 1)[0].strip()
        if not content:
            continue
        given, want = (s.strip() for s in content.split("=>"))
        got = step(c, given)
        assert got == [int(w, 16) for w in want.split()], f"{path.name}:{number}: {given}"
        n += 1
    print(f"{path.name}: {n} vectors bit-exact from Python")
    assert n > 100


def test_the_vector_files_are_all_there() -> None:
    assert len(VECTORS) == 8
