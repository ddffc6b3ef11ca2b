"""Drives PyPI `natnet` 0.3.0 (a third-party NatNet client) against a server
and prints every frame it decoded as one JSON line, floats as the u64 bit
patterns of the doubles Python holds (exact, no decimal round trip), so tests/natnet_peers.rs can compare them bit for bit with the recording.

usage: natnet_pypi_client.py SERVER_IP COMMAND_PORT DATA_PORT FRAMES TIMEOUT_S
"""
import json
import struct
import sys
import time

from natnet import NatNetClient

server, command_port, data_port, want, timeout = sys.argv[1:6]
frames = []
client = NatNetClient(
    server_ip_address=server,
    local_ip_address="127.0.0.1",
    command_port=int(command_port),
    data_port=int(data_port),
    use_multicast=False,
)
client.on_data_frame_received_event.handlers.append(frames.append)
client.connect(timeout=5.0)
print(json.dumps({"server": client.server_info.application_name,
                  "version": str(client.protocol_version)}), flush=True)
client.run_async()
deadline = time.time() + float(timeout)
while len(frames) < int(want) and time.time() < deadline:
    time.sleep(0.05)
client.shutdown()
def bits(x):
    return struct.unpack("<Q", struct.pack("<d", x))[0]


for f in frames:
    print(json.dumps({
        "frame": f.prefix.frame_number,
        "labeled": [[bits(c) for c in m.pos] for m in f.labeled_markers],
        "unlabeled": [m.unlabeled for m in f.labeled_markers],
        "timestamp": bits(f.suffix.timestamp),
    }))
