"""Receives treemocap's OSC output with python-osc (a receiver we did not
write) and prints one JSON summary line: the first whole tree and how many
tip frames arrived. Usage: osc_receive.py PORT MIN_TIP_FRAMES TIMEOUT_S"""
import json
import sys
import time

from pythonosc import dispatcher, osc_server

port, min_tips, timeout = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
state = {"begin": None, "end": None, "nodes": {}, "tip_frames": 0, "tips_per_frame": [], "wind": 0,
         "pose_datagrams": 0, "pose_nodes_max": 0}


def begin(_addr, version, count):
    if state["end"] is None:
        state["begin"] = [version, count]
        state["nodes"] = {}


def node(_addr, nid, parent, x, y, z, radius):
    if state["end"] is None:
        state["nodes"][nid] = [parent, x, y, z, radius]


def end(_addr, version, count):
    if state["end"] is None and state["begin"] is not None:
        state["end"] = [version, count]


def tips(_addr, frame, t, *rest):
    state["tip_frames"] += 1
    state["tips_per_frame"].append(len(rest) // 4)


def pose(_addr, version, frame, t, first, count, *d):
    # A run of datagrams per pose, each naming its first node and count.
    if len(d) == 3 * count:
        state["pose_datagrams"] += 1
        state["pose_nodes_max"] = max(state["pose_nodes_max"], first + count)


def wind(_addr, *args):
    state["wind"] += 1


d = dispatcher.Dispatcher()
d.map("/treemocap/tree/begin", begin)
d.map("/treemocap/tree/node", node)
d.map("/treemocap/tree/end", end)
d.map("/treemocap/tips", tips)
d.map("/treemocap/wind", wind)
d.map("/treemocap/pose", pose)
server = osc_server.BlockingOSCUDPServer(("127.0.0.1", port), d)
server.timeout = 0.2
print("ready", flush=True)
deadline = time.time() + timeout
while time.time() < deadline:
    server.handle_request()
    if state["end"] is not None and state["tip_frames"] >= min_tips:
        break
nodes = state["nodes"]
print(json.dumps({
    "begin": state["begin"],
    "end": state["end"],
    "nodes_received": len(nodes),
    "parents_ok": all(p == -1 or (0 <= p < len(nodes)) for p, *_ in nodes.values()),
    "tip_frames": state["tip_frames"],
    "max_tips_per_frame": max(state["tips_per_frame"] or [0]),
    "pose_datagrams": state["pose_datagrams"],
    "pose_nodes_max": state["pose_nodes_max"],
    "wind": state["wind"],
}), flush=True)
