// SPDX-License-Identifier: MIT
// Thread-count control without including omp.h above kernels/ (and without OpenMP builds).
#pragma once

namespace g2l {

/// Threads the CPU kernels use (OpenMP's max threads; 1 without OpenMP).
int num_threads();
/// Sets the threads the CPU kernels use (n >= 1). Results never depend on it.
void set_num_threads(int n);

}  // namespace g2l
