#!/bin/sh
# Regenerate the golden traces from an installed BehaviorTree.CPP 4.10 (see harness/README.md).
#
#   BTCPP_PREFIX=/path/to/btcpp/install tests/tree/conformance/regenerate.sh
#
# Builds only our harness (harness/, linked against BTCPP_PREFIX) in a temporary folder, then
# writes golden/NNN_name.trace for every trees/ and bad/ file, and golden/shipped/*.trace for
# every shipped tree under trees/ loaded with stub leaves from `chaser-bt export-model`.
# The generated trees (trees/2NN_gen_*.xml) come from generate.py: run it first when its cases change.
set -eu
: "${BTCPP_PREFIX:?set BTCPP_PREFIX to an installed BehaviorTree.CPP 4.10 prefix}"
HERE=$(cd "$(dirname "$0")" && pwd)
REPO=$(cd "$HERE/../../.." && pwd)
PYTHON=${PYTHON:-python3}
BUILD=$(mktemp -d)
trap 'rm -rf "$BUILD"' EXIT
cmake -S "$HERE/harness" -B "$BUILD" -DCMAKE_PREFIX_PATH="$BTCPP_PREFIX" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$BUILD" >/dev/null
HARNESS="$BUILD/conformance_harness"
export LD_LIBRARY_PATH="$BTCPP_PREFIX/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"

mkdir -p "$HERE/golden/bad" "$HERE/golden/shipped"
for tree in "$HERE"/trees/*.xml; do
  "$HARNESS" trace "$tree" > "$HERE/golden/$(basename "$tree" .xml).trace"
done
for tree in "$HERE"/bad/*.xml; do
  "$HARNESS" trace "$tree" > "$HERE/golden/bad/$(basename "$tree" .xml).trace"
done

# Shipped trees, with every registered node as a stub leaf (manifest from export-model).
"$PYTHON" -m chaser_bt.cli export-model -o "$BUILD/model.xml"
"$PYTHON" "$HERE/stub_manifest.py" "$BUILD/model.xml" > "$BUILD/manifest.txt"
for tree in "$REPO"/trees/*.xml "$REPO"/trees/subtrees/*.xml; do
  name=$(echo "${tree#"$REPO"/trees/}" | sed 's|/|__|g; s|\.xml$||')
  "$HARNESS" stubs "$BUILD/manifest.txt" "$tree" > "$HERE/golden/shipped/$name.trace"
done
# What the goldens were made from, so a test can tell when they are stale.
(cd "$HERE" && sha256sum trees/*.xml bad/*.xml) > "$HERE/golden/SOURCES.sha256"
(cd "$REPO" && sha256sum trees/*.xml trees/subtrees/*.xml) > "$HERE/golden/shipped/SOURCES.sha256"
echo "goldens written to $HERE/golden"
