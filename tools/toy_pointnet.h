// SPDX-License-Identifier: MIT
// A tiny PointNet classifier trained on generated point clouds (sphere / box / cylinder
// surfaces at random scale, rotation and noise). It is the engine's end-to-end learning check
// and the smallest real training job (`g2l_demo --toy`).
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "core/tensor.h"

namespace g2l::tools {

struct ToyConfig {
    int num_classes = 3;       ///< 2 = sphere/box, 3 adds cylinders
    int points = 128;          ///< points per cloud
    int batch = 32;
    int steps = 300;
    int test_samples = 600;
    double lr = 2e-3;
    double noise_mm = 0.01;    ///< isotropic noise relative to the unit shape
    uint64_t seed = 1;
};

struct ToyResult {
    double final_loss = 0;     ///< mean cross-entropy of the last 20 steps
    double first_loss = 0;     ///< mean cross-entropy of the first 20 steps
    double test_accuracy = 0;  ///< on freshly generated clouds, eval mode
    double seconds = 0;
    double samples_per_s = 0;
};

/// Generates one cloud of class `label` (0 sphere, 1 box, 2 cylinder): x [3, N] channel-first.
Tensor make_toy_cloud(int label, int points, double noise, uint64_t seed);

/// Trains and evaluates; `progress(step, loss)` is called every 25 steps if set.
ToyResult train_toy_pointnet(const ToyConfig& cfg,
                             const std::function<void(int, double)>& progress = nullptr);

}  // namespace g2l::tools
