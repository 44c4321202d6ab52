#!/usr/bin/env bash
# g2l entry point. Installs missing Debian packages (as root), builds incrementally, runs.
#   ./g2l.sh demo [args]   the main job end to end on the embedded data (see --help of g2l_demo)
#   ./g2l.sh test          build everything and run the whole CTest suite
#   ./g2l.sh build         build only (Release, ./build)
#   ./g2l.sh bench [args]  g2l_bench (engine speed on G2L-Net shapes)
#   ./g2l.sh deps          install the Debian packages only
set -euo pipefail
cd "$(dirname "$0")"

PKGS="cmake ninja-build g++ pkg-config libeigen3-dev libopencv-dev nlohmann-json3-dev catch2
      libnanoflann-dev libcli11-dev libomp-dev"
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

build() {
    deps
    cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
    cmake --build "$BUILD_DIR" -j "$JOBS"
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
        build
        exec "./$BUILD_DIR/train/g2l_demo" "$@"
        ;;
    bench)
        build
        exec "./$BUILD_DIR/train/g2l_bench" "$@"
        ;;
    help|-h|--help)
        sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'
        ;;
    *)
        echo "g2l.sh: unknown command '$cmd'" >&2
        sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//' >&2
        exit 2
        ;;
esac
