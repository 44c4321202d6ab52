#!/usr/bin/env bash
# g2l entry point. Installs missing Debian packages (as root), builds incrementally, runs.
#   ./g2l.sh demo [args]   the main job end to end on the embedded data: the shipped detector,
#                          pose model and refinement on the shipped real frames (no ground-truth
#                          box), after a short G2L-Net training on renders of the shipped meshes
#   ./g2l.sh toy           the engine's smallest job: a PointNet classifier on generated clouds
#   ./g2l.sh test          build everything and run the whole CTest suite
#   ./g2l.sh build [--target T]  build only (Release, ./build): everything, or the targets named
#   ./g2l.sh bench [args]  g2l_bench (engine speed on G2L-Net shapes)
#   ./g2l.sh deps          install the Debian packages only
set -euo pipefail
cd "$(dirname "$0")"

PKGS="cmake ninja-build g++ pkg-config libeigen3-dev libopencv-dev nlohmann-json3-dev catch2
      libnanoflann-dev libcli11-dev libomp-dev libopenmpi-dev openmpi-bin"
BUILD_DIR=${G2L_BUILD_DIR:-build}
JOBS=${G2L_JOBS:-$(nproc)}

deps() {
    local missing=""
    for p in $PKGS; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
    done
    [ -z "$missing" ] && return 0
    if [ "$(id -u)" -ne 0 ]; then
        echo "g2l.sh: missing Debian packages:$missing (run as root, or: sudo apt-get install$missing)" >&2
        exit 1
    fi
    echo "g2l.sh: installing$missing"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $missing >/dev/null
}

# build [--target T ...]: configure (Release) and build everything, or only the targets named.
build() {
    deps
    cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
    cmake --build "$BUILD_DIR" -j "$JOBS" "$@"
}

cmd=${1:-help}
[ $# -gt 0 ] && shift
case "$cmd" in
    deps) deps ;;
    build) build "$@" ;;
    test)
        build
        cd "$BUILD_DIR"
        ctest --output-on-failure --timeout 900 "$@"
        ;;
    demo)
        # 1. Trains G2L-Net on synthetic renders of the two YCB-Video meshes shipped in
        #    tests/data/ycbv_mini (configs/demo_cpu.json, ~1-2 min on 2 cores) and evaluates it
        #    with ground-truth boxes on the two REAL YCB-Video frames shipped there.
        # 2. The main job as a user runs it, no ground-truth box: the shipped depth detector
        #    (models/ycbv_detector.g2l) finds the objects, the shipped pose model
        #    (models/ycbv_sim2real.g2l) poses them, each pose refined against its mesh.
        build --target g2l_train --target g2l_eval
        run_dir=${G2L_DEMO_RUN:-runs/demo}
        rm -rf "$run_dir"
        "./$BUILD_DIR/apps/g2l_train" --config configs/demo_cpu.json --set "run_dir=$run_dir" "$@"
        "./$BUILD_DIR/apps/g2l_eval" --checkpoint "$run_dir/last.g2l" --config configs/demo_cpu.json \
            --json "$run_dir/eval.json"
        echo "== the main job: detector -> pose -> refinement on the real fixture frames (no ground-truth box)"
        "./$BUILD_DIR/apps/g2l_eval" --checkpoint models/ycbv_sim2real.g2l \
            --detector models/ycbv_detector.g2l --boxes det --root tests/data/ycbv_mini \
            --split train_real --json "$run_dir/eval_pipeline.json" --vis "$run_dir/vis"
        pic=$(ls "$run_dir"/vis/0*.png | head -n 1)
        echo
        echo "g2l.sh demo:"
        echo "  trained   G2L-Net (narrow width) on renders of the 2 fixture meshes: $run_dir (config, logs, checkpoints)"
        echo "  measured  the shipped detector + pose model + refinement on the 2 real YCB-Video frames"
        echo "            of tests/data/ycbv_mini (table above; $run_dir/eval_pipeline.json)"
        echo "  picture   yellow: the detector's box, green: ground truth, blue: a reported pose with"
        echo "            its score (the probability that it is right, from the depth verification),"
        echo "            red: a rejected hypothesis with the reason (duplicate, overlap, low score)"
        echo "$pic"
        ;;
    toy)
        build
        exec "./$BUILD_DIR/apps/g2l_demo" "$@"
        ;;
    bench)
        build
        exec "./$BUILD_DIR/apps/g2l_bench" "$@"
        ;;
    help|-h|--help)
        sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'
        ;;
    *)
        echo "g2l.sh: unknown command '$cmd'" >&2
        sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//' >&2
        exit 2
        ;;
esac
