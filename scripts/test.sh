#!/usr/bin/env bash
# Runs every test of treemocap, installing first the third-party peers the
# tests talk to (Python packages from PyPI, node packages from npm). A fresh
# machine needs only the Rust toolchain, Python 3 with pip, and node with npm.
set -euo pipefail
cd "$(dirname "$0")/.."

# The live page's browser tests (tests/it/live_view.rs) drive Debian's
# Chromium headless; playwright-core (npm, below) only talks to it and
# downloads no browser of its own.
if ! command -v chromium >/dev/null 2>&1; then
  echo "== installing Debian's chromium (browser tests of the live page)"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
fi
if [ -s tests/peers/requirements.txt ]; then
  echo "== installing Python test peers (tests/peers/requirements.txt)"
  python3 -m pip install --quiet --disable-pip-version-check -r tests/peers/requirements.txt
fi
if [ -f tests/peers/package.json ]; then
  echo "== installing node test peers (tests/peers/package.json)"
  if [ -f tests/peers/package-lock.json ]; then
    npm ci --prefix tests/peers --no-audit --no-fund --loglevel=error
  else
    npm install --prefix tests/peers --no-audit --no-fund --loglevel=error
  fi
fi

# tcpdump records our own NatNet server and client on loopback for the
# capture (pcap) tests in tests/it/natnet_pcap.rs. Debian's package; apt is
# shared with other jobs on the machine, hence the lock.
if ! command -v tcpdump >/dev/null; then
  echo "== installing tcpdump (NatNet capture tests)"
  flock /tmp/apt.lock apt-get update -qq
  flock /tmp/apt.lock apt-get install -y -qq tcpdump >/dev/null
fi

# animate (issue 13): the animated tree.glb is played by three.js in headless
# Chromium and imported by Blender in background mode, both Debian's packages
# (Blender's glTF importer needs numpy from Debian too). Blender is ~220 MB and
# installs in about 2 minutes; it is skipped when already there.
debs=()
command -v chromium >/dev/null || debs+=(chromium)
command -v blender >/dev/null || debs+=(blender)
dpkg -s python3-numpy >/dev/null 2>&1 || debs+=(python3-numpy)
if [ ${#debs[@]} -gt 0 ]; then
  echo "== installing Debian test peers: ${debs[*]}"
  flock /tmp/apt.lock apt-get update -qq
  flock /tmp/apt.lock apt-get install -y -qq "${debs[@]}" >/dev/null
fi

echo "== cargo test"
cargo test --all-targets "$@"
