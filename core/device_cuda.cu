// SPDX-License-Identifier: MIT
// CUDA runtime wrappers (compiled only with G2L_WITH_CUDA=ON).
#include <cuda_runtime.h>

#include "core/device_cuda.h"
#include "core/error.h"

#define G2L_CUDA_CHECK(expr)                                                          \
    do {                                                                              \
        const cudaError_t e_ = (expr);                                                \
        G2L_CHECK(e_ == cudaSuccess, #expr, ": ", cudaGetErrorString(e_));            \
    } while (0)

namespace g2l::cuda {

int device_count() {
    int n = 0;
    if (cudaGetDeviceCount(&n) != cudaSuccess) {
        cudaGetLastError();  // clear the sticky "no driver" error
        return 0;
    }
    return n;
}

void* malloc_device(size_t nbytes, int index) {
    G2L_CUDA_CHECK(cudaSetDevice(index));
    void* p = nullptr;
    const cudaError_t e = cudaMalloc(&p, nbytes ? nbytes : 1);
    G2L_CHECK(e == cudaSuccess, "cudaMalloc of ", nbytes, " bytes on cuda:", index, " failed: ",
              cudaGetErrorString(e));
    return p;
}

void free_device(void* p) noexcept { cudaFree(p); }

void copy_host_to_device(void* dst, const void* src, size_t n) {
    G2L_CUDA_CHECK(cudaMemcpy(dst, src, n, cudaMemcpyHostToDevice));
}
void copy_device_to_host(void* dst, const void* src, size_t n) {
    G2L_CUDA_CHECK(cudaMemcpy(dst, src, n, cudaMemcpyDeviceToHost));
}
void copy_device_to_device(void* dst, const void* src, size_t n) {
    G2L_CUDA_CHECK(cudaMemcpy(dst, src, n, cudaMemcpyDeviceToDevice));
}
void memset_zero(void* p, size_t n) { G2L_CUDA_CHECK(cudaMemset(p, 0, n)); }

template <class T>
__global__ void accumulate_kernel(T* dst, const T* src, long long n) {
    const long long i = (long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) dst[i] += src[i];
}

template <class T>
static void accumulate(T* dst, const T* src, long long n) {
    if (n == 0) return;
    const int threads = 256;
    const long long blocks = (n + threads - 1) / threads;
    accumulate_kernel<T><<<(unsigned)blocks, threads>>>(dst, src, n);
    G2L_CUDA_CHECK(cudaGetLastError());
}
void accumulate_f32(float* dst, const float* src, long long n) { accumulate(dst, src, n); }
void accumulate_f64(double* dst, const double* src, long long n) { accumulate(dst, src, n); }

}  // namespace g2l::cuda
