#!/usr/bin/env bash
# Fails if a layer includes a layer above it (docs/architecture.md):
#   core <- kernels <- nn <- {train, infer};  core <- geometry <- {nn, data}; data <- train;
#   apps (command-line programs on the library) <- nothing; train/infer never include each other,
#   and infer (the embeddable library) includes neither data nor train.
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
check core kernels nn geometry data train infer
check kernels nn geometry data train infer
check nn data train infer
check geometry kernels nn data train infer
check data kernels nn train infer
check train infer
check infer train data apps
check train apps
check nn apps
[ $status -eq 0 ] && echo "layers ok"
exit $status
