#!/usr/bin/env bash
# Fails if a layer includes a layer above it (docs/architecture.md):
#   core <- kernels <- nn <- infer <- eval <- train <- tools <- apps;  core <- geometry <- {nn, data};
#   data <- {eval, train}; infer (the frame pipeline and the embeddable library) includes neither
#   data, eval, train nor tools; nothing includes apps.
set -u
root=${1:-.}
status=0
check() {  # check <dir> <forbidden include prefixes...>
    local dir=$1; shift
    [ -d "$root/$dir" ] || return 0
    for bad in "$@"; do
        hits=$(grep -rnE "#include +\"$bad/" "$root/$dir" --include='*.h' --include='*.cpp' --include='*.cu' --include='*.cuh' || true)
        if [ -n "$hits" ]; then
            echo "layer violation: $dir/ must not include $bad/:"; echo "$hits"; status=1
        fi
    done
}
check core kernels nn geometry data infer eval train tools apps
check kernels nn geometry data infer eval train tools apps
check nn data infer eval train tools apps
check geometry kernels nn data infer eval train tools apps
check data kernels nn infer eval train tools apps
check infer data eval train tools apps
check eval train tools apps
check train tools apps
check tools apps
[ $status -eq 0 ] && echo "layers ok"
exit $status
