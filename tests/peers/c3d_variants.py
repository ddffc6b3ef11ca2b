#!/usr/bin/env python3
"""Writes C3D files of every processor x storage variant with an independent
writer (py-c3d, PyPI `c3d`), for tests/c3d.rs.

py-c3d writes Intel files only, so the DEC and MIPS variants are made by
re-encoding its Intel output field by field (header words, parameter records,
point and analog words) in `convert`. Every file, the converted ones
included, is then read back with py-c3d's Reader and checked against the
known positions and gaps before anything is reported, so py-c3d is the
oracle for the conversion as well.

Usage: c3d_variants.py OUTDIR  -> prints a JSON manifest on stdout:
  {"files": [{"path", "processor", "storage", "scale", "rate", "labels",
              "first_frame", "frames": [[[x,y,z] | null, ...], ...]}]}
Positions are the intended ones in mm (the file's units), before int16
quantisation; null marks a point that must read as missing.
"""
import io
import json
import math
import os
import struct
import sys

import numpy as np

try:
    import c3d
except ImportError:
    sys.exit("python package 'c3d' is missing: pip install -r tests/peers/requirements.txt")

RATE = 100.0
POINTS = 5
FRAMES = 40
LABELS = ["TIP_A", "TIP_B", "TIP_C", "TIP_D", "TIP_E"]

INTEL, DEC, MIPS = 84, 85, 86


def truth(float_storage, dec):
    """Known positions (mm) and the gap of each kind; None = missing."""
    frames = []
    for f in range(FRAMES):
        row = []
        for i in range(POINTS):
            row.append([100.0 * i + 1.5 * f - 250.0, 10.0 * f - 3.0 * i + 0.25, 900.0 + 0.5 * i * f])
        frames.append(row)
    gaps = {}  # (frame, point) -> kind
    for f in range(5, 10):
        gaps[(f, 1)] = "minus_one"
    for f in range(10, 13):
        gaps[(f, 2)] = "motive"  # -32768 with stale coordinates
    for f in range(20, 23):
        # ezc3d's NaN gaps exist only in IEEE float files; VAX floats have
        # no NaN and int16 none either, so those variants use -1 there.
        gaps[(f, 3)] = "nan" if float_storage and not dec else "minus_one"
    gaps[(0, 0)] = "minus_one"
    gaps[(FRAMES - 1, 4)] = "motive"
    return frames, gaps


def write_intel(float_storage, frames, gaps, scale):
    w = c3d.Writer(point_rate=RATE, analog_rate=2 * RATE,
                   point_scale=-scale if float_storage else scale, point_units="mm  ")
    w.set_point_labels(LABELS)
    w.set_analog_labels(["FZ", "EMG"])
    w.set_screen_axis("+X", "+Z")
    for f, row in enumerate(frames):
        pts = np.zeros((POINTS, 5), np.float32)
        for i, xyz in enumerate(row):
            kind = gaps.get((f, i))
            pts[i, :3] = xyz
            if kind == "nan":
                pts[i, :3] = np.nan
                pts[i, 3] = 0.0  # ezc3d: residual 0, coordinates NaN
            elif kind is not None:
                pts[i, 3] = -1.0
            else:
                # Residuals up to 200 x scale with camera bits: BTS-like
                # low bytes >= 128 and a non-zero high byte stay valid.
                pts[i, 3] = ((f * 7 + i * 31) % 201) * scale
                pts[i, 4] = (f + i) % 128
        analog = np.array([[f * 1.0, -f * 1.0], [1000.0 + f, 5.0]], np.float64)  # 2 channels x 2 samples
        w.add_frames([(pts, analog)])
    buf = io.BytesIO()
    w.write(buf)
    data = bytearray(buf.getvalue())
    # Motive's gaps: residual word -32768 and stale, non-zero coordinates,
    # which py-c3d's writer cannot produce; patched into the data section.
    data_block = struct.unpack_from("<H", data, 16)[0]
    word = 4 if float_storage else 2
    frame_bytes = POINTS * 4 * word + 2 * 2 * word
    for (f, i), kind in gaps.items():
        if kind != "motive":
            continue
        at = (data_block - 1) * 512 + f * frame_bytes + i * 4 * word
        stale = [529.3, 70.3, 194.9]
        if float_storage:
            struct.pack_into("<4f", data, at, *stale, -32768.0)
        else:
            struct.pack_into("<4h", data, at, *[round(v / scale) for v in stale], -32768)
    return bytes(data)


# --- Intel -> DEC / MIPS -------------------------------------------------

def conv_i16(b, proc):
    v = struct.unpack("<h", b)[0]
    return struct.pack(">h" if proc == MIPS else "<h", v)


