#!/usr/bin/env bash
# Vendors three.js from the npm registry into src/serve/web/three/ (the live
# view's 3D library; the binary embeds these files). Usage: scripts/vendor_three.sh 0.187.0
set -euo pipefail
cd "$(dirname "$0")/.."
version="${1:?usage: scripts/vendor_three.sh VERSION}"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
(cd "$tmp" && npm pack --silent "three@$version" >/dev/null && tar xzf three-*.tgz)
src="$tmp/package"
dst=src/serve/web/three
mkdir -p "$dst/addons/loaders" "$dst/addons/controls" "$dst/addons/utils"
cp "$src/LICENSE" "$src/build/three.module.js" "$src/build/three.core.js" "$dst/"
cp "$src/examples/jsm/loaders/GLTFLoader.js" "$dst/addons/loaders/"
cp "$src/examples/jsm/controls/OrbitControls.js" "$dst/addons/controls/"
cp "$src/examples/jsm/utils/BufferGeometryUtils.js" "$src/examples/jsm/utils/SkeletonUtils.js" "$dst/addons/utils/"
sed -i "s/version \*\*[0-9.]*\*\*/version **$version**/" "$dst/VENDOR.md"
echo "three $version vendored into $dst; update the revision in VENDOR.md if it changed"
