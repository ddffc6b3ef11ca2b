"""Reads treemocap's exported trajectories back with third-party readers
(ezc3d and py-c3d for the C3D file, pandas with no options for the CSV) and
prints what they saw as one JSON object on stdout.

usage: read_export.py FILE.c3d FILE.csv
"""
import json
import math
import sys

import c3d
import ezc3d
import numpy as np
import pandas as pd


def clean(v):
    return None if (v is None or (isinstance(v, float) and math.isnan(v))) else v


def main():
    c3d_path, csv_path = sys.argv[1], sys.argv[2]
    out = {}

    e = ezc3d.c3d(c3d_path)
    pts = e["data"]["points"]  # 4 x points x frames
    res = e["data"]["meta_points"]["residuals"]  # 1 x points x frames
    out["ezc3d"] = {
        "labels": e["parameters"]["POINT"]["LABELS"]["value"],
        "rate": float(e["header"]["points"]["frame_rate"]),
        "points": [
            [[clean(float(pts[a, p, f])) for a in range(3)] + [float(res[0, p, f])] for f in range(pts.shape[2])]
            for p in range(pts.shape[1])
        ],
    }

    with open(c3d_path, "rb") as h:
        r = c3d.Reader(h)
        labels = [l.strip() for l in r.point_labels]
        frames = [points.tolist() for _, points, _ in r.read_frames()]
    out["py_c3d"] = {
        "labels": labels,
        "rate": float(r.point_rate),
        "points": [[[frames[f][p][a] for a in range(4)] for f in range(len(frames))] for p in range(len(labels))],
    }

    df = pd.read_csv(csv_path)
    out["pandas"] = {
        "columns": list(df.columns),
        "rows": int(len(df)),
        "dtypes": {c: str(t) for c, t in df.dtypes.items()},
        "tip_01_x_m": [clean(float(v)) for v in df["tip_01_x_m"].to_numpy(dtype=np.float64)],
        "tip_01_filled": [clean(float(v)) for v in df["tip_01_filled"].to_numpy(dtype=np.float64)],
    }
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
