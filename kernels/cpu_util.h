// SPDX-License-Identifier: MIT
// Small helpers shared by the CPU kernels.
#pragma once

#include <cstdint>

namespace g2l::kernels {

/// ceil(a / b) for a >= 0, b > 0.
inline int64_t ceil_div(int64_t a, int64_t b) { return (a + b - 1) / b; }

/// Sums over a row in kLanes independent accumulators, added up in a fixed order at the end.
/// A plain `s += x[i]` is one dependency chain (one add latency, ~4 cycles, per element) that
/// the compiler may not reorder; kLanes chains vectorize. The order depends on the row length
/// only, so results stay bitwise the same for any thread count.
constexpr int kLanes = 16;

template <class Acc>
struct Lanes {
    Acc v[kLanes] = {};

    /// v[i % kLanes] += term(i) for i in [0, n).
    template <class F>
    void add(int64_t n, F&& term) {
        int64_t i = 0;
        for (; i + kLanes <= n; i += kLanes)
            for (int l = 0; l < kLanes; ++l) v[l] += term(i + l);
        for (int l = 0; i < n; ++i, ++l) v[l] += term(i);
    }

    /// The lanes added pairwise (a fixed tree).
    Acc total() const {
        Acc t[kLanes];
        for (int l = 0; l < kLanes; ++l) t[l] = v[l];
        for (int w = kLanes / 2; w >= 1; w /= 2)
            for (int l = 0; l < w; ++l) t[l] += t[l + w];
        return t[0];
    }
};

}  // namespace g2l::kernels
