#!/usr/bin/env python3
"""What py-c3d (PyPI `c3d`) reads from C3D files, for tests/c3d.rs to compare
with treemocap's reader: frame and point counts, first frame, rate, missing
samples per point, and sums of the valid coordinates (file units and axes).

py-c3d marks a point invalid when its fourth word is negative or any of its
values is not finite, the same rule as spec/c3d.md, implemented
independently.

Usage: c3d_counts.py FILE... -> JSON list on stdout, one object per file.
"""
import json
import sys
import warnings

import numpy as np

try:
    import c3d
except ImportError:
    sys.exit("python package 'c3d' is missing: pip install -r tests/peers/requirements.txt")

warnings.simplefilter("ignore")


def counts(path):
    with open(path, "rb") as h:
        r = c3d.Reader(h)
        used = int(r.point_used)
        missing = np.zeros(used, np.int64)
        sums = np.zeros(3, np.float64)
        frames = 0
        first = None
        for no, points, _ in r.read_frames(analog_transform=False):
            if first is None:
                first = int(no)
            frames += 1
            invalid = points[:, 3] < 0
            missing += invalid
            sums += points[~invalid, :3].astype(np.float64).sum(axis=0)
        labels = r.get("POINT:LABELS")
        return {
            "path": path,
            "frames": frames,
            "first_frame": first,
            "points": used,
            "rate": float(r.point_rate),
            "labels": [s.strip() for s in labels.string_array][:used] if labels is not None else [],
            "missing": missing.tolist(),
            "sums": sums.tolist(),
        }


json.dump([counts(p) for p in sys.argv[1:]], sys.stdout)
