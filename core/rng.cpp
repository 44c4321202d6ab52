// SPDX-License-Identifier: MIT
#include "core/rng.h"

#include <cmath>

#include "core/error.h"

namespace g2l {

namespace {
uint64_t splitmix64(uint64_t& x) {
    uint64_t z = (x += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
}  // namespace

void Rng::reseed(uint64_t seed) {
    // The xoshiro authors' recommended seeding: one 64-bit seed expands into 256 well-mixed state
    // bits, so nearby seeds (0, 1, 2, ...) give unrelated streams and the all-zero state, which
    // xoshiro can never leave, does not arise in practice.
    for (auto& v : s_) v = splitmix64(seed);
}

uint64_t Rng::below(uint64_t n) {
    G2L_CHECK(n > 0, "Rng::below: n must be > 0");
    const uint64_t limit = UINT64_MAX - UINT64_MAX % n;  // reject the biased tail
    uint64_t x;
    do {
        x = next_u64();
    } while (x >= limit);
    return x % n;
}

double Rng::normal() {
    double u1 = uniform();
    // uniform() can return exactly 0, and log(0) would make the sample infinite.
    while (u1 <= 0.0) u1 = uniform();
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

}  // namespace g2l
