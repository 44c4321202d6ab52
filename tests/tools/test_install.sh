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
# The installed programs start as they are (their RPATH finds libg2l.so.0 relative to them).
for tool in g2l_infer g2l_bench; do
    [ -x "$tmp/prefix/bin/$tool" ] || { echo "FAIL: bin/$tool not installed"; exit 1; }
    env -u LD_LIBRARY_PATH "$tmp/prefix/bin/$tool" --help > "$tmp/$tool.help" 2>&1 \
        || { echo "FAIL: the installed $tool does not start:"; cat "$tmp/$tool.help"; exit 1; }
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
# The pose, pinned against the fixture's ground truth (scene_gt.json, image 1, object 8) near
# the values measured 2026-12-04 with the networks alone (the example gives no meshes, so no
# refinement): translation error 6.6 mm, rotation error 153.4 deg (the networks alone do not
# find this box's rotation on real depth; the refinement does, docs/results.md). A change to
# the shipped model, the crop or the engine moves these and fails here.
echo "$out" | awk '
  /^R = \[/ { gsub(/[][;R=]/, " "); n = split($0, r, " "); }
  /^t = \[/ { gsub(/[][t=m]/, " "); split($0, t, " "); }
  END {
    split("0.023388461238133155 -0.6309259097300829 0.7754917946168369 0.9331277258632086 -0.2646079492419404 -0.24342225948802707 0.35878191775210355 0.7293255835844041 0.5825453120678373", g, " ");
    split("-30.632231140806272 -8.03169956929697 592.6409962060181", tg, " ");
    if (n != 9) { print "FAIL: no R printed"; exit 1 }
    tr = 0; for (i = 1; i <= 9; i++) tr += r[i] * g[i];
    c = (tr - 1) / 2; if (c > 1) c = 1; if (c < -1) c = -1;
    rot = atan2(sqrt(1 - c * c), c) * 180 / 3.14159265358979;
    dt = sqrt((t[1] - tg[1])^2 + (t[2] - tg[2])^2 + (t[3] - tg[3])^2);
    det = r[1] * (r[5] * r[9] - r[6] * r[8]) - r[2] * (r[4] * r[9] - r[6] * r[7]) + r[3] * (r[4] * r[8] - r[5] * r[7]);
    printf "pose vs ground truth: translation error %.1f mm, rotation error %.1f deg, det(R) %.6f\n", dt, rot, det;
    if (dt > 8.6) { print "FAIL: translation error above the measured 6.6 mm + 2"; exit 1 }
    if (rot < 148.4 || rot > 158.4) { print "FAIL: rotation error moved from the measured 153.4 deg (+-5)"; exit 1 }
    if (det < 0.9999 || det > 1.0001) { print "FAIL: R is not a rotation"; exit 1 }
  }' || exit 1
# A box outside the image: status, exit 1; a missing model: exit 2 with the file named.
set +e
"$tmp/ex/pose_from_files" "$model" "$frame" 1066.778 1067.487 312.9869 241.3109 0.1 8 900 132 10 10 > "$tmp/o.txt"; rc=$?
grep -q "box outside image" "$tmp/o.txt" && [ $rc -eq 1 ] || { echo "FAIL: outside box rc=$rc"; cat "$tmp/o.txt"; exit 1; }
"$tmp/ex/pose_from_files" "$tmp/none.g2l" "$frame" 1066.778 1067.487 312.9869 241.3109 0.1 8 186 132 139 191 2> "$tmp/e.txt"; rc=$?
grep -q "none.g2l" "$tmp/e.txt" && [ $rc -eq 2 ] || { echo "FAIL: missing model rc=$rc"; cat "$tmp/e.txt"; exit 1; }
echo "install + example: ok"
