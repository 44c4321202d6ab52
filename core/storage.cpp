// SPDX-License-Identifier: MIT
#include "core/storage.h"

#include <atomic>
#include <cstdlib>
#include <new>

#include "core/device_cuda.h"
#include "core/error.h"

namespace g2l {

namespace {
std::atomic<int64_t> g_cpu_bytes{0};
constexpr size_t kAlign = 64;
}  // namespace

Storage::Storage(size_t nbytes, Device device) : nbytes_(nbytes), device_(device) {
    if (device.is_cpu()) {
        // aligned_alloc needs a size that is a multiple of the alignment (and > 0).
        const size_t rounded = ((nbytes + kAlign - 1) / kAlign) * kAlign;
        data_ = std::aligned_alloc(kAlign, rounded ? rounded : kAlign);
        G2L_CHECK(data_ != nullptr, "out of memory allocating ", nbytes, " bytes on cpu");
        g_cpu_bytes += int64_t(nbytes);
    } else {
        data_ = cuda::malloc_device(nbytes, device.index);
    }
}

Storage::~Storage() {
    if (device_.is_cpu()) {
        std::free(data_);
        g_cpu_bytes -= int64_t(nbytes_);
    } else {
        cuda::free_device(data_);
    }
}

int64_t Storage::cpu_bytes_in_use() { return g_cpu_bytes.load(); }

}  // namespace g2l
