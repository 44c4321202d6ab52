// SPDX-License-Identifier: MIT
// The data-parallel hook of the engine: what a differentiable op needs to know when the batch is
// split over several processes (train/distributed.h sets it; nn never depends on MPI).
// BatchNorm in training mode sums its per-channel statistics (forward) and gradient terms
// (backward) over the processes through `sum`; dropout draws its mask for the global batch and
// keeps this process's rows, so N processes x batch B/N compute what one process computes on
// batch B (to float rounding).
#pragma once

#include <cstdint>
#include <functional>

namespace g2l::nn {

struct DataParallel {
    /// Sums `n` doubles element-wise over every process, in place (every process gets the
    /// sum). Called by every process in the same order (collective).
    std::function<void(double* values, int64_t n)> sum;
    int64_t batch_offset = 0;  ///< index of this process's first sample in the global batch
    int64_t global_batch = 0;  ///< samples of the global batch (all processes)
};

/// The calling thread's active hook, or null (the default: one process, nothing is shared).
const DataParallel* data_parallel();

/// Makes `dp` the active hook of the calling thread while it lives (borrowed; must outlive the
/// guard). Used around a training step's forward and backward; validation and inference run
/// without it. Per thread, so that other threads (a prefetch thread, or the two "processes" of
/// tests/nn/test_data_parallel.cpp) are not affected.
class DataParallelGuard {
public:
    explicit DataParallelGuard(const DataParallel* dp);
    ~DataParallelGuard();
    DataParallelGuard(const DataParallelGuard&) = delete;
    DataParallelGuard& operator=(const DataParallelGuard&) = delete;

private:
    const DataParallel* previous_;
};

}  // namespace g2l::nn
