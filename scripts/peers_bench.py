"""Times the tools a user would otherwise use on the files `examples/scale.rs`
made, and prints one JSON line per measurement: {"tool", "file", "seconds",
"values"} ("values": numbers read, to check the tool read everything).

usage:
  peers_bench.py pandas-motive FILE      Motive CSV export (header rows skipped)
  peers_bench.py pandas-log FILE         treemocap log, no options
  peers_bench.py c3d FILE                py-c3d (`c3d` on PyPI)
  peers_bench.py ezc3d FILE              ezc3d
  peers_bench.py natnetsdk FILE MAJOR MINOR REPEAT
                                         OptiTrack's Python client decoding
                                         one NatNet frame packet REPEAT times
A tool that is not installed prints {"tool", "error"} instead.
"""
import contextlib
import io
import json
import sys
import time


def emit(tool, path, seconds, values):
    print(json.dumps({"tool": tool, "file": path, "seconds": seconds, "values": values}), flush=True)


def motive_header_rows(path):
    """Rows before the 'Frame,Time' axis row of a Motive export."""
    with open(path, "r", encoding="utf-8-sig", newline="") as f:
        for i, line in enumerate(f):
            if line.startswith("Frame,"):
                return i
    raise SystemExit(f"{path}: no 'Frame,Time' row")


def pandas_motive(path):
    import pandas

    skip = motive_header_rows(path)
    t = time.perf_counter()
    df = pandas.read_csv(path, skiprows=skip, header=0, low_memory=False)
    seconds = time.perf_counter() - t
    emit("pandas", path, seconds, int(df.iloc[:, 2:].count().sum()))


def pandas_log(path):
    import pandas

    t = time.perf_counter()
    df = pandas.read_csv(path)
    seconds = time.perf_counter() - t
    emit("pandas", path, seconds, int(df[["x", "y", "z"]].count().sum()))


def py_c3d(path):
    import c3d

    t = time.perf_counter()
    n = 0
    with open(path, "rb") as f:
        for _, points, _ in c3d.Reader(f).read_frames():
            n += int((points[:, 3] >= 0).sum()) * 3
    emit("py-c3d", path, time.perf_counter() - t, n)


def ezc3d_read(path):
    import ezc3d
    import numpy

    t = time.perf_counter()
    c = ezc3d.c3d(path)
    pts = c["data"]["points"]
    n = int(numpy.isfinite(pts[:3]).sum())
    emit("ezc3d", path, time.perf_counter() - t, n)


def natnetsdk_decode(path, major, minor, repeat):
    from natnetsdk.NatNetClient import NatNetClient

    data = open(path, "rb").read()
    client = NatNetClient()
    client.set_nat_net_version(major, minor)
    unpack = client._NatNetClient__unpack_mocap_data
    size = int.from_bytes(data[2:4], "little")
    body = data[4:]
    t = time.perf_counter()
    # The SDK prints every frame it unpacks; the printing is part of its cost
    # but not of decoding, so it goes to a buffer that is thrown away.
    with contextlib.redirect_stdout(io.StringIO()):
        for _ in range(repeat):
            _, frame = unpack(body, size, major, minor)
    seconds = time.perf_counter() - t
    markers = frame.labeled_marker_data.get_labeled_marker_count() if frame.labeled_marker_data else 0
    emit("natnetsdk", path, seconds / repeat, markers)


def main():
    tool, path = sys.argv[1], sys.argv[2]
    try:
        if tool == "pandas-motive":
            pandas_motive(path)
        elif tool == "pandas-log":
            pandas_log(path)
        elif tool == "c3d":
            py_c3d(path)
        elif tool == "ezc3d":
            ezc3d_read(path)
        elif tool == "natnetsdk":
            natnetsdk_decode(path, int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]))
        else:
            raise SystemExit(f"unknown tool {tool}")
    except ImportError as e:
        print(json.dumps({"tool": tool, "file": path, "error": str(e)}), flush=True)


if __name__ == "__main__":
    main()
