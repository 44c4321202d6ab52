// SPDX-License-Identifier: MIT
// Storage: bytes owned on exactly one device, freed in the destructor (Open3D's Blob).
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/dtype.h"

namespace g2l {

/// CPU storage is 64-byte aligned; CUDA storage comes from cudaMalloc. Not copyable.
/// `version` counts in-place writes: autograd refuses to run a backward that saved a tensor
/// whose storage was modified afterwards.
class Storage {
public:
    /// Allocates nbytes on `device`; throws on failure or for CUDA in a CPU-only build.
    Storage(size_t nbytes, Device device);
    ~Storage();
    Storage(const Storage&) = delete;
    Storage& operator=(const Storage&) = delete;

    void* data() { return data_; }
    const void* data() const { return data_; }
    size_t nbytes() const { return nbytes_; }
    Device device() const { return device_; }

    uint64_t version() const { return version_; }
    void bump_version() { ++version_; }

    /// Bytes currently held by all CPU storages (for benchmarks and leak tests).
    static int64_t cpu_bytes_in_use();

private:
    void* data_ = nullptr;
    size_t nbytes_ = 0;
    Device device_;
    uint64_t version_ = 0;
};

}  // namespace g2l
