// SPDX-License-Identifier: MIT
// Small helpers shared by the op tests (test_elementwise / reduce / softmax / loss / shape /
// dropout / conv2d / pool2d / upsample).
#pragma once

#include "testing.h"
#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <functional>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/tensor.h"

namespace g2l::testing::opsa {

/// Any float tensor's values as doubles.
inline std::vector<double> values(const Tensor& t) { return t.to(DType::F64).to_vector<double>(); }

/// f64 tensor from values and shape (test inputs).
inline Tensor f64(const std::vector<double>& v, const Shape& s) {
    return Tensor::from_vector<double>(v, s);
}

/// i32 tensor from values and shape (indices, labels).
inline Tensor i32(const std::vector<int32_t>& v, const Shape& s) {
    return Tensor::from_vector<int32_t>(v, s);
}

/// Element-wise |a - b| <= tol (sizes must match).
inline void require_close(const std::vector<double>& a, const std::vector<double>& b,
                          double tol = 1e-12) {
    REQUIRE(a.size() == b.size());
    for (size_t i = 0; i < a.size(); ++i) {
        INFO("index " << i << ": " << a[i] << " vs " << b[i]);
        REQUIRE(std::fabs(a[i] - b[i]) <= tol);
    }
}

/// Runs f with OpenMP limited to n threads (no-op limit without OpenMP), restoring the default.
inline void with_threads(int n, const std::function<void()>& f) {
#ifdef _OPENMP
    const int prev = omp_get_max_threads();
    omp_set_num_threads(n);
    f();
    omp_set_num_threads(prev);
#else
    // Without OpenMP a "1 vs 2 threads" comparison compares a run with itself: skip loudly.
    testing::mark_skipped("built without OpenMP: thread-count independence not checked");
    (void)n;
    f();
#endif
}

/// Bitwise equality of two tensors' bytes (same shape and dtype).
inline bool bitwise_equal(const Tensor& a, const Tensor& b) {
    return a.shape() == b.shape() && a.dtype() == b.dtype() &&
           std::memcmp(a.data(), b.data(), a.nbytes()) == 0;
}

}  // namespace g2l::testing::opsa
