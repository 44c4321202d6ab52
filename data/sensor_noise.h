// SPDX-License-Identifier: MIT
// Depth-sensor noise for synthetic depth: a structured-light (Kinect / Asus Xtion) error model
// applied to a clean rendered depth image. Deterministic for a seed and independent of the
// thread count (per-pixel random numbers come from a counter-based hash of (seed, pixel)).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace g2l::data {

/// Parameters of the depth-noise model. Defaults were chosen against the real YCB-Video depth
/// (Asus Xtion, docs/renderer.md gives the measurement).
struct SensorNoiseConfig {
    bool enabled = true;             ///< false: depth is left untouched
    /// Axial (along-z) Gaussian noise, sigma(z) = sigma_a_mm + sigma_b_mm_per_m2 * (z / 1000)^2.
    /// Fitted to YCB-V train_real (robust residual to the GT-posed models: 1.20 mm at 0.56 m,
    /// 3.16 mm at 0.94 m, 2.78 mm at 1.05 m; an upper bound, so the fit stays slightly below).
    double sigma_a_mm = 0.5;
    double sigma_b_mm_per_m2 = 2.0;
    /// Depth is rounded to multiples of this step (the PNG depth_scale, mm); 0 = no rounding.
    double quant_step_mm = 0.1;
    /// Pixels whose |cos(normal, viewing ray)| is below this get no depth (grazing angles).
    double grazing_cos_min = 0.1;
    /// A pixel is an edge pixel when a neighbour within edge_width_px differs by more than
    /// edge_jump_mm or has no depth; edge pixels are dropped with probability edge_dropout_prob.
    double edge_jump_mm = 15.0;
    int edge_width_px = 1;
    double edge_dropout_prob = 0.5;
    /// Random circular holes (missing depth): count uniform in [holes_min, holes_max], radius
    /// uniform in [hole_radius_min_px, hole_radius_max_px].
    int holes_min = 0;
    int holes_max = 3;
    double hole_radius_min_px = 2.0;
    double hole_radius_max_px = 8.0;
    /// Lateral jitter: each pixel takes the depth of the pixel at a Gaussian offset with this
    /// sigma (pixels, rounded); 0 = off.
    double lateral_sigma_px = 0.0;
};

/// Throws g2l::Error naming the field when a parameter is out of range (negative sigma or
/// step, probability outside [0, 1], holes_min > holes_max, radius min > max, ...). `where`
/// prefixes the message (e.g. the config file and key).
void validate(const SensorNoiseConfig& cfg, const std::string& where = "SensorNoiseConfig");

/// Axial standard deviation sigma(z) in mm for a depth z in mm.
double axial_sigma_mm(const SensorNoiseConfig& cfg, double z_mm);

/// Applies the noise in place to depth_mm (H x W row-major, mm, 0 = no depth). cos_view (H x W,
/// from RenderOutput::cos_view) drives the grazing-angle dropout; pass nullptr to skip it.
/// Order: lateral jitter, edge dropout (edges found on the clean depth), grazing dropout, axial
/// noise, quantisation, holes. `scratch` is reused between calls. Throws g2l::Error for a null
/// depth pointer, a non-positive size or an invalid config. threads: OpenMP threads (0 = the
/// default); the result does not depend on it.
void apply_sensor_noise(const SensorNoiseConfig& cfg, uint64_t seed, int width, int height,
                        const float* cos_view, float* depth_mm, std::vector<float>& scratch,
                        int threads = 0);

}  // namespace g2l::data
