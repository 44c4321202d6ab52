// SPDX-License-Identifier: MIT
#include "nn/models/g2l_pose.h"

#include <chrono>

#include "core/autograd.h"
#include "geometry/kabsch.h"

namespace g2l::nn {

namespace {
using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
// [1, 3, N] channel-first tensor of rows `idx` of pts minus `centre`.
Tensor to_input(const geom::Points& pts, const std::vector<int>& idx, const Eigen::Vector3f& centre) {
    const int64_t N = int64_t(idx.size());
    Tensor x = Tensor::empty({1, 3, N});  // host: filled from the host point cloud
    float* p = x.data<float>();
    for (int64_t n = 0; n < N; ++n)
        for (int c = 0; c < 3; ++c) p[c * N + n] = pts(idx[size_t(n)], c) - centre[c];
    return x;
}
}  // namespace

std::vector<int> even_sample(int size, int n) {
    std::vector<int> out;
    even_sample_into(size, n, &out);
    return out;
}

void even_sample_into(int size, int n, std::vector<int>* out) {
    out->clear();
    if (size <= 0 || n <= 0) return;
    out->reserve(size_t(n));
    if (size >= n) {
        for (int i = 0; i < n; ++i) out->push_back(int(int64_t(i) * size / n));
    } else {
        for (int i = 0; i < size; ++i) out->push_back(i);
        const int extra = n - size;
        for (int i = 0; i < extra; ++i) out->push_back(int(int64_t(i) * size / extra));
    }
}

PoseEstimate estimate_pose(G2LNet& net, const geom::Points& pts, int class_index,
                           const std::vector<Eigen::Vector3f>& model_keypoints, int max_points,
                           int crop_points_n) {
    const G2LConfig& cfg = net.config();
    G2L_CHECK(class_index >= 0 && class_index < cfg.num_classes, "estimate_pose: class index ",
              class_index, " outside [0, ", cfg.num_classes, ")");
    G2L_CHECK(int(model_keypoints.size()) == cfg.num_keypoints, "estimate_pose: ",
              model_keypoints.size(), " model keypoints, the network predicts ",
              cfg.num_keypoints);
    autograd::NoGradGuard no_grad;
    PoseEstimate est;
    if (pts.rows() < 10) {
        est.status = "too few crop points";
        return est;
    }
    Tensor onehot = Tensor::zeros({1, cfg.num_classes});  // host: filled on the host
    onehot.data<float>()[class_index] = 1.f;

    // 1. segmentation on the crop centred by its mean
    auto t0 = Clock::now();
    std::vector<int> all;
    if (crop_points_n > 0) {
        all = even_sample(int(pts.rows()), crop_points_n);
    } else {
        all.resize(size_t(pts.rows()));
        for (size_t i = 0; i < all.size(); ++i) all[i] = int(i);
    }
    // The mean of the points the seg net sees (training centres its input the same way).
    Eigen::Vector3f mean_all = Eigen::Vector3f::Zero();
    for (int i : all) mean_all += pts.row(i).transpose();
    mean_all /= float(all.size());
    const Tensor logp = net.seg_forward(to_input(pts, all, mean_all), onehot);
    const int64_t N = int64_t(all.size());
    std::vector<int> obj;
    for (int64_t n = 0; n < N; ++n)
        if (logp.data<float>()[N + n] > logp.data<float>()[n]) obj.push_back(all[size_t(n)]);
    est.ms_seg = ms_since(t0);
    est.num_object_points = int(obj.size());
    if (obj.size() < 10) {
        est.status = "too few object points";
        return est;
    }
    if (max_points > 0) {
        std::vector<int> sub;
        for (int i : even_sample(int(obj.size()), max_points)) sub.push_back(obj[size_t(i)]);
        obj.swap(sub);
    }

    // 2. translation = mean of the object points + residual
    t0 = Clock::now();
    Eigen::Vector3f mean = Eigen::Vector3f::Zero();
    for (int i : obj) mean += pts.row(i).transpose();
    mean /= float(obj.size());
    const Tensor res = net.t_forward(to_input(pts, obj, mean), onehot);
    const Eigen::Vector3f T = mean + Eigen::Vector3f(res.data<float>()[0], res.data<float>()[1],
                                                     res.data<float>()[2]);
    est.ms_t = ms_since(t0);

    // 3. rotation in the canonical frame (points - T)
    t0 = Clock::now();
    Tensor scale;
    if (cfg.rot_unit != "mm") {
        scale = Tensor::empty({1, 1, 1});  // host: filled on the host
        scale.data<float>()[0] = float(rotation_scale(cfg.rot_unit, model_keypoints));
    }
    const RotOut rot = net.rot_forward(to_input(pts, obj, T), onehot, scale);
    const int K = cfg.num_keypoints;
    geom::Points P(K, 3), Q(K, 3);
    for (int k = 0; k < K; ++k) {
        P.row(k) = model_keypoints[size_t(k)].transpose();
        for (int c = 0; c < 3; ++c) Q(k, c) = rot.keypoints.data<float>()[k * 3 + c];
    }
    Eigen::Matrix3d R = geom::kabsch(P, Q);
    if (rot.residual.defined()) {
        geom::Points Pc(K, 3);
        for (int k = 0; k < K; ++k)
            for (int c = 0; c < 3; ++c)
                Pc(k, c) = float((R * P.row(k).transpose().cast<double>())[c]) +
                           rot.residual.data<float>()[k * 3 + c];
        R = geom::kabsch(P, Pc);
    }
    est.ms_rot = ms_since(t0);
    est.pose.R = R;
    est.pose.t = T.cast<double>();
    est.ok = true;
    est.status = "ok";
    return est;
}

}  // namespace g2l::nn
