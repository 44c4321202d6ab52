#!/usr/bin/env bash
# Fails unless every op of nn/ reaches its kernels through the one dispatch point of kernels/
# (kernels/dispatch.h, docs/architecture.md "Dispatch"):
#   - nn/ calls no *_cpu kernel directly (the CPU inference engine nn/models/g2l_engine.cpp,
#     which works on its own preallocated host buffers, is the one exception);
#   - no op checks "CPU only" by itself (require_cpu / dispatch_float are gone);
#   - every tensor that nn/ allocates names a device (a line that allocates on the host on
#     purpose -- module construction, inputs filled from host data -- says so with "// host").
set -u
root=${1:-.}
status=0
fail() { echo "$1"; echo "$2"; status=1; }
hits=$(grep -rnE 'kernels::[a-z0-9_]+_cpu *[<(]' "$root/nn" --include='*.cpp' --include='*.h' \
       | grep -v 'nn/models/g2l_engine.cpp' || true)
[ -n "$hits" ] && fail "nn/ calls CPU kernels directly (use the kernels/ entry point):" "$hits"
hits=$(grep -rnE '\b(require_cpu|dispatch_float)\b' "$root/core" "$root/kernels" "$root/nn" \
       "$root/train" "$root/infer" --include='*.cpp' --include='*.h' --include='*.cu' || true)
[ -n "$hits" ] && fail "per-op device checks outside kernels/dispatch.h:" "$hits"
hits=$(grep -rnE 'Tensor::(empty|zeros|ones|full)\(' "$root/nn" --include='*.cpp' --include='*.h' \
       | grep -v 'nn/models/g2l_engine.cpp' | grep -v 'device()' | grep -v '// host' || true)
[ -n "$hits" ] && fail "allocations in nn/ without a device:" "$hits"
[ $status -eq 0 ] && echo "dispatch ok"
exit $status
