// SPDX-License-Identifier: MIT
// Deterministic random numbers, identical on every platform and compiler (std distributions are
// implementation-defined, so we do not use them). xoshiro256** seeded by splitmix64.
#pragma once

#include <array>
#include <cstdint>

namespace g2l {

/// A seed derived from two values (splitmix64 finaliser of a * phi + b): independent streams per
/// (run seed, epoch, item, ...) without correlations between neighbouring values.
inline uint64_t mix_seed(uint64_t a, uint64_t b) {
    uint64_t z = a * 0x9E3779B97F4A7C15ull + b + 0x632BE59BD9B4E019ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

class Rng {
public:
    explicit Rng(uint64_t seed = 0x9E3779B97F4A7C15ull) { reseed(seed); }
    void reseed(uint64_t seed);

    /// Next raw 64-bit value (inline: dropout draws one per element of its mask).
    uint64_t next_u64() {
        const uint64_t result = rotl(s_[1] * 5, 7) * 9;
        const uint64_t t = s_[1] << 17;
        s_[2] ^= s_[0];
        s_[3] ^= s_[1];
        s_[1] ^= s_[2];
        s_[0] ^= s_[3];
        s_[2] ^= t;
        s_[3] = rotl(s_[3], 45);
        return result;
    }
    /// Uniform double in [0, 1).
    double uniform() { return double(next_u64() >> 11) * 0x1.0p-53; }
    /// Uniform double in [lo, hi).
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    /// Uniform integer in [0, n) (n > 0), unbiased.
    uint64_t below(uint64_t n);
    /// Uniform integer in [lo, hi) (hi > lo).
    int64_t randint(int64_t lo, int64_t hi) { return lo + int64_t(below(uint64_t(hi - lo))); }
    /// Standard normal (Box-Muller, no cached second value so the state alone defines the stream).
    double normal();
    double normal(double mean, double stddev) { return mean + stddev * normal(); }

    /// The full state, for checkpoints (resume continues the exact stream).
    std::array<uint64_t, 4> state() const { return s_; }
    void set_state(const std::array<uint64_t, 4>& s) { s_ = s; }

private:
    static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
    std::array<uint64_t, 4> s_{};
};

}  // namespace g2l
