// SPDX-License-Identifier: MIT
#include "core/storage.h"

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <new>
#include <string>
#include <vector>

#include "core/device_cuda.h"
#include "core/error.h"

#if defined(__SANITIZE_ADDRESS__)
#define G2L_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define G2L_ASAN 1
#endif
#endif

namespace g2l {

namespace {
std::atomic<int64_t> g_cpu_bytes{0};
constexpr size_t kAlign = 64;
constexpr size_t kCacheMin = size_t(256) << 10;  // smaller blocks: malloc's own free lists
constexpr size_t kPage = 4096;                     // cached blocks are whole pages

size_t round_up(size_t n, size_t to) { return ((n + to - 1) / to) * to; }

// The recycling cache of large CPU blocks (see storage.h). Few blocks live here at once (one
// per distinct tensor of a step), so a linear scan is cheaper than the page faults it saves.
class BlockCache {
public:
    BlockCache() {
#ifdef G2L_ASAN
        // A recycled block is never returned to malloc, so ASan could not flag a use after free.
        limit_ = 0;
#else
        limit_ = int64_t(1) << 30;
        if (const char* e = std::getenv("G2L_CPU_CACHE_MB")) {
            char* end = nullptr;
            const long long mb = std::strtoll(e, &end, 10);
            G2L_CHECK(end != e && *end == '\0' && mb >= 0,
                      "G2L_CPU_CACHE_MB must be a whole number of MiB >= 0, got '", e, "'");
            limit_ = int64_t(mb) << 20;
        }
#endif
    }

    // A cached block of at least `bytes` and at most 1/8 more, or nullptr.
    void* take(size_t bytes, size_t* capacity) {
        std::lock_guard<std::mutex> lock(mu_);
        size_t best = blocks_.size();
        for (size_t i = 0; i < blocks_.size(); ++i) {
            const size_t c = blocks_[i].capacity;
            // The 1/8 cap keeps a small tensor from pinning a much larger block; among the blocks
            // that qualify, the smallest (best fit) wins.
            if (c >= bytes && c <= bytes + bytes / 8 &&
                (best == blocks_.size() || c < blocks_[best].capacity))
                best = i;
        }
        if (best == blocks_.size()) return nullptr;
        void* p = blocks_[best].p;
        *capacity = blocks_[best].capacity;
        cached_ -= int64_t(*capacity);
        blocks_.erase(blocks_.begin() + std::ptrdiff_t(best));
        if (poison_) std::memset(p, 0xFF, *capacity);
        return p;
    }

    // Keeps the block for reuse (evicting the oldest ones to stay within the limit), or frees it.
    void give(void* p, size_t capacity) {
        std::lock_guard<std::mutex> lock(mu_);
        // A block larger than the whole limit can never be cached (limit 0 disables the cache).
        if (int64_t(capacity) > limit_) {
            std::free(p);
            return;
        }
        // Make room first so the cache never exceeds its limit, even briefly.
        trim_locked(limit_ - int64_t(capacity));
        blocks_.push_back({p, capacity});
        cached_ += int64_t(capacity);
    }

    void trim(int64_t keep) {
        std::lock_guard<std::mutex> lock(mu_);
        trim_locked(keep);
    }
    void set_limit(int64_t bytes) {
        G2L_CHECK(bytes >= 0, "Storage::set_cpu_cache_limit: limit must be >= 0, got ", bytes);
        std::lock_guard<std::mutex> lock(mu_);
// Under ASan the limit stays 0 whatever is asked, for the reason given in the constructor.
#ifndef G2L_ASAN
        limit_ = bytes;
#endif
        trim_locked(limit_);
    }
    int64_t limit() {
        std::lock_guard<std::mutex> lock(mu_);
        return limit_;
    }
    int64_t cached() {
        std::lock_guard<std::mutex> lock(mu_);
        return cached_;
    }
    void set_poison(bool on) {
        std::lock_guard<std::mutex> lock(mu_);
        poison_ = on;
    }

private:
    struct Block {
        void* p;
        size_t capacity;
    };
    void trim_locked(int64_t keep) {  // oldest first: blocks_ is in the order they came back
        size_t n = 0;
        while (n < blocks_.size() && cached_ > keep) {
            std::free(blocks_[n].p);
            cached_ -= int64_t(blocks_[n].capacity);
            ++n;
        }
        blocks_.erase(blocks_.begin(), blocks_.begin() + std::ptrdiff_t(n));
    }

    std::mutex mu_;
    std::vector<Block> blocks_;
    int64_t cached_ = 0, limit_ = 0;
    bool poison_ = false;
};

BlockCache& cache() {
    static BlockCache* c = new BlockCache;  // never destroyed: storages may outlive statics
    return *c;
}
}  // namespace

Storage::Storage(size_t nbytes, Device device) : nbytes_(nbytes), device_(device) {
    if (device.is_cpu()) {
        // aligned_alloc needs a size that is a multiple of the alignment (and > 0).
        capacity_ = std::max(round_up(nbytes, kAlign), kAlign);
        if (capacity_ >= kCacheMin) {
            // Whole pages: requests that differ by a few bytes ask for the same capacity and can
            // share blocks.
            capacity_ = round_up(capacity_, kPage);
            // take() may hand back a somewhat larger block; capacity_ becomes its real size so
            // that the destructor returns it to the cache with the right size.
            data_ = cache().take(capacity_, &capacity_);
        }
        if (!data_) data_ = std::aligned_alloc(kAlign, capacity_);
        G2L_CHECK(data_ != nullptr, "out of memory allocating ", nbytes, " bytes on cpu");
        // Counts requested bytes (what tensors use), not capacity; the cache has its own count.
        g_cpu_bytes += int64_t(nbytes);
    } else {
        data_ = cuda::malloc_device(nbytes, device.index);
    }
}

Storage::~Storage() {
    if (device_.is_cpu()) {
        // Same threshold as the constructor: only blocks that may have come from the cache go back.
        if (capacity_ >= kCacheMin) cache().give(data_, capacity_);
        else std::free(data_);
        g_cpu_bytes -= int64_t(nbytes_);
    } else {
        cuda::free_device(data_);
    }
}

int64_t Storage::cpu_bytes_in_use() { return g_cpu_bytes.load(); }
int64_t Storage::cpu_bytes_cached() { return cache().cached(); }
int64_t Storage::cpu_cache_limit() { return cache().limit(); }
void Storage::set_cpu_cache_limit(int64_t bytes) { cache().set_limit(bytes); }
void Storage::release_cpu_cache() { cache().trim(0); }
void Storage::set_cpu_cache_poison(bool on) { cache().set_poison(on); }

}  // namespace g2l
