// SPDX-License-Identifier: MIT
// The thin host-side CUDA runtime layer used by Storage. Every function exists in every build:
// without G2L_WITH_CUDA they throw "built without CUDA (G2L_WITH_CUDA=OFF)" (device_count()
// returns 0), so callers never need #ifdefs and nothing falls back to the CPU silently.
#pragma once

#include <cstddef>

namespace g2l::cuda {

/// Number of visible CUDA devices (0 without CUDA or without a driver).
int device_count();
/// cudaMalloc on device `index`; throws with the size and the CUDA error.
void* malloc_device(size_t nbytes, int index);
/// cudaFree; never throws (used in destructors).
void free_device(void* p) noexcept;
/// Synchronous copies.
void copy_host_to_device(void* dst, const void* src, size_t nbytes);
void copy_device_to_host(void* dst, const void* src, size_t nbytes);
void copy_device_to_device(void* dst, const void* src, size_t nbytes);
/// dst[i] += src[i] for n floats / doubles on the device (gradient accumulation).
void accumulate_f32(float* dst, const float* src, long long n);
void accumulate_f64(double* dst, const double* src, long long n);
/// Sets n bytes to zero.
void memset_zero(void* p, size_t nbytes);

}  // namespace g2l::cuda
