// SPDX-License-Identifier: MIT
// CUDA entry points for builds without CUDA: every call throws, device_count() is 0.
#ifndef G2L_WITH_CUDA
#include "core/device_cuda.h"
#include "core/error.h"

namespace g2l::cuda {

namespace {
[[noreturn]] void no_cuda(const char* what) {
    G2L_CHECK(false, what, ": g2l was built without CUDA (G2L_WITH_CUDA=OFF); rebuild with "
                     "-DG2L_WITH_CUDA=ON or use device cpu");
}
}  // namespace

int device_count() { return 0; }
void* malloc_device(size_t, int) { no_cuda("cuda::malloc_device"); }
// Called from Storage's destructor, so it must not throw; nothing can reach it anyway because
// malloc_device() always throws in this build.
void free_device(void*) noexcept {}
void copy_host_to_device(void*, const void*, size_t) { no_cuda("cuda::copy_host_to_device"); }
void copy_device_to_host(void*, const void*, size_t) { no_cuda("cuda::copy_device_to_host"); }
void copy_device_to_device(void*, const void*, size_t) { no_cuda("cuda::copy_device_to_device"); }
void accumulate_f32(float*, const float*, long long) { no_cuda("cuda::accumulate_f32"); }
void accumulate_f64(double*, const double*, long long) { no_cuda("cuda::accumulate_f64"); }
void memset_zero(void*, size_t) { no_cuda("cuda::memset_zero"); }

}  // namespace g2l::cuda
#endif
