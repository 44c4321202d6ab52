#!/usr/bin/env bash
# Installs the build into a temporary prefix, builds examples/pose_from_files against the
# installed package (find_package(g2l)), runs it on a fixture frame with the installed model,
# and checks that the installed library exports only the public API.
set -euo pipefail
build=$1; src=$2
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" > "$tmp/install.log"
for f in include/g2l/pose_estimator.h share/g2l/models/ycbv_sim2real.g2l; do
    [ -f "$tmp/prefix/$f" ] || { echo "FAIL: $f not installed"; exit 1; }
done
lib=$(ls "$tmp"/prefix/lib*/libg2l.so 2>/dev/null | head -n1)
[ -n "$lib" ] || { echo "FAIL: libg2l.so not installed"; ls -R "$tmp/prefix"; exit 1; }
# Only g2l:: symbols (and inline std template instances) are exported: the engine is hidden.
leaked=$(nm -DC --defined-only "$lib" | awk '{ $1=""; $2=""; print }' | grep -v '^ *g2l::' | grep -v '^ *std::' | grep -v '^ *void std::' || true)
[ -z "$leaked" ] || { echo "FAIL: non-API symbols exported:"; echo "$leaked" | head; exit 1; }
nm -DC --defined-only "$lib" | grep -q 'g2l::PoseEstimator::estimate' || { echo "FAIL: estimate not exported"; exit 1; }
cmake -S "$src/examples/pose_from_files" -B "$tmp/ex" -DCMAKE_PREFIX_PATH="$tmp/prefix" \
      -DCMAKE_BUILD_TYPE=Release > "$tmp/configure.log" || { cat "$tmp/configure.log"; exit 1; }
cmake --build "$tmp/ex" > "$tmp/build.log" 2>&1 || { cat "$tmp/build.log"; exit 1; }
frame="$src/tests/data/ycbv_mini/train_real/000000/depth/000001.png"
model="$tmp/prefix/share/g2l/models/ycbv_sim2real.g2l"
out=$("$tmp/ex/pose_from_files" "$model" "$frame" 1066.778 1067.487 312.9869 241.3109 0.1 8 186 132 139 191)
echo "$out"
echo "$out" | grep -q "obj 8: ok" || { echo "FAIL: no pose"; exit 1; }
echo "$out" | grep -qE "^t = \[-?[0-9.]+ -?[0-9.]+ 5[0-9][0-9]\.[0-9]+\] mm" || { echo "FAIL: t not ~0.5-0.6 m"; exit 1; }
# A box outside the image: status, exit 1; a missing model: exit 2 with the file named.
set +e
"$tmp/ex/pose_from_files" "$model" "$frame" 1066.778 1067.487 312.9869 241.3109 0.1 8 900 132 10 10 > "$tmp/o.txt"; rc=$?
grep -q "box outside image" "$tmp/o.txt" && [ $rc -eq 1 ] || { echo "FAIL: outside box rc=$rc"; cat "$tmp/o.txt"; exit 1; }
"$tmp/ex/pose_from_files" "$tmp/none.g2l" "$frame" 1066.778 1067.487 312.9869 241.3109 0.1 8 186 132 139 191 2> "$tmp/e.txt"; rc=$?
grep -q "none.g2l" "$tmp/e.txt" && [ $rc -eq 2 ] || { echo "FAIL: missing model rc=$rc"; cat "$tmp/e.txt"; exit 1; }
echo "install + example: ok"
