#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Regenerates tests/data/ycbv_mini, the small BOP fixture used by tests/data/test_bop.cpp, from
# the YCB-Video subset in ../shared/data/ycbv (MIT licence; LICENSE is copied along).
#
#   tests/data/make_ycbv_mini.sh [SHARED_YCBV_DIR]      (default: <repo>/../shared/data/ycbv)
#
# Content: frames 1 and 11 of train_real/000000 (rgb, depth, mask_visib, scene_gt.json,
# scene_camera.json, scene_gt_info.json restricted to those frames), models 8 and 14 only
# (obj_000008.ply, obj_000014.ply, models_info.json restricted to them), camera.json,
# obj_names.json and LICENSE. Scene 000000 also shows object 21; its instances (always the last,
# index 2) are dropped from the JSON files and its masks are not copied, so every instance has a
# model. PNGs are re-encoded losslessly (same filtered scanlines, zlib level 9) with Python's
# standard library only; pixel values are unchanged. Needs: bash, jq, python3. Not run by CI.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
src=${1:-$here/../../../shared/data/ycbv}
out=$here/ycbv_mini
frames=(1 11)
objs='[8, 14]'
scene=train_real/000000

[ -f "$src/models/models_info.json" ] || { echo "no YCB-V data at $src" >&2; exit 1; }
rm -rf "$out"
mkdir -p "$out/models" "$out/$scene/rgb" "$out/$scene/depth" "$out/$scene/mask_visib"

cp "$src/LICENSE" "$src/camera.json" "$src/obj_names.json" "$out/"
for o in 8 14; do cp "$src/models/$(printf 'obj_%06d.ply' $o)" "$out/models/"; done
chmod -R u+w "$out"
jq --argjson objs "$objs" 'with_entries(select(.key | tonumber | IN($objs[])))' \
    "$src/models/models_info.json" > "$out/models/models_info.json"

keys=$(printf '"%s",' "${frames[@]}"); keys="[${keys%,}]"
# scene_gt.json: keep the frames, and in each frame the instances of the kept objects. The
# dropped ones must be trailing so that the k of mask_visib/<im>_<k>.png stays valid.
jq --argjson keys "$keys" --argjson objs "$objs" '
    with_entries(select(.key | IN($keys[])))
    | map_values(if ([.[] | .obj_id | IN($objs[])] | . == (sort | reverse))
                 then map(select(.obj_id | IN($objs[])))
                 else error("kept instances not leading") end)' \
    "$src/$scene/scene_gt.json" > "$out/$scene/scene_gt.json"
jq --argjson keys "$keys" 'with_entries(select(.key | IN($keys[])))' \
    "$src/$scene/scene_camera.json" > "$out/$scene/scene_camera.json"
# scene_gt_info.json: same frames, truncated to the number of kept instances per frame.
jq --argjson keys "$keys" --slurpfile gt "$out/$scene/scene_gt.json" '
    with_entries(select(.key | IN($keys[])) | .value = .value[0:($gt[0][.key] | length)])' \
    "$src/$scene/scene_gt_info.json" > "$out/$scene/scene_gt_info.json"

recompress() {  # recompress <in.png> <out.png>: lossless, the IDAT stream at zlib level 9
    python3 - "$1" "$2" <<'PY'
import struct, sys, zlib
data = open(sys.argv[1], "rb").read()
assert data[:8] == b"\x89PNG\r\n\x1a\n", sys.argv[1] + ": not a PNG"
chunks, i = [], 8
while i < len(data):
    n, = struct.unpack(">I", data[i:i + 4])
    chunks.append((data[i + 4:i + 8], data[i + 8:i + 8 + n]))
    i += 12 + n
idat = zlib.compress(zlib.decompress(b"".join(d for t, d in chunks if t == b"IDAT")), 9)
def chunk(t, d):
    return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
out = [data[:8]]
for t, d in chunks:
    if t == b"IDAT":
        if idat is not None:
            out.append(chunk(t, idat))
            idat = None
    else:
        out.append(chunk(t, d))
open(sys.argv[2], "wb").write(b"".join(out))
PY
}

for f in "${frames[@]}"; do
    im=$(printf '%06d' "$f")
    recompress "$src/$scene/rgb/$im.png" "$out/$scene/rgb/$im.png"
    recompress "$src/$scene/depth/$im.png" "$out/$scene/depth/$im.png"
    n=$(jq --arg k "$f" '.[$k] | length' "$out/$scene/scene_gt.json")
    for ((k = 0; k < n; ++k)); do
        m=$(printf '%s_%06d.png' "$im" "$k")
        recompress "$src/$scene/mask_visib/$m" "$out/$scene/mask_visib/$m"
    done
done
du -sh "$out"
