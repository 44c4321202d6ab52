// SPDX-License-Identifier: MIT
#include "train/pipeline.h"

#include <Eigen/Dense>
#include <cmath>

#include "core/autograd.h"
#include "geometry/kabsch.h"
#include "nn/ops/elementwise.h"
#include "nn/ops/loss.h"

namespace g2l::train {

namespace {

Tensor one_hot(const std::vector<PoseSample>& s, int num_classes) {
    Tensor oh = Tensor::zeros({int64_t(s.size()), num_classes});
    for (size_t b = 0; b < s.size(); ++b) {
        G2L_CHECK(s[b].class_index >= 0 && s[b].class_index < num_classes, "g2l_step: sample ",
                  b, " has class index ", s[b].class_index, " outside [0, ", num_classes, ")");
        oh.data<float>()[b * size_t(num_classes) + size_t(s[b].class_index)] = 1.f;
    }
    return oh;
}

}  // namespace

StepLosses g2l_step(nn::G2LNet& net, const std::vector<PoseSample>& samples,
                    const KeypointTable& keypoints, int num_classes, int seg_points,
                    const LossWeights& w, Rng& rng, const SymmetricKeypoints* symmetric,
                    const StepOptions& opt) {
    const int64_t B = int64_t(samples.size());
    G2L_CHECK(B > 0, "g2l_step: empty batch");
    G2L_CHECK(seg_points > 0, "g2l_step: seg_points must be > 0, got ", seg_points);
    G2L_CHECK(std::isfinite(opt.centre_noise_mm) && opt.centre_noise_mm >= 0,
              "g2l_step: centre_noise_mm must be finite and >= 0, got ", opt.centre_noise_mm);
    const int64_t N = int64_t(samples[0].labels.size());
    const int64_t M = seg_points;
    for (int64_t b = 0; b < B; ++b)
        G2L_CHECK(int64_t(samples[b].labels.size()) == N &&
                      int64_t(samples[b].points.size()) == 3 * N,
                  "g2l_step: sample ", b, " has ", samples[b].labels.size(),
                  " points, sample 0 has ", N);
    const int K = net.config().num_keypoints;
    const Tensor onehot = one_hot(samples, num_classes);
    G2L_CHECK(!opt.sample_rngs || int64_t(opt.sample_rngs->size()) == B, "g2l_step: ",
              opt.sample_rngs ? opt.sample_rngs->size() : 0, " sample streams for ", B,
              " samples");
    auto rng_of = [&](int64_t b) -> Rng& {
        return opt.sample_rngs ? (*opt.sample_rngs)[size_t(b)] : rng;
    };
    StepLosses out;

    if (opt.rot_only) {
        // Rotation blocks alone on the ground-truth object points (resampled to M).
        const RotationInput in = gt_rotation_input(samples, M, opt.centre_noise_mm, &rng,
                                                   opt.sample_rngs);
        out.total = rotation_losses(net, samples, in.x, in.object, in.centres, onehot, keypoints,
                                    w, symmetric, opt, &out);
        return out;
    }

    // ---- 1. segmentation on the augmented crop: x [B, 3, N] ----
    Tensor x = Tensor::empty({B, 3, N});
    Tensor labels = Tensor::empty({B, N}, DType::I32);
    for (int64_t b = 0; b < B; ++b) {
        float* px = x.data<float>() + b * 3 * N;
        for (int64_t n = 0; n < N; ++n)
            for (int c = 0; c < 3; ++c) px[c * N + n] = samples[b].points[size_t(n * 3 + c)];
        std::copy(samples[b].labels.begin(), samples[b].labels.end(),
                  labels.data<int32_t>() + b * N);
    }
    const Tensor logp = net.seg_forward(x, onehot);  // [B, 2, N]
    const Tensor l_seg = nn::nll_loss(logp, labels);

    // ---- 2. points predicted as object, resampled to M (no gradient through the choice) ----
    Tensor xt = Tensor::empty({B, 3, M});      // T-net input: object points minus their mean
    Tensor t_target = Tensor::empty({B, 3});
    std::vector<Eigen::Vector3f> sel_mean(static_cast<size_t>(B));
    std::vector<std::vector<int32_t>> picks(static_cast<size_t>(B));
    int64_t correct = 0;
    for (int64_t b = 0; b < B; ++b) {
        const PoseSample& s = samples[size_t(b)];
        const float* lp = logp.data<float>() + b * 2 * N;
        std::vector<int32_t> idx;
        for (int64_t n = 0; n < N; ++n) {
            const int pred = lp[N + n] > lp[n] ? 1 : 0;
            correct += pred == s.labels[size_t(n)];
            if (pred) idx.push_back(int32_t(n));
        }
        if (idx.size() < 10 || opt.rot_gt_points) {
            idx.clear();
            for (int64_t n = 0; n < N; ++n)
                if (s.labels[size_t(n)]) idx.push_back(int32_t(n));
        }
        if (idx.empty())
            for (int64_t n = 0; n < N; ++n) idx.push_back(int32_t(n));
        std::vector<int32_t> pick(static_cast<size_t>(M));
        for (auto& p : pick) p = idx[rng_of(b).below(idx.size())];
        Eigen::Vector3f mean = Eigen::Vector3f::Zero();
        for (int32_t p : pick)
            mean += Eigen::Vector3f(s.points[size_t(p) * 3], s.points[size_t(p) * 3 + 1],
                                    s.points[size_t(p) * 3 + 2]);
        mean /= float(M);
        sel_mean[size_t(b)] = mean;
        for (int c = 0; c < 3; ++c) t_target.data<float>()[b * 3 + c] = s.t[c] - mean[c];
        float* pt = xt.data<float>() + b * 3 * M;
        for (int64_t m = 0; m < M; ++m) {
            const size_t p = size_t(pick[size_t(m)]);
            for (int a = 0; a < 3; ++a) pt[a * M + m] = s.points[p * 3 + size_t(a)] - mean[a];
        }
        picks[size_t(b)] = std::move(pick);
    }
    out.seg_accuracy = double(correct) / double(B * N);

    // ---- 3. translation residual ----
    const Tensor t_pred = net.t_forward(xt, onehot);  // [B, 3]
    const Tensor l_t = w.t_smooth_l1 ? nn::smooth_l1_loss(t_pred, t_target, 1.0)
                                     : nn::mse_loss(t_pred, t_target);
    {
        double e = 0;
        for (int64_t b = 0; b < B; ++b) {
            double d2 = 0;
            for (int c = 0; c < 3; ++c) {
                const double d = t_pred.data<float>()[b * 3 + c] - t_target.data<float>()[b * 3 + c];
                d2 += d * d;
            }
            e += std::sqrt(d2);
        }
        out.t_error_mm = e / double(B);
    }

    // ---- 4. rotation blocks in the canonical frame: points minus the centre ----
    Tensor xr = Tensor::empty({B, 3, M});
    std::vector<uint8_t> object(static_cast<size_t>(B * M));
    std::vector<Eigen::Vector3f> centres(static_cast<size_t>(B));
    for (int64_t b = 0; b < B; ++b) {
        const PoseSample& s = samples[size_t(b)];
        Eigen::Vector3f c = s.t;
        if (opt.centre_with_prediction) {
            for (int a = 0; a < 3; ++a)
                c[a] = sel_mean[size_t(b)][a] + t_pred.data<float>()[b * 3 + a];
        } else if (opt.centre_noise_mm > 0) {
            for (int a = 0; a < 3; ++a) c[a] += float(rng_of(b).normal() * opt.centre_noise_mm);
        }
        centres[size_t(b)] = c;
        float* pr = xr.data<float>() + b * 3 * M;
        for (int64_t m = 0; m < M; ++m) {
            const size_t p = size_t(picks[size_t(b)][size_t(m)]);
            for (int a = 0; a < 3; ++a) pr[a * M + m] = s.points[p * 3 + size_t(a)] - c[a];
            object[size_t(b * M + m)] = s.labels[p] ? 1 : 0;
        }
    }
    Tensor total = nn::mul_scalar(l_seg, w.seg) + nn::mul_scalar(l_t, w.t);
    out.seg = l_seg.item<double>();
    out.t = l_t.item<double>();
    total = total + rotation_losses(net, samples, xr, object, centres, onehot, keypoints, w,
                                    symmetric, opt, &out);
    (void)K;
    out.total = total;
    return out;
}

RotationInput gt_rotation_input(const std::vector<PoseSample>& samples, int64_t M,
                                double noise_mm, Rng* shared_rng,
                                std::vector<Rng>* sample_rngs) {
    const int64_t B = int64_t(samples.size());
    G2L_CHECK(!sample_rngs || int64_t(sample_rngs->size()) == B, "gt_rotation_input: ",
              sample_rngs ? sample_rngs->size() : 0, " sample streams for ", B, " samples");
    RotationInput in;
    in.x = Tensor::empty({B, 3, M});
    in.object.assign(size_t(B * M), 1);
    in.centres.resize(size_t(B));
    for (int64_t b = 0; b < B; ++b) {
        const PoseSample& s = samples[size_t(b)];
        Rng* rng = sample_rngs ? &(*sample_rngs)[size_t(b)] : shared_rng;
        std::vector<int32_t> idx;
        for (size_t n = 0; n < s.labels.size(); ++n)
            if (s.labels[n]) idx.push_back(int32_t(n));
        G2L_CHECK(!idx.empty(), "rotation input: sample ", b, " (object ", s.obj_id,
                  ") has no object point");
        Eigen::Vector3f c = s.t;
        if (rng && noise_mm > 0)
            for (int a = 0; a < 3; ++a) c[a] += float(rng->normal() * noise_mm);
        in.centres[size_t(b)] = c;
        float* pr = in.x.data<float>() + b * 3 * M;
        for (int64_t m = 0; m < M; ++m) {
            const size_t p = size_t(rng ? idx[rng->below(idx.size())]
                                        : idx[size_t(m * int64_t(idx.size()) / M)]);
            for (int a = 0; a < 3; ++a) pr[a * M + m] = s.points[p * 3 + size_t(a)] - c[a];
        }
    }
    return in;
}

namespace {

// Block C's target base online (G2L-Net §3.4): R_hat = Kabsch(model keypoints -> predicted
// keypoints, detached), base = R_hat * model keypoints + t_hat, t_hat aligning the centroids
// (the inputs may be centred off the object's origin: centre noise / predicted T). Block C's
// corrected keypoints are base + residual.
Tensor residual_base(const Tensor& pred_kp, const std::vector<PoseSample>& samples,
                     const KeypointTable& keypoints, int K) {
    const int64_t B = int64_t(samples.size());
    Tensor model_kp = Tensor::empty({B, K, 3});
    for (int64_t b = 0; b < B; ++b)
        for (int k = 0; k < K; ++k)
            for (int c = 0; c < 3; ++c)
                model_kp.data<float>()[(b * K + k) * 3 + c] =
                    keypoints[size_t(samples[size_t(b)].class_index)][size_t(k)][c];
    Tensor Rhat = Tensor::empty({B, 3, 3});
    geom::kabsch_batched(model_kp.data<float>(), pred_kp.data<float>(), int(B), K,
                         Rhat.data<float>());
    Tensor base = Tensor::empty({B, K, 3});
    for (int64_t b = 0; b < B; ++b) {
        const Eigen::Map<const Eigen::Matrix<float, 3, 3, Eigen::RowMajor>> R(
            Rhat.data<float>() + b * 9);
        Eigen::Vector3f cm = Eigen::Vector3f::Zero(), cp = Eigen::Vector3f::Zero();
        for (int k = 0; k < K; ++k) {
            cm += Eigen::Map<const Eigen::Vector3f>(model_kp.data<float>() + (b * K + k) * 3);
            cp += Eigen::Map<const Eigen::Vector3f>(pred_kp.data<float>() + (b * K + k) * 3);
        }
        const Eigen::Vector3f th = (cp - R * cm) / float(K);
        for (int k = 0; k < K; ++k) {
            const Eigen::Map<const Eigen::Vector3f> p(model_kp.data<float>() + (b * K + k) * 3);
            Eigen::Map<Eigen::Vector3f>(base.data<float>() + (b * K + k) * 3) = R * p + th;
        }
    }
    return base;
}

// Checks each sample's class has its keypoints (and symmetric sets), and with a rotation unit
// other than mm fills the per-sample unit (mm per unit) and its inverse, [B, 1, 1].
void rotation_scales(const nn::G2LNet& net, const std::vector<PoseSample>& samples,
                     const KeypointTable& keypoints, const SymmetricKeypoints* symmetric,
                     const StepOptions& opt, Tensor* scale, Tensor* inv_scale) {
    const int64_t B = int64_t(samples.size());
    const int K = net.config().num_keypoints;
    const bool unit = net.config().rot_unit != "mm";
    std::vector<float> sc(static_cast<size_t>(B), 1.f);
    for (int64_t b = 0; b < B; ++b) {
        const int cls = samples[size_t(b)].class_index;
        G2L_CHECK(cls >= 0 && cls < int(keypoints.size()) &&
                      int(keypoints[size_t(cls)].size()) == K,
                  "g2l_step: no ", K, " keypoints for class index ", cls);
        if (symmetric)
            G2L_CHECK(cls < int(symmetric->size()) && !(*symmetric)[size_t(cls)].empty(),
                      "g2l_step: no symmetric keypoint sets for class index ", cls);
        if (unit) {
            G2L_CHECK(cls < int(opt.rot_scale.size()) && opt.rot_scale[size_t(cls)] > 0,
                      "g2l_step: rot_unit '", net.config().rot_unit,
                      "' needs a rotation scale for class index ", cls);
            sc[size_t(b)] = opt.rot_scale[size_t(cls)];
        }
    }
    if (!unit) return;
    *scale = Tensor::empty({B, 1, 1});
    *inv_scale = Tensor::empty({B, 1, 1});
    for (int64_t b = 0; b < B; ++b) {
        scale->data<float>()[b] = sc[size_t(b)];
        inv_scale->data<float>()[b] = 1.f / sc[size_t(b)];
    }
}

// The mean distance (mm) between predicted and target keypoints, [B, K, 3] each.
double mean_keypoint_error(const Tensor& pred, const Tensor& target) {
    const int64_t n = pred.numel() / 3;
    const float* a = pred.data<float>();
    const float* g = target.data<float>();
    double e = 0;
    for (int64_t i = 0; i < n; ++i) {
        double d2 = 0;
        for (int c = 0; c < 3; ++c) d2 += double(a[i * 3 + c] - g[i * 3 + c]) * (a[i * 3 + c] - g[i * 3 + c]);
        e += std::sqrt(d2);
    }
    return e / double(n);
}

}  // namespace

Tensor rotation_losses(nn::G2LNet& net, const std::vector<PoseSample>& samples, const Tensor& xr,
                       const std::vector<uint8_t>& object,
                       const std::vector<Eigen::Vector3f>& centres, const Tensor& onehot,
                       const KeypointTable& keypoints, const LossWeights& w,
                       const SymmetricKeypoints* symmetric, const StepOptions& opt,
                       StepLosses* out) {
    const int64_t B = int64_t(samples.size());
    G2L_CHECK(xr.dim() == 3 && xr.size(0) == B && xr.size(1) == 3,
              "rotation_losses: expected xr as [", B, ", 3, M], got ", xr.desc());
    const int64_t M = xr.size(2);
    G2L_CHECK(int64_t(object.size()) == B * M && int64_t(centres.size()) == B,
              "rotation_losses: ", object.size(), " object flags and ", centres.size(),
              " centres for ", B, " samples of ", M, " points");
    const int K = net.config().num_keypoints;
    // The rotation unit of each sample (mm per unit) and its inverse, [B, 1, 1].
    const bool unit = net.config().rot_unit != "mm";
    Tensor scale, inv_scale;
    rotation_scales(net, samples, keypoints, symmetric, opt, &scale, &inv_scale);
    // In the rotation unit (identity for mm).
    auto in_unit = [&](const Tensor& t) { return unit ? nn::mul(t, inv_scale) : t; };

    const nn::RotOut rot = net.rot_forward(xr, onehot, scale);
    Tensor vec_target = Tensor::zeros({B, 3 * int64_t(K), M});
    Tensor kp_target = Tensor::empty({B, K, 3});
    // Targets: the GT keypoints R * kp + (t - centre) (of the symmetric set nearest block B's
    // prediction when `symmetric` is given) and, for object points, unit vectors to them (spec
    // §5).
    int64_t n_sym = 0;
    for (int64_t b = 0; b < B; ++b) {
        const PoseSample& s = samples[size_t(b)];
        const Eigen::Vector3f off = s.t - centres[size_t(b)];
        const KeypointTable* sets = symmetric ? &(*symmetric)[size_t(s.class_index)] : nullptr;
        const std::vector<Eigen::Vector3f>* kpm = &keypoints[size_t(s.class_index)];
        if (sets) {
            const float* pred = rot.keypoints.data<float>() + b * K * 3;
            double best = -1;
            size_t best_i = 0;
            for (size_t i = 0; i < sets->size(); ++i) {
                G2L_CHECK(int((*sets)[i].size()) == K, "g2l_step: symmetric keypoint set ", i,
                          " of class index ", s.class_index, " has ", (*sets)[i].size(),
                          " keypoints, expected ", K);
                double d = 0;
                for (int k = 0; k < K; ++k)
                    d += (s.R * (*sets)[i][size_t(k)] + off -
                          Eigen::Map<const Eigen::Vector3f>(pred + k * 3))
                             .squaredNorm();
                if (best < 0 || d < best) best = d, best_i = i;
            }
            kpm = &(*sets)[best_i];
            n_sym += best_i != 0;
        }
        std::vector<Eigen::Vector3f> kpc(static_cast<size_t>(K));  // canonical-frame keypoints
        for (int k = 0; k < K; ++k) {
            kpc[size_t(k)] = s.R * (*kpm)[size_t(k)] + off;
            for (int c = 0; c < 3; ++c) kp_target.data<float>()[(b * K + k) * 3 + c] = kpc[size_t(k)][c];
        }
        if (!rot.vectors.defined()) continue;
        const float* pr = xr.data<float>() + b * 3 * M;
        float* pv = vec_target.data<float>() + b * 3 * K * M;
        for (int64_t m = 0; m < M; ++m) {
            if (!object[size_t(b * M + m)]) continue;  // background: zero targets
            const Eigen::Vector3f c(pr[m], pr[M + m], pr[2 * M + m]);
            for (int k = 0; k < K; ++k) {
                Eigen::Vector3f v = kpc[size_t(k)] - c;
                const float len = v.norm();
                if (len > 1e-6f) v /= len;
                for (int a = 0; a < 3; ++a) pv[(k * 3 + a) * M + m] = v[a];
            }
        }
    }
    out->sym_fraction = double(n_sym) / double(B);
    Tensor total;
    auto add = [&total](const Tensor& t) { total = total.defined() ? total + t : t; };
    if (rot.vectors.defined()) {
        const Tensor l_vec = nn::mse_loss(rot.vectors, vec_target);
        out->vec = l_vec.item<double>();
        add(nn::mul_scalar(l_vec, w.vec));
    }
    const Tensor kp_target_u = in_unit(kp_target);
    const Tensor l_kp = nn::mse_loss(in_unit(rot.keypoints), kp_target_u);
    out->kp = l_kp.item<double>();
    add(nn::mul_scalar(l_kp, w.kp));
    Tensor final_kp = rot.keypoints;
    if (rot.residual.defined()) {
        const Tensor base = residual_base(rot.keypoints, samples, keypoints, K);
        final_kp = base + rot.residual;
        const Tensor l_res = nn::mse_loss(in_unit(final_kp), kp_target_u);
        out->res = l_res.item<double>();
        add(nn::mul_scalar(l_res, w.res));
    }
    out->kp_error_mm = mean_keypoint_error(final_kp, kp_target);
    return total;
}

}  // namespace g2l::train
