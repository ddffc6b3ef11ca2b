#!/usr/bin/env python3
"""Sends marker frames over OSC with python-osc, the way the NatNet->OSC
bridges in shared/spec/osc.md do, for treemocap's OSC tests.

    osc_send.py HOST PORT --family F --frames FRAMES.json [--rate HZ] [--source-ip IP]
    osc_send.py HOST PORT --bad

FRAMES.json: [{"frame": n, "time_ms": t, "markers": [[id, x, y, z], ...]}, ...]

Families:
  hku          one bundle per frame: /marker ,ifff (index, x, y, z) plus a
               /rigidBody message (hku-ect NatNet2OSCbridge)
  max          unbundled /frame/start ,i; /frame/timestamp ,i ms;
               /marker ,isfff (id, "position", x, y, z); /rigidbody ,isi;
               /frame/end ,i -- one datagram each (NatNetThree2OSC --oscMode max)
  max-bundled  the same messages in one bundle per frame (--bundled)
  path         like max with /marker/<id>/position ,fff (isadora/touch mode)
  treemocap    /treemocap/markers ,hd f... (frame, time in s, x y z per marker)

--bad sends garbage and messages with wrong type tags, then one good
/treemocap/markers frame (number 77), and prints what it sent by kind.

Always prints one JSON line at the end: {"datagrams": N, ...}. With --progress
it also prints "sent <frame>" after each frame, flushed, so a caller can time
them.
"""

import argparse
import json
import socket
import sys
import time

from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message_builder import OscMessageBuilder


def message(address, *args):
    b = OscMessageBuilder(address=address)
    for value, tag in args:
        b.add_arg(value, tag)
    return b.build()


def bundle(messages):
    b = OscBundleBuilder(IMMEDIATELY)
    for m in messages:
        b.add_content(m)
    return b.build()


def frame_messages(family, f):
    n, ms, markers = f["frame"], f["time_ms"], f["markers"]
    if family == "hku":
        msgs = [message("/marker", (m[0], "i"), (m[1], "f"), (m[2], "f"), (m[3], "f")) for m in markers]
        rb = [(1, "i"), ("tree_base", "s")] + [(0.0, "f")] * 6 + [(1.0, "f"), (1, "i")]
        msgs.insert(len(msgs) // 2, message("/rigidBody", *rb))
        return [bundle(msgs)]
    if family == "treemocap":
        args = [(n, "h"), (ms / 1000.0, "d")]
        for m in markers:
            args += [(m[1], "f"), (m[2], "f"), (m[3], "f")]
        return [message("/treemocap/markers", *args)]
    msgs = [message("/frame/start", (n, "i")), message("/frame/timestamp", (ms, "i"))]
    for m in markers:
        if family == "path":
            msgs.append(message("/marker/%d/position" % m[0], (m[1], "f"), (m[2], "f"), (m[3], "f")))
        else:
            msgs.append(
                message("/marker", (m[0], "i"), ("position", "s"), (m[1], "f"), (m[2], "f"), (m[3], "f"))
            )
    msgs.append(message("/rigidbody", (1, "i"), ("tracked", "s"), (1, "i")))
    msgs.append(message("/frame/end", (n, "i")))
    if family == "max-bundled":
        return [bundle(msgs)]
    if family in ("max", "path"):
        return msgs
    raise SystemExit("unknown family %r" % family)


def bad_datagrams():
    """(kind, bytes) pairs; kinds are treemocap's counters."""
    good = message("/marker", (1, "i"), ("position", "s"), (1.0, "f"), (2.0, "f"), (3.0, "f")).dgram
    cases = [
        ("garbage", b""),
        ("garbage", b"hello, treemocap"),
        ("garbage", bytes(range(256))),
        ("garbage", good[: len(good) - 3]),  # truncated in the last float
        ("garbage", good + b"\x00\x00\x00\x07"),  # trailing bytes
        ("garbage", b"#bundle\x00" + b"\x00" * 7),  # short time tag
        ("bad_args", message("/marker", ("seven", "s"), (1.0, "f"), (2.0, "f"), (3.0, "f")).dgram),
        ("bad_args", message("/marker", (1, "i"), (1.0, "f"), (2, "i"), (3.0, "f")).dgram),
        ("bad_args", message("/marker", (1, "i"), (1.0, "f")).dgram),
        ("bad_args", message("/marker/3/position", (1.0, "f"), ("y", "s"), (3.0, "f")).dgram),
        ("bad_args", message("/frame/start", ("one", "s")).dgram),
        ("bad_args", message("/treemocap/markers", (1, "i"), (0.5, "d"), (1.0, "f"), (2.0, "f")).dgram),
        ("bad_args", message("/treemocap/markers", (1.5, "f"), (0.5, "d")).dgram),
    ]
    final = message("/treemocap/markers", (77, "h"), (7.7, "d"), (0.5, "f"), (1.5, "f"), (-0.25, "f"))
    return cases, final.dgram


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("host")
    ap.add_argument("port", type=int)
    ap.add_argument("--family")
    ap.add_argument("--frames")
    ap.add_argument("--rate", type=float, default=0.0, help="frames per second (0: as fast as possible)")
    ap.add_argument("--source-ip", default="", help="send from this local address")
    ap.add_argument("--bad", action="store_true")
    ap.add_argument("--progress", action="store_true")
    a = ap.parse_args()

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((a.source_ip, 0))
    dest = (a.host, a.port)
    sent = 0

    if a.bad:
        cases, final = bad_datagrams()
        counts = {}
        for kind, dgram in cases:
            sock.sendto(dgram, dest)
            sent += 1
            counts[kind] = counts.get(kind, 0) + 1
            time.sleep(0.002)
        sock.sendto(final, dest)
        sent += 1
        counts["datagrams"] = sent
        print(json.dumps(counts), flush=True)
        return

    with open(a.frames) as fh:
        frames = json.load(fh)
    start = time.perf_counter()
    for i, f in enumerate(frames):
        if a.rate > 0:
            due = start + i / a.rate
            while True:
                left = due - time.perf_counter()
                if left <= 0:
                    break
                time.sleep(min(left, 0.01))
        for m in frame_messages(a.family, f):
            sock.sendto(m.dgram, dest)
            sent += 1
        if a.progress:
            print("sent %d" % f["frame"], flush=True)
    print(json.dumps({"datagrams": sent, "frames": len(frames)}), flush=True)


if __name__ == "__main__":
    sys.exit(main())
