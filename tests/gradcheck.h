// SPDX-License-Identifier: MIT
// Finite-difference gradient checks (double precision), dlib test_layer style:
// L = sum(f(x) * R) for a fixed random R; analytic dL/dx from backward() vs central differences.
#pragma once

#include <functional>
#include <vector>

#include "core/tensor.h"

namespace g2l::testing {

struct GradcheckOptions {
    double eps = 1e-6;
    double rtol = 1e-4;
    double atol = 1e-6;
    int max_checked = 4096;  ///< all elements up to this many, else `sampled` random indices
    int sampled = 512;
    uint64_t seed = 1234;
};

using TensorFn = std::function<Tensor(const std::vector<Tensor>&)>;

/// Checks d sum(f(inputs) * R) / d input for every F64 input that requires grad (the caller
/// marks them). f must be deterministic (re-seed any RNG inside f). Throws g2l::Error naming the
/// input, the flat index, and the analytic and numeric values on the first mismatch.
void gradcheck(const TensorFn& f, const std::vector<Tensor>& inputs,
               const GradcheckOptions& opt = {});

/// f64 tensor of `shape` with distinct non-zero values spaced >= min_gap apart, in random order
/// (inputs for max-pool / ReLU without ties). Values are centred around 0.
Tensor distinct_values(const Shape& shape, uint64_t seed, double min_gap = 1e-2);

/// max |a - b| over all elements (same shape; any float dtype, any device).
double max_abs_diff(const Tensor& a, const Tensor& b);

}  // namespace g2l::testing
