// SPDX-License-Identifier: MIT
#include "tools/toy_pointnet.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <memory>

#include "core/autograd.h"
#include "core/rng.h"
#include "nn/modules/shared_mlp.h"
#include "nn/ops/loss.h"
#include "nn/ops/pool_points.h"
#include "nn/optim.h"

namespace g2l::tools {

namespace {

constexpr double kPi = 3.14159265358979323846;

// A random rotation from a uniformly random unit quaternion.
void random_rotation(Rng& rng, double R[9]) {
    double q[4], n = 0;
    // A normalised 4-D Gaussian is uniform on the unit quaternions, hence on SO(3); the loop only
    // guards the (practically impossible) zero vector.
    do {
        n = 0;
        for (double& v : q) { v = rng.normal(); n += v * v; }
    } while (n < 1e-12);
    n = std::sqrt(n);
    const double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
    const double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
                         2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                         2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)};
    std::memcpy(R, r, sizeof(r));
}

class ToyNet : public nn::Module {
public:
    ToyNet(int classes, Rng& rng) {
        feat = register_module("feat", std::make_shared<nn::SharedMlp>(
                                           std::vector<int64_t>{3, 32, 64, 128}, rng));
        head = register_module("head", std::make_shared<nn::Mlp>(std::vector<int64_t>{128, 64},
                                                                  rng));
        out = register_module("out", std::make_shared<nn::Linear>(64, classes, rng));
    }
    Tensor forward(const Tensor& x) {
        // The PointNet recipe G2L's networks build on: a per-point shared MLP, a max over
        // points (so the point order does not matter), then a per-cloud MLP.
        return out->forward(head->forward(nn::max_pool_points(feat->forward(x))));
    }
    std::shared_ptr<nn::SharedMlp> feat;
    std::shared_ptr<nn::Mlp> head;
    std::shared_ptr<nn::Linear> out;
};

}  // namespace

Tensor make_toy_cloud(int label, int points, double noise, uint64_t seed) {
    G2L_CHECK(label >= 0 && label <= 2, "make_toy_cloud: label must be 0, 1 or 2, got ", label);
    G2L_CHECK(points > 0, "make_toy_cloud: points must be > 0, got ", points);
    Rng rng(seed);
    double R[9];
    random_rotation(rng, R);
    // Random scale and rotation: the class must be read from the shape, not from size or pose.
    const double scale = rng.uniform(0.6, 1.4);
    Tensor x = Tensor::empty({3, points});
    float* p = x.data<float>();
    for (int i = 0; i < points; ++i) {
        double v[3];
        if (label == 0) {  // sphere surface
            double n = 0;
            do {
                n = 0;
                for (double& c : v) { c = rng.normal(); n += c * c; }
            } while (n < 1e-12);
            for (double& c : v) c /= std::sqrt(n);
        } else if (label == 1) {  // cube surface: a random face, uniform on it
            // All faces have the same area, so a uniform face and a uniform point on it are
            // uniform on the whole surface.
            const int face = int(rng.below(6));
            v[0] = rng.uniform(-1, 1); v[1] = rng.uniform(-1, 1); v[2] = rng.uniform(-1, 1);
            v[face / 2] = (face % 2) ? 1.0 : -1.0;
        } else {  // cylinder side (radius 1, height 2)
            const double a = rng.uniform(0, 2 * kPi);
            v[0] = std::cos(a); v[1] = std::sin(a); v[2] = rng.uniform(-1, 1);
        }
        for (int r = 0; r < 3; ++r) {
            const double c = R[r * 3] * v[0] + R[r * 3 + 1] * v[1] + R[r * 3 + 2] * v[2];
            p[r * points + i] = float(scale * c + noise * rng.normal());
        }
    }
    return x;
}

ToyResult train_toy_pointnet(const ToyConfig& cfg, const std::function<void(int, double)>& progress) {
    G2L_CHECK(cfg.num_classes == 2 || cfg.num_classes == 3, "toy: num_classes must be 2 or 3, got ",
              cfg.num_classes);
    // batch > 1: the head's BatchNorm sees one value per channel and sample, and training
    // BatchNorm needs more than one.
    G2L_CHECK(cfg.batch > 1 && cfg.steps > 0 && cfg.points > 0 && cfg.test_samples > 0,
              "toy: batch > 1, steps, points and test_samples > 0 required");
    Rng rng(cfg.seed);
    ToyNet net(cfg.num_classes, rng);
    nn::Adam opt({nn::ParamGroup{"toy", net.named_parameters()}}, nn::AdamOptions{cfg.lr});
    auto make_batch = [&](int n, uint64_t base_seed, Tensor& x, Tensor& y) {
        x = Tensor::empty({n, 3, cfg.points});
        y = Tensor::empty({n}, DType::I32);
        for (int i = 0; i < n; ++i) {
            // Labels cycle through the classes: every batch is balanced.
            const int label = int((base_seed + uint64_t(i)) % uint64_t(cfg.num_classes));
            // One seed per sample from (run seed, sample index): batches are reproducible
            // and need no shared generator state.
            const Tensor c = make_toy_cloud(label, cfg.points, cfg.noise_mm,
                                            cfg.seed * 1000003u + base_seed + uint64_t(i));
            std::memcpy(x.data<float>() + i * 3 * cfg.points, c.data(), c.nbytes());
            y.data<int32_t>()[i] = label;
        }
    };
    ToyResult res;
    const auto t0 = std::chrono::steady_clock::now();
    double first = 0, last = 0;
    for (int step = 0; step < cfg.steps; ++step) {
        Tensor x, y;
        make_batch(cfg.batch, uint64_t(step) * uint64_t(cfg.batch) + 17, x, y);
        // Step decay (x0.1 for the last third): BatchNorm's running statistics, used at test
        // time, then settle on the final weights instead of lagging a moving network.
        opt.set_lr(step < cfg.steps * 2 / 3 ? cfg.lr : cfg.lr * 0.1);
        opt.zero_grad();
        Tensor loss = nn::cross_entropy(net.forward(x), y);
        loss.backward();
        opt.step();
        const double l = loss.item<double>();
        if (step < 20) first += l / std::min(20, cfg.steps);
        if (step >= cfg.steps - 20) last += l / std::min(20, cfg.steps);
        if (progress && (step % 25 == 0 || step + 1 == cfg.steps)) progress(step, l);
    }
    res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    res.samples_per_s = double(cfg.steps) * cfg.batch / res.seconds;
    res.first_loss = first;
    res.final_loss = last;

    // Eval mode: BatchNorm uses its running statistics, as at inference.
    net.eval();
    autograd::NoGradGuard no_grad;
    Tensor x, y;
    // Test indices start far past any training index, so the test clouds are never seen in
    // training.
    make_batch(cfg.test_samples, 1u << 30, x, y);
    const Tensor pred = nn::argmax(net.forward(x), 1);
    int correct = 0;
    for (int i = 0; i < cfg.test_samples; ++i)
        correct += pred.data<int32_t>()[i] == y.data<int32_t>()[i];
    res.test_accuracy = double(correct) / cfg.test_samples;
    return res;
}

}  // namespace g2l::tools
