#!/usr/bin/env python3
"""Writes small FORCES.bin files from docs/formats.md ("FORCES.bin") alone, without cutload's code:
the fuzz target forces_bin starts from them (tests/fuzz/seeds/forces_bin/), and reading them checks
the reader against the document rather than against cutload's own writer.

usage: scripts/forces_bin_seeds.py OUT_DIR
"""
import json
import struct
import sys
from pathlib import Path

COLUMNS = [("t_s", 6), ("spindle_angle_deg", 3), ("block", 0), ("tool", 0), ("fx_N", 3), ("fy_N", 3),
           ("fz_N", 3), ("torque_Nm", 4), ("power_kW", 4), ("chip_mm", 5), ("bending_MPa", 3),
           ("radial_engagement_mm", 3), ("axial_engagement_mm", 3), ("removed_mm3", 5), ("holder_contact", 0)]


def varint(u):
    out = bytearray()
    while u >= 0x80:
        out.append((u & 0x7F) | 0x80)
        u >>= 7
    out.append(u)
    return bytes(out)


def zigzag(d):
    return (d << 1) ^ (d >> 63) if d >= 0 else ((-d) << 1) - 1


def forces_bin(columns, rows, block_names, chunk_rows):
    header = json.dumps({"format": "cutload FORCES.bin", "columns": [{"name": n, "decimals": k} for n, k in columns],
                         "chunk_rows": chunk_rows, "block_names": block_names}).encode()
    out = bytearray(b"\x89CLF\r\n\x1a\n") + struct.pack("<II", 1, len(header)) + header
    for start in range(0, len(rows), chunk_rows):
        chunk = rows[start:start + chunk_rows]
        out += struct.pack("<I", len(chunk))
        for c, (_, k) in enumerate(columns):
            data, prev = bytearray(), 0
            for row in chunk:
                q = round(row[c] * 10 ** k)
                data += varint(zigzag(q - prev))
                prev = q
            out += struct.pack("<I", len(data)) + data
    out += struct.pack("<I", 0) + struct.pack("<Q", len(rows))
    return bytes(out)


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    # A slot's tooth passes: 8 rows at 30 kHz, 2 deg steps, one block change, air at the end.
    rows = []
    for i in range(8):
        cutting = i < 6
        rows.append([0.5 + i / 30000, 2.0 * i, 0 if i < 4 else 1, 7, 120.5 - 10 * i if cutting else 0,
                     -80.25 + i if cutting else 0, -12.0 if cutting else 0, 0.85 if cutting else 0,
                     0.89 if cutting else 0, 0.04321 if cutting else 0, 22.5 if cutting else 0,
                     10.0 if cutting else 0, 3.0 if cutting else 0, 0.01234 if cutting else 0, 0])
    (out / "slot.bin").write_bytes(forces_bin(COLUMNS, rows, ["N10 G1 X20", "N20 G1 Y5"], 3))
    # The six columns a reader needs and no others, in another order, one chunk.
    needed = [("block", 0), ("t_s", 3), ("fz_N", 1), ("fx_N", 1), ("fy_N", 1), ("spindle_angle_deg", 0)]
    (out / "minimal.bin").write_bytes(forces_bin(needed, [[-1, 0.001, -1.5, 2.0, 3.0, 0], [-1, 0.002, -1.4, 2.5, 3.5, 90]],
                                                 [], 65536))


if __name__ == "__main__":
    main()
