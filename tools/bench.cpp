// SPDX-License-Identifier: MIT
#include "tools/bench.h"

#include <unistd.h>

#include <cstdio>

#include <sys/resource.h>

#include <cmath>
#include "nn/models/g2l_engine.h"
#include "nn/models/g2l_pose.h"

#include <algorithm>
#include <Eigen/Geometry>
#include <chrono>

#include "core/autograd.h"
#include "core/error.h"
#include "core/rng.h"
#include "data/render_primitives.h"
#include "geometry/labels.h"
#include "geometry/metrics.h"
#include "geometry/model_info.h"
#include "geometry/refine.h"
#include "infer/frame_pipeline.h"
#include "kernels/gemm.h"
#include "nn/models/detector.h"
#include "nn/models/g2l_net.h"
#include "nn/ops/concat_conv.h"
#include "nn/ops/linear.h"
#include "nn/optim.h"
#include "train/pipeline.h"

namespace g2l::tools {

// Tools measure the training code: its names are used as they are.
using namespace g2l::train;

double median_seconds(const std::function<void()>& fn, int reps, int warmup) {
    for (int i = 0; i < warmup; ++i) fn();
    std::vector<double> t;
    for (int i = 0; i < std::max(1, reps); ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        fn();
        t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    std::sort(t.begin(), t.end());
    return t[t.size() / 2];
}

namespace {

// The 90th percentile of sorted timings (the smallest value >= 90% of them).
double p90_of(const std::vector<double>& sorted) {
    return sorted[std::min(sorted.size() - 1, size_t(std::ceil(0.9 * double(sorted.size()))) - 1)];
}

// One shared-MLP layer x [B, Cin, N] -> [B, Cout, N]: forward-only and forward+backward figures.
void bench_shared_mlp(std::vector<BenchFigure>& out, const std::string& key, int64_t B,
                      int64_t Cin, int64_t N, int64_t Cout, int reps) {
    Rng rng(1);
    Tensor x = Tensor::randn({B, Cin, N}, rng);
    Tensor w = Tensor::randn({Cout, Cin}, rng);
    Tensor b = Tensor::randn({Cout}, rng);
    const double flops = 2.0 * double(B) * Cin * N * Cout;
    const std::string shape = "[" + std::to_string(B) + ", " + std::to_string(Cin) + ", " +
                              std::to_string(N) + "] -> " + std::to_string(Cout);
    const double tf = median_seconds([&] {
        autograd::NoGradGuard g;
        nn::conv1x1(x, w, b);
    }, reps);
    x.set_requires_grad();
    w.set_requires_grad();
    b.set_requires_grad();
    Tensor dy = Tensor::randn({B, Cout, N}, rng);
    const double tfb = median_seconds([&] {
        x.zero_grad();
        w.zero_grad();
        b.zero_grad();
        nn::conv1x1(x, w, b).backward(dy);
    }, reps);
    out.push_back({key + "_fwd_gflops", flops / tf / 1e9, "GFLOP/s", "conv1x1 forward " + shape});
    out.push_back({key + "_fwdbwd_gflops", 3 * flops / tfb / 1e9, "GFLOP/s",
                   "conv1x1 forward + backward (dx, dw, db) " + shape});
    out.push_back({key + "_fwdbwd_ms", tfb * 1e3, "ms", "conv1x1 forward + backward " + shape});
}

// A head's first layer as the network runs it: concat_conv1x1 over per-point features
// [B, Cp, N] and global ones [B, Cg] (the global part once per cloud, never tiled).
void bench_concat_conv(std::vector<BenchFigure>& out, const std::string& key, int64_t B,
                       int64_t Cp, int64_t Cg, int64_t N, int64_t Cout, int reps) {
    Rng rng(3);
    Tensor x = Tensor::randn({B, Cp, N}, rng), g = Tensor::randn({B, Cg}, rng);
    Tensor w = Tensor::randn({Cout, Cp + Cg}, rng), b = Tensor::randn({Cout}, rng);
    const double flops = 2.0 * double(B) * double(Cout) * (double(Cp) * N + double(Cg));
    const std::string shape = "[" + std::to_string(B) + ", " + std::to_string(Cp) + ", " +
                              std::to_string(N) + "] + global [" + std::to_string(B) + ", " +
                              std::to_string(Cg) + "] -> " + std::to_string(Cout);
    const double tf = median_seconds([&] {
        autograd::NoGradGuard ng;
        nn::concat_conv1x1({x}, {g}, w, b);
    }, reps);
    for (Tensor* t : {&x, &g, &w, &b}) t->set_requires_grad();
    Tensor dy = Tensor::randn({B, Cout, N}, rng);
    const double tfb = median_seconds([&] {
        for (Tensor* t : {&x, &g, &w, &b}) t->zero_grad();
        nn::concat_conv1x1({x}, {g}, w, b).backward(dy);
    }, reps);
    out.push_back({key + "_fwd_ms", tf * 1e3, "ms", "concat_conv1x1 forward " + shape});
    out.push_back({key + "_fwdbwd_ms", tfb * 1e3, "ms", "concat_conv1x1 forward + backward " + shape});
    out.push_back({key + "_fwd_gflops", flops / tf / 1e9, "GFLOP/s",
                   "concat_conv1x1 forward " + shape + " (executed FLOPs)"});
}

}  // namespace

std::vector<BenchFigure> bench_engine(int reps, bool quick) {
    std::vector<BenchFigure> out;
    // The headline figure: G2L-Net block B's first layer on one sample (spec §4.5).
    bench_shared_mlp(out, "shared_mlp", 1, 2280, 1000, 1024, reps);
    {
        const int64_t S = quick ? 1024 : 2048;
        Rng rng(2);
        Tensor a = Tensor::randn({S, S}, rng), b = Tensor::randn({S, S}, rng);
        Tensor c = Tensor::empty({S, S});
        const double t = median_seconds([&] {
            kernels::gemm_cpu<float>(false, false, S, S, S, 1.f, a.data<float>(), S,
                                     b.data<float>(), S, 0.f, c.data<float>(), S);
        }, reps);
        out.push_back({"gemm_peak_gflops", 2.0 * S * S * S / t / 1e9, "GFLOP/s",
                       "square SGEMM " + std::to_string(S) + "^3 (gemm_cpu)"});
    }
    if (!quick) {
        // The other large layers of one training batch (B = 8; 1500 points in the seg net,
        // 1000 after segmentation), spec §4.2-§4.6.
        // Head first layers run concat_conv1x1: per-point x1, x2, pf (64 + 128 + 1024) and the
        // global g + one-hot (1024 + 16) computed once per cloud.
        bench_concat_conv(out, "seg_head1_b8", 8, 1216, 1040, 1500, 512, std::max(1, reps / 2));
        bench_shared_mlp(out, "backbone_conv5_b8", 8, 128, 1500, 1024, std::max(1, reps / 2));
        bench_concat_conv(out, "rre_conv1_b8", 8, 1216, 1040, 1000, 256, std::max(1, reps / 2));
    }
    return out;
}

std::vector<BenchFigure> bench_training(int reps, double width, int batch, int points,
                                        int seg_points) {
    const int classes = 16, K = 8;
    nn::G2LConfig mc;
    mc.num_classes = classes;
    mc.width = width;
    nn::G2LNet net(mc);
    nn::Adam adam(net.param_groups(), nn::AdamOptions{});
    // Random crops: a 100 mm object blob (label 1) inside a 300 mm background cloud.
    Rng rng(5);
    std::vector<PoseSample> batch_samples(static_cast<size_t>(batch));
    for (int b = 0; b < batch; ++b) {
        PoseSample& s = batch_samples[size_t(b)];
        s.obj_id = b % classes + 1;
        s.class_index = b % classes;
        s.points.resize(size_t(points) * 3);
        s.labels.resize(size_t(points));
        for (int n = 0; n < points; ++n) {
            const bool obj = n % 2 == 0;
            s.labels[size_t(n)] = obj;
            for (int c = 0; c < 3; ++c)
                s.points[size_t(n) * 3 + size_t(c)] = float(rng.uniform(-1, 1) * (obj ? 50 : 150));
        }
        s.num_object_points = points / 2;
    }
    KeypointTable kps(static_cast<size_t>(classes));
    for (auto& k : kps)
        for (int i = 0; i < K; ++i)
            k.emplace_back(float((i & 1) ? 40 : -40), float((i & 2) ? 30 : -30),
                           float((i & 4) ? 50 : -50));
    LossWeights lw;
    Rng step_rng(9);
    const auto step = [&] {
        adam.zero_grad();
        StepLosses L = g2l_step(net, batch_samples, kps, classes, seg_points, lw, step_rng);
        L.total.backward();
        adam.step();
    };
    const uint64_t flops0 = kernels::sgemm_flops_done();
    step();  // the warm-up step, whose GEMM work every step repeats
    const double gflop = double(kernels::sgemm_flops_done() - flops0) * 1e-9;
    const double t = median_seconds(step, reps, 0);
    const std::string what = "G2L-Net step (width " + std::to_string(width).substr(0, 4) +
                             ", batch " + std::to_string(batch) + ", " + std::to_string(points) +
                             " -> " + std::to_string(seg_points) + " points)";
    return {{"train_samples_per_s", batch / t, "samples/s", what},
            {"train_step_ms", t * 1e3, "ms", what},
            {"train_step_gemm_gflop", gflop, "GFLOP", "GEMM work of one step (" + what + ")"},
            {"train_gemm_gflops", gflop / t, "GFLOP/s",
             "GEMM work of one step over the step's time: the rate of useful GEMM work"}};
}

std::vector<BenchFigure> bench_pose(const std::string& prefix, int reps, double width,
                                    int crop_points, int object_points, bool engine) {
    G2L_CHECK(reps >= 1 && crop_points >= 1 && object_points >= 1,
              "bench_pose: reps, crop_points and object_points must be >= 1");
    nn::G2LConfig mc;
    mc.num_classes = 21;
    mc.width = width;
    mc.rot_unit = "kp_rms";
    nn::G2LNet net(mc);
    for (auto& [name, t] : net.named_parameters())
        if (name == "seg.out.bias") t.data<float>()[0] = -10.f, t.data<float>()[1] = 10.f;
    net.eval();
    Rng rng(17);
    geom::Points crop(20000, 3);
    for (int64_t i = 0; i < crop.rows(); ++i)
        crop.row(i) = Eigen::RowVector3f(float(rng.uniform(-150, 150)), float(rng.uniform(-150, 150)),
                                         float(800 + rng.uniform(-150, 150)));
    std::vector<Eigen::Vector3f> kp;
    for (int i = 0; i < 8; ++i)
        kp.emplace_back(float((i & 1) ? 40 : -40), float((i & 2) ? 30 : -30), float((i & 4) ? 50 : -50));
    std::vector<double> ms, st[3];
    nn::PoseEngine eng(net);
    std::vector<nn::PoseQuery> q = {{&crop, 3, &kp}};
    std::vector<nn::PoseEstimate> res;
    for (int r = 0; r < reps + 3; ++r) {
        const auto t0 = std::chrono::steady_clock::now();
        if (engine) eng.estimate(q, object_points, crop_points, &res);
        const nn::PoseEstimate e =
            engine ? res[0] : nn::estimate_pose(net, crop, 3, kp, object_points, crop_points);
        const double dt =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        G2L_CHECK(e.ok && e.num_object_points == crop_points, "bench_pose: the pipeline did not run "
                  "at full size (", e.status, ", ", e.num_object_points, " object points)");
        if (r >= 3) {
            ms.push_back(dt);
            st[0].push_back(e.ms_seg), st[1].push_back(e.ms_t), st[2].push_back(e.ms_rot);
        }
    }
    for (auto& v : st) std::sort(v.begin(), v.end());
    std::sort(ms.begin(), ms.end());
    const double med = ms[ms.size() / 2];
    const double p90 = p90_of(ms);
    const std::string what = std::string(engine ? "PoseEngine" : "eval-mode graph") + ", batch-1 pose, width " + std::to_string(width).substr(0, 4) + ", " +
                             std::to_string(crop_points) + " -> " + std::to_string(object_points) +
                             " points, " + std::to_string(reps) + " runs";
    return {{prefix, med, "ms", what}, {prefix + "_p90", p90, "ms", what},
            {prefix + "_min", ms.front(), "ms", what},
            {prefix + "_seg", st[0][st[0].size() / 2], "ms", "segmentation stage (median)"},
            {prefix + "_t", st[1][st[1].size() / 2], "ms", "translation stage (median)"},
            {prefix + "_rot", st[2][st[2].size() / 2], "ms", "rotation stage: blocks A, B, C + Kabsch (median)"}};
}

std::vector<BenchFigure> bench_detector(int reps, int width, int downscale, bool mirror) {
    G2L_CHECK(reps >= 1, "bench_detector: reps must be >= 1");
    nn::DetectorConfig dc;
    dc.num_classes = 8;
    dc.width = width;
    nn::Detector net(dc);
    net.eval();
    Rng rng(5);
    std::vector<uint8_t> rgb(size_t(640) * 480 * 3);
    for (auto& v : rgb) v = uint8_t(rng.below(256));
    std::vector<double> ms;
    for (int r = 0; r < reps + 3; ++r) {
        const auto t0 = std::chrono::steady_clock::now();
        const auto d = nn::detect(net, downscale, rgb.data(), 640, 480, 0.05f, 5, mirror);
        const double dt =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        if (r >= 3) ms.push_back(dt);
    }
    std::sort(ms.begin(), ms.end());
    const double p90 = p90_of(ms);
    const std::string what = "2D detector on a 640 x 480 frame (downscale " +
                             std::to_string(downscale) + ", width " + std::to_string(width) +
                             ", 8 classes" + (mirror ? ", mirrored second pass" : "") + "), " +
                             std::to_string(reps) + " runs";
    const std::string name = mirror ? "detector_mirror_ms" : "detector_ms";
    return {{name, ms[ms.size() / 2], "ms", what}, {name + "_p90", p90, "ms", what}};
}

std::vector<BenchFigure> bench_refine(int reps) {
    G2L_CHECK(reps >= 1, "bench_refine: reps must be >= 1");
    // The model: a 150 x 90 x 60 mm box with a 30 mm cube on one corner of its top face (no
    // turn maps it onto itself), its vertices and surface samples 2 mm apart (as for a mesh).
    const geom::Mesh body = data::make_box(150, 90, 60), bump = data::make_box(30, 30, 30);
    geom::Mesh mesh;
    mesh.vertices.resize(body.vertices.rows() + bump.vertices.rows(), 3);
    mesh.vertices << body.vertices,
        bump.vertices.rowwise() + Eigen::RowVector3f(60, 30, 45);
    mesh.faces.resize(body.faces.rows() + bump.faces.rows(), 3);
    mesh.faces << body.faces, bump.faces.array() + int32_t(body.vertices.rows());
    // What the frame pipeline prepares once per model (infer/frame_pipeline.h), timed.
    auto build = std::chrono::steady_clock::now();
    const infer::PreparedMesh pm =
        infer::PreparedMesh::from_mesh(mesh, geom::compute_model_info(mesh.vertices), true);
    const double build_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - build).count();
    const geom::ModelKdTree& tree = *pm.tree;
    const geom::Points& model = tree.points();
    const geom::Points& normals = pm.normals;
    const geom::ModelInfo& info = pm.info;
    // The scene: the box standing on a table plane, seen from 800 mm and 40 degrees above.
    geom::Intrinsics K;
    K.fx = K.fy = 600;
    K.cx = 320;
    K.cy = 240;
    K.width = 640;
    K.height = 480;
    const Eigen::Matrix3d tilt =
        Eigen::AngleAxisd(-50 * 3.14159265358979 / 180, Eigen::Vector3d::UnitX()).toRotationMatrix();
    geom::Pose gt;
    gt.R = tilt * Eigen::AngleAxisd(0.6, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    gt.t = Eigen::Vector3d(10, -5, 800);
    const Eigen::Vector3d up = gt.R.col(2);  // the table's normal (towards the camera side)
    const Eigen::Vector3d on_table = gt.t - 30.0 * up;  // the box's bottom face, 30 mm below
    std::vector<float> depth(size_t(K.width) * size_t(K.height), 0.f);
    for (int v = 0; v < K.height; ++v)
        for (int u = 0; u < K.width; ++u) {
            const Eigen::Vector3d ray((u + 0.5 - K.cx) / K.fx, (v + 0.5 - K.cy) / K.fy, 1.0);
            const double den = up.dot(ray);
            if (std::abs(den) < 1e-9) continue;
            const double z = up.dot(on_table) / den;
            if (z > 0) depth[size_t(v) * K.width + u] = float(z);
        }
    std::vector<int64_t> owner(depth.size(), -1);
    for (int64_t i = 0; i < model.rows(); ++i) {  // z-buffer of the posed model points
        const Eigen::Vector3d q = gt.R * model.row(i).transpose().cast<double>() + gt.t;
        const int u = int(K.fx * q.x() / q.z() + K.cx), v = int(K.fy * q.y() / q.z() + K.cy);
        if (u < 0 || v < 0 || u >= K.width || v >= K.height) continue;
        float& z = depth[size_t(v) * K.width + u];
        if (q.z() < z || owner[size_t(v) * K.width + u] < 0) {
            z = float(q.z());
            owner[size_t(v) * K.width + u] = i;
        }
    }
    std::vector<Eigen::Vector3f> seen;
    for (size_t p = 0; p < owner.size(); ++p)
        if (owner[p] >= 0)
            seen.push_back((gt.R * model.row(owner[p]).transpose().cast<double>() + gt.t).cast<float>());
    // ~1,000 of them, evenly strided: about the object points of a crop of sampling.points.
    const size_t n_obs = std::min<size_t>(seen.size(), 1000);
    geom::Points obs(int64_t(n_obs), 3);
    for (size_t i = 0; i < n_obs; ++i) obs.row(int64_t(i)) = seen[i * seen.size() / n_obs].transpose();
    geom::Pose start = gt;
    start.R = Eigen::AngleAxisd(20 * 3.14159265358979 / 180, Eigen::Vector3d(1, 2, 3).normalized()) * gt.R;
    start.t += Eigen::Vector3d(10, -8, 8);
    const geom::DepthImage di{depth.data(), K};
    const geom::RefineOptions ro;  // the defaults --refine turns runs
    const geom::ClosestPointGrid& grid = pm.grid;
    auto time = [&](const geom::ClosestPointGrid* g, std::vector<double>* ms) {
        for (int r = 0; r < reps + 1; ++r) {
            const auto t0 = std::chrono::steady_clock::now();
            const geom::RefineResult rr = geom::refine_pose(tree, info, obs, start, ro, &di, &normals, g);
            const double dt = std::chrono::duration<double, std::milli>(
                                  std::chrono::steady_clock::now() - t0).count();
            G2L_CHECK(geom::rotation_error_deg(rr.pose.R, gt.R) < 2,
                      "bench_refine: the refinement missed the pose (",
                      geom::rotation_error_deg(rr.pose.R, gt.R), " deg)");
            if (r >= 1) ms->push_back(dt);
        }
        std::sort(ms->begin(), ms->end());
    };
    std::vector<double> fast, exact;
    time(&grid, &fast);
    time(nullptr, &exact);
    const double p90 = p90_of(fast);
    const std::string what = "refine_pose, turns, " + std::to_string(obs.rows()) +
                             " observed points of a " + std::to_string(model.rows()) +
                             "-point box, " + std::to_string(reps) + " runs";
    return {{"refine_ms", fast[fast.size() / 2], "ms", what + " (closest-point grid)"},
            {"refine_ms_p90", p90, "ms", what + " (closest-point grid)"},
            {"refine_tree_ms", exact[exact.size() / 2], "ms", what + " (k-d tree only)"},
            {"refine_prepare_ms", build_ms, "ms",
             "infer::PreparedMesh: k-d tree, normals and a closest-point grid of " +
                 std::to_string(grid.size()) + " cells of " + std::to_string(grid.cell_mm()) +
                 " mm (once per model)"}};
}

double current_rss_mb() {
    std::FILE* f = std::fopen("/proc/self/statm", "r");
    if (!f) return -1;
    long pages = 0, resident = 0;
    const int n = std::fscanf(f, "%ld %ld", &pages, &resident);
    std::fclose(f);
    return n == 2 ? double(resident) * double(sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0) : -1;
}

double peak_rss_mb() {
    struct rusage u;
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

}  // namespace g2l::tools