def conv_f32(b, proc):
    if proc == MIPS:
        return b[::-1]
    v = struct.unpack("<f", b)[0]
    if v == 0.0 or not math.isfinite(v):
        if not math.isfinite(v):
            raise ValueError("DEC floats cannot hold NaN or infinity")
        return b"\0\0\0\0"
    le = struct.pack("<f", v * 4.0)  # VAX-F: exponent bias 2 higher...
    return le[2:4] + le[0:2]         # ...and the 16-bit halves swapped


def conv_words(data, start, end, size, proc):
    f = conv_i16 if size == 2 else conv_f32
    out = bytearray()
    for at in range(start, end, size):
        out += f(bytes(data[at:at + size]), proc)
    data[start:end] = out


def convert(intel, proc, float_storage):
    d = bytearray(intel)
    # Header: words 1-5, float, word 8, word 9, float.
    for at in (2, 4, 6, 8, 10, 16, 18):
        d[at:at + 2] = conv_i16(intel[at:at + 2], proc)
    for at in (12, 20):
        d[at:at + 4] = conv_f32(intel[at:at + 4], proc)
    param_at = (intel[0] - 1) * 512
    d[param_at + 3] = proc
    pos = param_at + 4
    while True:
        name_len, gid = struct.unpack_from("<bb", intel, pos)
        if name_len == 0 or gid == 0:
            break
        n = abs(name_len)
        off_at = pos + 2 + n
        offset = struct.unpack_from("<h", intel, off_at)[0]
        d[off_at:off_at + 2] = conv_i16(intel[off_at:off_at + 2], proc)
        if gid > 0:
            body = off_at + 2
            ptype, ndims = struct.unpack_from("<bB", intel, body)
            dims = intel[body + 2: body + 2 + ndims]
            count = int(np.prod(list(dims))) if ndims else 1
            start = body + 2 + ndims
            if ptype in (2, 4):
                conv_words(d, start, start + count * ptype, ptype, proc)
        if offset == 0:
            break
        pos = off_at + offset
    data_block = struct.unpack_from("<H", intel, 16)[0]
    start = (data_block - 1) * 512
    word = 4 if float_storage else 2
    frame_bytes = POINTS * 4 * word + 2 * 2 * word
    conv_words(d, start, start + FRAMES * frame_bytes, word, proc)
    return bytes(d)


def check_with_py_c3d(path, frames, gaps, scale, float_storage):
    with open(path, "rb") as h:
        r = c3d.Reader(h)
        assert r.point_used == POINTS, (path, r.point_used)
        n = 0
        for f, (_, pts, _) in enumerate(r.read_frames()):
            n += 1
            for i in range(POINTS):
                missing = pts[i, 3] < 0
                assert missing == ((f, i) in gaps), (path, f, i, pts[i])
                if not missing:
                    tol = 1e-3 if float_storage else scale / 2 + 1e-3
                    assert np.allclose(pts[i, :3], frames[f][i], atol=tol), (path, f, i, pts[i], frames[f][i])
        assert n == FRAMES, (path, n)


def write_long(outdir):
    """A file longer than 65535 frames (TRIAL fields / POINT:LONG_FRAMES)."""
    n = 70000
    w = c3d.Writer(point_rate=1000.0, point_scale=1.0, point_units="mm  ")
    w.set_point_labels(["ONLY"])
    pts = np.zeros((1, 5), np.float32)
    frames = []
    for f in range(n):
        p = pts.copy()
        p[0, :3] = (f % 1000, 0, f // 1000)
        p[0, 3] = -1.0 if f % 10000 == 9999 else 0.0
        frames.append((p, np.zeros((0, 0))))
    w.add_frames(frames)
    path = os.path.join(outdir, "long_intel_int.c3d")
    with open(path, "wb") as h:
        w.write(h)
    with open(path, "rb") as h:
        r = c3d.Reader(h)
        assert r.frame_count == n, r.frame_count
    return {"path": path, "frames": n, "missing": n // 10000}


def main():
    outdir = sys.argv[1]
    files = []
    for float_storage in (False, True):
        scale = 0.1
        for proc, pname in ((INTEL, "Intel"), (DEC, "DEC"), (MIPS, "MIPS")):
            frames, gaps = truth(float_storage, proc == DEC)
            intel = write_intel(float_storage, frames, gaps, scale)
            data = intel if proc == INTEL else convert(intel, proc, float_storage)
            storage = "float32" if float_storage else "int16"
            path = os.path.join(outdir, f"{pname.lower()}_{storage}.c3d")
            with open(path, "wb") as h:
                h.write(data)
            check_with_py_c3d(path, frames, gaps, scale, float_storage)
            files.append({
                "path": path, "processor": pname, "storage": storage, "scale": scale,
                "rate": RATE, "labels": LABELS, "first_frame": 1,
                "frames": [[None if (f, i) in gaps else frames[f][i] for i in range(POINTS)]
                           for f in range(FRAMES)],
            })
    json.dump({"files": files, "long": write_long(outdir)}, sys.stdout)


if __name__ == "__main__":
    main()
