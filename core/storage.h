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
///
/// Large CPU blocks (>= 256 KiB) are recycled: a freed block waits in a process-wide cache and
/// the next allocation of the same size (up to 1/8 larger) takes it back, so a training step or
/// a frame that allocates what the previous one did touches no fresh pages (the kernel's page
/// faults and zeroing cost 20-40 % of a [8, 1024, 1500] layer otherwise). The cache holds at
/// most `cpu_cache_limit()` bytes (default 1 GiB, environment G2L_CPU_CACHE_MB; 0 disables it),
/// evicting its oldest blocks first; it is off under AddressSanitizer so that a use after free
/// is still caught. A recycled block holds stale bytes, like any malloc'd block.
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
    /// Bytes of freed CPU blocks waiting in the cache for reuse.
    static int64_t cpu_bytes_cached();
    static int64_t cpu_cache_limit();
    /// Sets the cache's limit in bytes (0 disables it); blocks above the limit are freed now.
    static void set_cpu_cache_limit(int64_t bytes);
    /// Frees every cached block.
    static void release_cpu_cache();
    /// Fills every recycled block with 0xFF bytes (NaN floats) before handing it out, so that
    /// code which wrongly reads memory it never wrote shows NaN; the tests turn it on.
    static void set_cpu_cache_poison(bool on);

private:
    void* data_ = nullptr;
    size_t nbytes_ = 0;
    size_t capacity_ = 0;  // CPU: the block's real size (a recycled block may be larger)
    Device device_;
    uint64_t version_ = 0;
};

}  // namespace g2l
