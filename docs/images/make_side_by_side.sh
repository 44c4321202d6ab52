#!/usr/bin/env bash
# Rebuilds docs/images/renderer_real_vs_synthetic.jpg: frame 000001 of ../shared/data/ycbv
# train_real/000001 beside frame 1 of the scene settings before (configs/ycbv_sim2real.json at
# commit e9eb550: random poses, tilted plane) and after (the resting pose mode of the current
# config). Needs ImageMagick (apt-get install imagemagick; documentation only).
set -euo pipefail
cd "$(dirname "$0")/../.."
T=$(mktemp -d)
git show e9eb550:configs/ycbv_sim2real.json | python3 -c "import json,sys; json.dump(json.load(sys.stdin)['data']['train'][0]['scene'], open('$T/before.json','w'))"
python3 -c "import json; json.dump(json.load(open('configs/ycbv_sim2real.json'))['data']['train'][0]['scene'], open('$T/after.json','w'))"
for m in before after; do
    build/apps/g2l_render --models ../shared/data/ycbv/models --out "$T/$m" --frames 3 --config "$T/$m.json" --threads 1 >/dev/null
done
R=../shared/data/ycbv/train_real/000001
dep() { /usr/bin/convert "$1" -level 4000,14000 -negate -fill black -opaque white "$2"; }
dep $R/depth/000001.png "$T/real_d.png"
dep "$T/before/train_synt/000000/depth/000001.png" "$T/before_d.png"
dep "$T/after/train_synt/000000/depth/000001.png" "$T/after_d.png"
/usr/bin/montage -label 'real RGB' $R/rgb/000001.png -label 'real depth' "$T/real_d.png" \
    -label 'before (random poses) RGB' "$T/before/train_synt/000000/rgb/000001.png" \
    -label 'before depth' "$T/before_d.png" \
    -label 'after (resting) RGB' "$T/after/train_synt/000000/rgb/000001.png" \
    -label 'after depth' "$T/after_d.png" \
    -tile 2x3 -geometry 320x240+4+4 -pointsize 14 "$T/sbs.png"
/usr/bin/convert "$T/sbs.png" -quality 82 docs/images/renderer_real_vs_synthetic.jpg
rm -rf "$T"
