// SPDX-License-Identifier: MIT
#include "data/sensor_noise.h"

#include <algorithm>
#include <cmath>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/error.h"
#include "core/rng.h"

namespace g2l::data {
namespace {

// splitmix64 finaliser: a bijective 64-bit hash, so hash(seed, stream, pixel) gives independent
// per-pixel random numbers without a sequential generator (thread-count independent).
uint64_t mix(uint64_t z) {
    z += 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

// Uniform in (0, 1) for (seed, stream, index).
double uniform01(uint64_t seed, uint64_t stream, uint64_t index) {
    const uint64_t h = mix(mix(seed ^ (stream * 0xD1B54A32D192ED03ull)) + index);
    return (double(h >> 11) + 0.5) * 0x1.0p-53;
}

// Standard normal by Box-Muller from two hashed uniforms.
double normal01(uint64_t seed, uint64_t stream, uint64_t index) {
    const double u1 = uniform01(seed, stream, 2 * index);
    const double u2 = uniform01(seed, stream, 2 * index + 1);
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

// Two independent standard normals for the pixel pair (2 j, 2 j + 1): both Box-Muller outputs,
// half the transcendental calls of normal01.
void normal_pair(uint64_t seed, uint64_t stream, uint64_t j, float& a, float& b) {
    const double u1 = uniform01(seed, stream, 2 * j), u2 = uniform01(seed, stream, 2 * j + 1);
    const float r = float(std::sqrt(-2.0 * std::log(u1)));
    const float phi = float(6.283185307179586 * u2);
    a = r * std::cos(phi);
    b = r * std::sin(phi);
}

enum Stream : uint64_t { kLateralU = 1, kLateralV, kEdge, kAxial, kHoles };

bool is_edge(const float* d, int w, int h, int u, int v, int width_px, double jump) {
    const float z = d[size_t(v) * w + u];
    for (int dv = -width_px; dv <= width_px; ++dv) {
        for (int du = -width_px; du <= width_px; ++du) {
            const int uu = u + du, vv = v + dv;
            if (uu < 0 || vv < 0 || uu >= w || vv >= h) continue;
            const float zn = d[size_t(vv) * w + uu];
            if (zn <= 0 || std::fabs(zn - z) > jump) return true;
        }
    }
    return false;
}

}  // namespace

void validate(const SensorNoiseConfig& c, const std::string& where) {
    G2L_CHECK(c.sigma_a_mm >= 0 && c.sigma_b_mm_per_m2 >= 0, where,
              ": sigma_a_mm and sigma_b_mm_per_m2 must be >= 0, got ", c.sigma_a_mm, " and ",
              c.sigma_b_mm_per_m2);
    G2L_CHECK(c.quant_step_mm >= 0, where, ": quant_step_mm must be >= 0, got ", c.quant_step_mm);
    G2L_CHECK(c.grazing_cos_min >= 0 && c.grazing_cos_min <= 1, where,
              ": grazing_cos_min must be in [0, 1], got ", c.grazing_cos_min);
    G2L_CHECK(c.edge_jump_mm > 0, where, ": edge_jump_mm must be > 0, got ", c.edge_jump_mm);
    G2L_CHECK(c.edge_width_px >= 0 && c.edge_width_px <= 16, where,
              ": edge_width_px must be in [0, 16], got ", c.edge_width_px);
    G2L_CHECK(c.edge_dropout_prob >= 0 && c.edge_dropout_prob <= 1, where,
              ": edge_dropout_prob must be in [0, 1], got ", c.edge_dropout_prob);
    G2L_CHECK(c.holes_min >= 0 && c.holes_min <= c.holes_max, where,
              ": need 0 <= holes_min <= holes_max, got ", c.holes_min, " and ", c.holes_max);
    G2L_CHECK(c.hole_radius_min_px >= 0 && c.hole_radius_min_px <= c.hole_radius_max_px, where,
              ": need 0 <= hole_radius_min_px <= hole_radius_max_px, got ", c.hole_radius_min_px,
              " and ", c.hole_radius_max_px);
    G2L_CHECK(c.lateral_sigma_px >= 0 && c.lateral_sigma_px <= 10, where,
              ": lateral_sigma_px must be in [0, 10], got ", c.lateral_sigma_px);
}

double axial_sigma_mm(const SensorNoiseConfig& cfg, double z_mm) {
    const double zm = z_mm / 1000.0;
    return cfg.sigma_a_mm + cfg.sigma_b_mm_per_m2 * zm * zm;
}

void apply_sensor_noise(const SensorNoiseConfig& cfg, uint64_t seed, int width, int height,
                        const float* cos_view, float* depth_mm, std::vector<float>& scratch,
                        int threads) {
    G2L_CHECK(depth_mm != nullptr, "apply_sensor_noise: null depth image");
    G2L_CHECK(width > 0 && height > 0, "apply_sensor_noise: image size must be > 0, got ", width,
              " x ", height);
    validate(cfg, "SensorNoiseConfig");
    if (!cfg.enabled) return;
    const int W = width, H = height;
    const size_t n = size_t(W) * size_t(H);
    // scratch keeps the clean (jittered) depth so edges are found before any pixel is dropped.
    scratch.assign(depth_mm, depth_mm + n);
#ifdef _OPENMP
    const int nt = threads > 0 ? threads : omp_get_max_threads();
#else
    (void)threads;
#endif
    if (cfg.lateral_sigma_px > 0) {
        const std::vector<float> src(depth_mm, depth_mm + n);
#pragma omp parallel for schedule(static) num_threads(nt)
        for (int v = 0; v < H; ++v) {
            for (int u = 0; u < W; ++u) {
                const size_t i = size_t(v) * W + u;
                const int du = int(std::lround(cfg.lateral_sigma_px * normal01(seed, kLateralU, i)));
                const int dv = int(std::lround(cfg.lateral_sigma_px * normal01(seed, kLateralV, i)));
                const int uu = std::clamp(u + du, 0, W - 1), vv = std::clamp(v + dv, 0, H - 1);
                scratch[i] = src[size_t(vv) * W + uu];
            }
        }
    }
    const int half = (W + 1) / 2;
#pragma omp parallel for schedule(static) num_threads(nt)
    for (int v = 0; v < H; ++v) {
        float g[2] = {0, 0};
        for (int u = 0; u < W; ++u) {
            const size_t i = size_t(v) * W + u;
            if (u % 2 == 0) normal_pair(seed, kAxial, uint64_t(v) * half + u / 2, g[0], g[1]);
            const float z = scratch[i];
            float out = z;
            if (z > 0 && cfg.edge_dropout_prob > 0 && cfg.edge_width_px > 0 &&
                is_edge(scratch.data(), W, H, u, v, cfg.edge_width_px, cfg.edge_jump_mm) &&
                uniform01(seed, kEdge, i) < cfg.edge_dropout_prob) {
                out = 0;
            }
            if (out > 0 && cos_view != nullptr && cos_view[i] < cfg.grazing_cos_min) out = 0;
            if (out > 0) {
                out = float(z + axial_sigma_mm(cfg, z) * g[u % 2]);
                if (cfg.quant_step_mm > 0) {
                    out = float(std::nearbyint(out / cfg.quant_step_mm) * cfg.quant_step_mm);
                }
                if (out < 0) out = 0;
            }
            depth_mm[i] = out;
        }
    }
    // Holes: a few discs of missing depth (sequential generator; few draws).
    Rng rng(seed ^ 0x5A17E5ull);
    const int holes = int(rng.randint(cfg.holes_min, cfg.holes_max + 1));
    for (int k = 0; k < holes; ++k) {
        const double cu = rng.uniform(0, W), cv = rng.uniform(0, H);
        const double r = rng.uniform(cfg.hole_radius_min_px, cfg.hole_radius_max_px);
        const int v0 = std::max(0, int(cv - r)), v1 = std::min(H - 1, int(cv + r) + 1);
        const int u0 = std::max(0, int(cu - r)), u1 = std::min(W - 1, int(cu + r) + 1);
        for (int v = v0; v <= v1; ++v) {
            for (int u = u0; u <= u1; ++u) {
                if ((u - cu) * (u - cu) + (v - cv) * (v - cv) <= r * r) {
                    depth_mm[size_t(v) * W + u] = 0;
                }
            }
        }
    }
}

}  // namespace g2l::data
