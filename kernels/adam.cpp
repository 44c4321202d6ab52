// SPDX-License-Identifier: MIT
// Adam: the dispatch point (kernels/dispatch.h); the CPU kernel is in adam_cpu.cpp.
#include "kernels/adam.h"

#include "kernels/dispatch.h"

namespace g2l::kernels {

void adam_update(Tensor& p, const Tensor& g, Tensor& m, Tensor& v, const AdamArgs& a) {
    dispatch("adam_update", {&p, &g, &m, &v}, [&](auto tag) {
        using T = decltype(tag);
        adam_update_cpu<T>(p.data<T>(), g.data<T>(), m.data<T>(), v.data<T>(), p.numel(), a);
    });
    // The kernel writes through a raw pointer, bypassing copy_(), so the version is bumped here:
    // a graph that saved p before the step then refuses to run backward with the new values.
    p.impl()->storage->bump_version();
}

}  // namespace g2l::kernels
