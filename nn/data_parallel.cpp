// SPDX-License-Identifier: MIT
#include "nn/data_parallel.h"

namespace g2l::nn {

namespace {
thread_local const DataParallel* g_active = nullptr;  // per thread: the step's thread
}  // namespace

const DataParallel* data_parallel() { return g_active; }

DataParallelGuard::DataParallelGuard(const DataParallel* dp) : previous_(g_active) {
    g_active = dp;
}

DataParallelGuard::~DataParallelGuard() { g_active = previous_; }

}  // namespace g2l::nn
