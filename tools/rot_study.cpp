// SPDX-License-Identifier: MIT
#include "tools/rot_study.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/autograd.h"
#include "geometry/kabsch.h"
#include "geometry/metrics.h"
#include "nn/models/g2l_net.h"
#include "nn/optim.h"

namespace g2l::tools {

// Tools measure the training code: its names are used as they are.
using namespace g2l::train;

namespace {

using Clock = std::chrono::steady_clock;

uint64_t mix(uint64_t a, uint64_t b) { return mix_seed(a, b); }

// The rotation input of a batch (train::gt_rotation_input) and its one-hot classes.
struct RotInput : RotationInput {
    Tensor onehot;
};

RotInput make_input(const std::vector<PoseSample>& s, int M, int num_classes, double noise_mm,
                    Rng* rng) {
    RotInput in;
    static_cast<RotationInput&>(in) = gt_rotation_input(s, M, noise_mm, rng);
    in.onehot = Tensor::zeros({int64_t(s.size()), num_classes});
    for (size_t b = 0; b < s.size(); ++b) {
        G2L_CHECK(s[b].class_index >= 0 && s[b].class_index < num_classes,
                  "rot_study: class index ", s[b].class_index, " outside [0, ", num_classes, ")");
        in.onehot.data<float>()[b * size_t(num_classes) + size_t(s[b].class_index)] = 1.f;
    }
    return in;
}

}  // namespace

namespace {

// The study's network (its config from cfg) with the optional zeroed last layers and the
// BatchNorm momentum.
std::unique_ptr<nn::G2LNet> study_net(const RotStudyConfig& cfg, int num_classes, int K) {
    nn::G2LConfig mc;
    mc.num_classes = num_classes;
    mc.num_keypoints = K;
    mc.evf = cfg.evf;
    mc.rre = cfg.rre;
    mc.width = cfg.width;
    mc.dropout = cfg.dropout;
    mc.seed = cfg.seed;
    mc.rot_unit = cfg.rot_unit;
    mc.out_scale_mm = cfg.out_scale_mm;
    mc.class_heads = cfg.class_heads;
    auto net = std::make_unique<nn::G2LNet>(mc);
    if (cfg.zero_last_layers)
        for (auto& [name, t] : net->named_parameters())
            if (name.rfind("evf.out.", 0) == 0 || name.rfind("rot.out.", 0) == 0 ||
                name.rfind("rre.out.", 0) == 0)
                std::fill(t.data<float>(), t.data<float>() + t.numel(), 0.f);
    net->apply([&](nn::Module& m) {
        if (auto* bn = dynamic_cast<nn::BatchNorm*>(&m)) bn->momentum = cfg.bn_momentum;
    });
    return net;
}

// The rotation of one validation sample from the predicted keypoints Q (corrected by block
// C's residual when there is one), as G2L-Net computes it: Kabsch of the model keypoints P.
Eigen::Matrix3d predicted_rotation(const geom::Points& P, geom::Points& Q, const float* residual) {
    const int K = int(P.rows());
    Eigen::Matrix3d R = geom::kabsch(P, Q);
    if (!residual) return R;
    geom::Points Pc(K, 3);
    const Eigen::Vector3d cm = P.cast<double>().colwise().mean().transpose();
    const Eigen::Vector3d cq = Q.cast<double>().colwise().mean().transpose();
    for (int k = 0; k < K; ++k)
        for (int c = 0; c < 3; ++c)
            Pc(k, c) = float((R * (P.row(k).transpose().cast<double>() - cm) + cq)[c]) +
                       residual[k * 3 + c];
    Q = Pc;
    return geom::kabsch(P, Pc);
}

// Validation (eval mode, deterministic points, GT centre): the keypoint and rotation errors
// of every validation sample into pt, against the nearest symmetric keypoint set when given.
void validate(nn::G2LNet& net, const RotStudyConfig& cfg, int num_classes,
              const KeypointTable& keypoints, const std::vector<double>& diameters,
              const SymmetricKeypoints* sym, const StepOptions& so,
              const std::vector<PoseSample>& val, RotStudyPoint* pt) {
    const int K = int(keypoints[0].size());
    net.eval();
    autograd::NoGradGuard ng;
    std::vector<double> rot_err;
    double kp_err = 0, kp_frac = 0;
    const int64_t chunk = 64;
    for (size_t lo = 0; lo < val.size(); lo += chunk) {
        const std::vector<PoseSample> vb(val.begin() + long(lo),
                                         val.begin() + long(std::min(val.size(), lo + chunk)));
        const RotInput in = make_input(vb, cfg.points, num_classes, 0, nullptr);
        Tensor scale;
        if (cfg.rot_unit != "mm") {
            scale = Tensor::empty({int64_t(vb.size()), 1, 1});
            for (size_t b = 0; b < vb.size(); ++b)
                scale.data<float>()[b] = so.rot_scale[size_t(vb[b].class_index)];
        }
        const nn::RotOut r = net.rot_forward(in.x, in.onehot, scale);
        for (size_t b = 0; b < vb.size(); ++b) {
            const PoseSample& s = vb[b];
            const auto& kpm = keypoints[size_t(s.class_index)];
            geom::Points P(K, 3), Q(K, 3);
            for (int k = 0; k < K; ++k) {
                P.row(k) = kpm[size_t(k)].transpose();
                for (int c = 0; c < 3; ++c) Q(k, c) = r.keypoints.data<float>()[(b * K + k) * 3 + c];
            }
            const Eigen::Matrix3d R = predicted_rotation(
                P, Q, r.residual.defined() ? r.residual.data<float>() + b * K * 3 : nullptr);
            const KeypointTable one{kpm};
            const KeypointTable& sets = sym ? (*sym)[size_t(s.class_index)] : one;
            double best_kp = -1, best_rot = 0;
            for (const auto& set : sets) {
                double e = 0;
                for (int k = 0; k < K; ++k)
                    e += double((s.R * set[size_t(k)] - Q.row(k).transpose()).norm());
                e /= K;
                if (best_kp < 0 || e < best_kp) {
                    best_kp = e;
                    // The symmetry's rotation: Kabsch of the identity set onto this set.
                    geom::Points S(K, 3);
                    for (int k = 0; k < K; ++k) S.row(k) = set[size_t(k)].transpose();
                    const Eigen::Matrix3d Rs = geom::kabsch(P, S);
                    best_rot = geom::rotation_error_deg(R, s.R.cast<double>() * Rs);
                }
            }
            kp_err += best_kp;
            kp_frac += best_kp / diameters[size_t(s.class_index)];
            pt->val_kp_err_frac_each.push_back(best_kp / diameters[size_t(s.class_index)]);
            rot_err.push_back(best_rot);
        }
    }
    pt->val_kp_err_mm = kp_err / double(val.size());
    pt->val_kp_err_frac = kp_frac / double(val.size());
    pt->val_rot_err_deg_each = rot_err;
    pt->val_rot_err_deg_median = geom::median(rot_err);
    double sum = 0;
    int under = 0;
    for (double e : rot_err) sum += e, under += e < 10;
    pt->val_rot_err_deg_mean = sum / double(rot_err.size());
    pt->val_acc_10deg = double(under) / double(rot_err.size());
}

}  // namespace

std::vector<RotStudyPoint> rot_study(const RotStudyConfig& cfg, int num_classes,
                                     const KeypointTable& keypoints,
                                     const std::vector<double>& diameters,
                                     const SymmetricKeypoints* symmetric, const SampleDraw& draw,
                                     const std::vector<PoseSample>& val,
                                     const std::function<void(const RotStudyPoint&)>& on_point) {
    G2L_CHECK(!val.empty(), "rot_study: empty validation set");
    G2L_CHECK(cfg.steps > 0 && cfg.batch > 0 && cfg.points > 0 && cfg.eval_every > 0,
              "rot_study: steps, batch, points and eval_every must be > 0");
    G2L_CHECK(!keypoints.empty() && diameters.size() == keypoints.size(),
              "rot_study: ", keypoints.size(), " keypoint sets and ", diameters.size(),
              " diameters");
    G2L_CHECK(!cfg.symmetric || symmetric, "rot_study: symmetric targets need symmetry tables");
    G2L_CHECK(cfg.lr_decay_every >= 0 && cfg.lr_decay_factor > 0 && cfg.lr_decay_factor <= 1,
              "rot_study: lr_decay_every must be >= 0 and lr_decay_factor in (0, 1], got ",
              cfg.lr_decay_every, " and ", cfg.lr_decay_factor);
    const int K = int(keypoints[0].size());
    const std::unique_ptr<nn::G2LNet> owned = study_net(cfg, num_classes, K);
    nn::G2LNet& net = *owned;
    std::vector<nn::ParamGroup> groups;
    for (auto& g : net.param_groups({1, 1, cfg.mult_evf, cfg.mult_rot, cfg.mult_rre})) {
        if (g.name == "seg" || g.name == "tnet") continue;
        groups.push_back(std::move(g));
    }
    nn::AdamOptions ao;
    ao.lr = cfg.lr;
    ao.beta1 = 0.9;
    ao.beta2 = 0.99;
    nn::Adam adam(groups, ao);

    StepOptions so;
    for (const auto& kp : keypoints) so.rot_scale.push_back(float(nn::rotation_scale(cfg.rot_unit, kp)));
    const SymmetricKeypoints* sym = cfg.symmetric ? symmetric : nullptr;

    std::vector<RotStudyPoint> curve;
    Rng rng(mix(cfg.seed, 0x5EED));
    int64_t next_draw = 0, samples = 0;
    double train_err_sum = 0;
    int train_err_n = 0;
    const auto t0 = Clock::now();
    for (int step = 1; step <= cfg.steps; ++step) {
        std::vector<PoseSample> batch;
        int fails = 0;
        while (int(batch.size()) < cfg.batch) {
            PoseSample s;
            if (draw(next_draw++, &s)) {
                batch.push_back(std::move(s));
                fails = 0;
            } else {
                G2L_CHECK(++fails < 1000, "rot_study: 1000 unusable draws in a row");
            }
        }
        if (cfg.lr_decay_every > 0)
            adam.set_lr(cfg.lr * std::pow(cfg.lr_decay_factor, (step - 1) / cfg.lr_decay_every));
        net.train();
        adam.zero_grad();
        const RotInput in = make_input(batch, cfg.points, num_classes, cfg.centre_noise_mm, &rng);
        StepLosses L;
        Tensor loss = rotation_losses(net, batch, in.x, in.object, in.centres, in.onehot,
                                      keypoints, cfg.weights, sym, so, &L);
        G2L_CHECK(std::isfinite(loss.item<double>()), "rot_study: non-finite loss at step ", step);
        loss.backward();
        adam.step();
        samples += cfg.batch;
        train_err_sum += L.kp_error_mm;
        ++train_err_n;
        if (step % cfg.eval_every != 0 && step != cfg.steps) continue;

        RotStudyPoint pt;
        pt.step = step;
        pt.samples = samples;
        pt.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
        pt.train_kp_err_mm = train_err_sum / std::max(1, train_err_n);
        train_err_sum = 0;
        train_err_n = 0;
        validate(net, cfg, num_classes, keypoints, diameters, sym, so, val, &pt);
        curve.push_back(pt);
        if (on_point) on_point(pt);
    }
    return curve;
}

}  // namespace g2l::tools
