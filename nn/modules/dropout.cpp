// SPDX-License-Identifier: MIT
#include <cstring>

#include "nn/modules/layers.h"
#include "nn/ops/dropout.h"

namespace g2l::nn {

Dropout::Dropout(double p_, uint64_t seed) : p(p_) {
    G2L_CHECK(p >= 0 && p < 1, "Dropout: p must be in [0, 1), got ", p);
    Rng rng(seed);
    const auto s = rng.state();
    // The stream state is a buffer, so checkpoints save it and a resumed run draws the exact
    // masks it would have drawn. Checkpoints store f32 / f64 / i32 only: 4 x u64 = 8 x i32.
    rng_state = Tensor::empty({8}, DType::I32);  // host: the Rng state lives on the CPU
    std::memcpy(rng_state.data(), s.data(), sizeof(s));
    register_buffer("rng_state", rng_state);
}

Tensor Dropout::forward(const Tensor& x) {
    if (!is_training() || p == 0) return x;
    std::array<uint64_t, 4> s;
    std::memcpy(s.data(), rng_state.data(), sizeof(s));
    Rng rng;
    rng.set_state(s);
    Tensor y = dropout(x, p, true, rng);
    const auto ns = rng.state();
    std::memcpy(rng_state.data(), ns.data(), sizeof(ns));
    // Written through memcpy: bump the version by hand like any other in-place write.
    rng_state.impl()->storage->bump_version();
    return y;
}

}  // namespace g2l::nn
