// SPDX-License-Identifier: MIT
#include "nn/models/detector.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "core/autograd.h"
#include "core/checkpoint.h"
#include "core/json.h"
#include "core/json_reader.h"
#include "core/error.h"
#include "nn/ops/elementwise.h"
#include "nn/ops/relu.h"
#include "nn/ops/upsample.h"

namespace g2l::nn {

using json = nlohmann::json;
constexpr const char* kDetectorExportFormat = "g2l-detector";

const char* to_string(DetectorInput input) {
    switch (input) {
        case DetectorInput::rgb: return "rgb";
        case DetectorInput::depth: return "depth";
        case DetectorInput::rgbd: return "rgbd";
    }
    return "?";
}

DetectorInput parse_detector_input(const std::string& text, const std::string& where) {
    if (text == "rgb") return DetectorInput::rgb;
    if (text == "depth") return DetectorInput::depth;
    if (text == "rgbd") return DetectorInput::rgbd;
    G2L_CHECK(false, where, ": the detector input must be \"rgb\", \"depth\" or \"rgbd\", got \"",
              text, "\"");
    return DetectorInput::rgb;
}

int detector_input_channels(DetectorInput input) {
    return input == DetectorInput::rgb ? 3 : input == DetectorInput::depth ? kDepthChannels
                                                                            : 3 + kDepthChannels;
}

void validate(const DetectorConfig& cfg) {
    G2L_CHECK(cfg.num_classes >= 1 && cfg.num_classes <= 4096,
              "detector: num_classes must be in [1, 4096], got ", cfg.num_classes);
    G2L_CHECK(cfg.width >= 4 && cfg.width <= 256, "detector: width must be in [4, 256], got ",
              cfg.width);
}

ConvBnRelu::ConvBnRelu(int64_t in, int64_t out, int64_t stride, Rng& rng) {
    conv = register_module("conv", std::make_shared<Conv2d>(in, out, std::array<int64_t, 2>{3, 3},
                                                            rng, std::array<int64_t, 2>{stride, stride},
                                                            std::array<int64_t, 2>{1, 1}));
    bn = register_module("bn", std::make_shared<BatchNorm>(out));
}

Tensor ConvBnRelu::forward(const Tensor& x) { return relu(bn->forward(conv->forward(x))); }

Detector::Detector(const DetectorConfig& cfg) : cfg_(cfg) {
    validate(cfg);
    Rng rng(cfg.seed);
    const int64_t c = cfg.width;
    stem_ = register_module("stem", std::make_shared<ConvBnRelu>(detector_input_channels(cfg.input), c, 2, rng));
    d4a_ = register_module("d4a", std::make_shared<ConvBnRelu>(c, 2 * c, 2, rng));
    d4b_ = register_module("d4b", std::make_shared<ConvBnRelu>(2 * c, 2 * c, 1, rng));
    d8a_ = register_module("d8a", std::make_shared<ConvBnRelu>(2 * c, 4 * c, 2, rng));
    d8b_ = register_module("d8b", std::make_shared<ConvBnRelu>(4 * c, 4 * c, 1, rng));
    d16a_ = register_module("d16a", std::make_shared<ConvBnRelu>(4 * c, 4 * c, 2, rng));
    d16b_ = register_module("d16b", std::make_shared<ConvBnRelu>(4 * c, 4 * c, 1, rng));
    lat8_ = register_module("lat8", std::make_shared<Conv2d>(4 * c, 4 * c,
                                                             std::array<int64_t, 2>{1, 1}, rng));
    up8_ = register_module("up8", std::make_shared<ConvBnRelu>(4 * c, 2 * c, 1, rng));
    lat4_ = register_module("lat4", std::make_shared<Conv2d>(2 * c, 2 * c,
                                                             std::array<int64_t, 2>{1, 1}, rng));
    up4_ = register_module("up4", std::make_shared<ConvBnRelu>(2 * c, 2 * c, 1, rng));
    head_ = register_module("head", std::make_shared<ConvBnRelu>(2 * c, 2 * c, 1, rng));
    const std::array<int64_t, 2> k1{1, 1};
    heat_ = register_module("heat", std::make_shared<Conv2d>(2 * c, cfg.num_classes, k1, rng));
    size_ = register_module("size", std::make_shared<Conv2d>(2 * c, 2, k1, rng));
    offset_ = register_module("offset", std::make_shared<Conv2d>(2 * c, 2, k1, rng));
    // CenterNet's prior: every cell starts at probability ~0.1 of being a centre, so the focal
    // loss of the many empty cells does not swamp the first steps.
    autograd::NoGradGuard no_grad;
    heat_->bias.fill_(-2.19);
}

DetOut Detector::forward(const Tensor& x) {
    const int channels = detector_input_channels(cfg_.input);
    G2L_CHECK(x.defined() && x.dim() == 4 && x.size(1) == channels && x.size(0) > 0 &&
                  x.size(2) > 0 && x.size(3) > 0 && x.size(2) % 16 == 0 && x.size(3) % 16 == 0,
              "Detector: expected the ", to_string(cfg_.input), " input as [B, ", channels,
              ", H, W] with H and W positive multiples of 16, got ",
              x.defined() ? x.desc() : std::string("undefined"));
    const Tensor f2 = stem_->forward(x);
    const Tensor f4 = d4b_->forward(d4a_->forward(f2));
    const Tensor f8 = d8b_->forward(d8a_->forward(f4));
    const Tensor f16 = d16b_->forward(d16a_->forward(f8));
    const Tensor g8 = up8_->forward(add(upsample_nearest2d(f16, 2), lat8_->forward(f8)));
    const Tensor g4 = up4_->forward(add(upsample_nearest2d(g8, 2), lat4_->forward(f4)));
    const Tensor h = head_->forward(g4);
    return {heat_->forward(h), size_->forward(h), offset_->forward(h)};
}

void widen_detector(const Detector& from, Detector& wide, uint64_t seed, double spread) {
    const DetectorConfig& a = from.config();
    const DetectorConfig& b = wide.config();
    G2L_CHECK(a.num_classes == b.num_classes && a.input == b.input,
              "widen_detector: the detectors differ in classes (", a.num_classes, " vs ",
              b.num_classes, ") or input (", to_string(a.input), " vs ", to_string(b.input), ")");
    G2L_CHECK(b.width >= a.width && b.width % a.width == 0,
              "widen_detector: width ", b.width, " is not a whole multiple of width ", a.width);
    G2L_CHECK(spread >= 0 && spread < 1, "widen_detector: spread must be in [0, 1), got ", spread);
    // Every channel count of the network is (1, 2 or 4) x width, and its one merge is an add
    // of two maps of the same count, so "new channel i is old channel i mod n" is consistent
    // across producer and consumer: widening every tensor dimension by that rule preserves
    // the function once the consumers' input weights are split among the copies.
    // The widened tensors are made apart and loaded once: a shape that does not fit leaves
    // `wide` as it was.
    const std::map<std::string, Tensor> src = from.state_dict();
    const std::map<std::string, Tensor> dst = wide.state_dict();
    std::map<std::string, Tensor> widened;
    Rng rng(seed);
    for (const auto& [name, t] : dst) {
        const auto it = src.find(name);
        G2L_CHECK(it != src.end(), "widen_detector: '", name, "' missing in the narrow detector");
        const Tensor& s = it->second;
        if (t.dtype() != DType::F32) {  // BatchNorm's step counter: one value, copied
            G2L_CHECK(s.shape() == t.shape() && s.dtype() == t.dtype(), "widen_detector: '",
                      name, "' is ", s.desc(), " -> ", t.desc());
            widened.emplace(name, s.clone());
            continue;
        }
        G2L_CHECK(s.dim() == t.dim() && (t.dim() == 1 || t.dim() == 4),
                  "widen_detector: '", name, "' has shape ", s.desc(), " -> ", t.desc());
        const int64_t O = s.size(0), Ow = t.size(0);
        const int64_t I = t.dim() == 4 ? s.size(1) : 1, Iw = t.dim() == 4 ? t.size(1) : 1;
        const int64_t K = t.dim() == 4 ? s.size(2) * s.size(3) : 1;
        G2L_CHECK(Ow % O == 0 && Iw % I == 0 && (t.dim() == 1 || t.size(2) * t.size(3) == K),
                  "widen_detector: '", name, "' has shape ", s.desc(), " -> ", t.desc());
        const int64_t k = Iw / I;  // copies of each input channel
        const float* sp = s.data<float>();
        std::vector<float> out(size_t(Ow * Iw * K));
        for (int64_t o = 0; o < Ow; ++o)
            for (int64_t i = 0; i < I; ++i)
                for (int64_t e = 0; e < K; ++e) {
                    const float v = sp[((o % O) * I + i) * K + e];
                    // shares of the k copies: 1/k each, moved by zero-sum noise
                    double left = 1.0;
                    for (int64_t c = 0; c < k; ++c) {
                        double share = left;
                        if (c + 1 < k) {
                            share = (1.0 + rng.uniform(-spread, spread)) / double(k);
                            left -= share;
                        }
                        out[size_t((o * Iw + c * I + i) * K + e)] = float(double(v) * share);
                    }
                }
        widened.emplace(name, Tensor::from_vector(out, t.shape()));
    }
    wide.load_state_dict(widened, true);
}

std::vector<Detection> decode_detections(const float* prob, const float* size,
                                         const float* offset, int K, int w, int h,
                                         float min_score, int max_per_class, int stride) {
    G2L_CHECK(prob && size && offset, "decode_detections: null buffer");
    G2L_CHECK(K > 0 && h > 0 && w > 0 && max_per_class > 0 && stride > 0,
              "decode_detections: sizes must be > 0, got K ", K, ", ", w, " x ", h,
              ", max_per_class ", max_per_class, ", stride ", stride);
    const size_t plane = size_t(h) * size_t(w);
    // Each class's peaks on its own (OpenMP over the classes), joined in class order after:
    // the same list whatever the thread count.
    std::vector<std::vector<Detection>> per_class(static_cast<size_t>(K));
#pragma omp parallel for schedule(dynamic, 1)
    for (int k = 0; k < K; ++k) {
        const float* p = prob + size_t(k) * plane;
        std::vector<Detection>& mine = per_class[size_t(k)];
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                const float v = p[size_t(y) * size_t(w) + size_t(x)];
                if (!(v >= min_score)) continue;
                bool peak = true;
                for (int dy = -1; dy <= 1 && peak; ++dy) {
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int yy = y + dy, xx = x + dx;
                        if ((dy == 0 && dx == 0) || yy < 0 || yy >= h || xx < 0 || xx >= w)
                            continue;
                        const float n = p[size_t(yy) * size_t(w) + size_t(xx)];
                        // A neighbour beats this cell if larger, or equal and earlier.
                        const bool earlier = yy < y || (yy == y && xx < x);
                        if (n > v || (n == v && earlier)) {
                            peak = false;
                            break;
                        }
                    }
                }
                if (!peak) continue;
                const size_t i = size_t(y) * size_t(w) + size_t(x);
                Detection d;
                d.cls = k;
                d.score = v;
                const float ox = std::clamp(offset[i], -0.5f, 1.5f);
                const float oy = std::clamp(offset[plane + i], -0.5f, 1.5f);
                const float cx = (float(x) + ox) * float(stride);
                const float cy = (float(y) + oy) * float(stride);
                // Sizes are log(pixels / stride); clamp so a wild output cannot overflow.
                const float bw = std::exp(std::clamp(size[i], -4.f, 8.f)) * float(stride);
                const float bh = std::exp(std::clamp(size[plane + i], -4.f, 8.f)) * float(stride);
                d.peak_x = cx;
                d.peak_y = cy;
                d.x = cx - 0.5f * bw;
                d.y = cy - 0.5f * bh;
                d.w = bw;
                d.h = bh;
                mine.push_back(d);
            }
        }
        std::stable_sort(mine.begin(), mine.end(),
                         [](const Detection& a, const Detection& b) { return a.score > b.score; });
        if (int(mine.size()) > max_per_class) mine.resize(size_t(max_per_class));
    }
    std::vector<Detection> all;
    for (const auto& mine : per_class) all.insert(all.end(), mine.begin(), mine.end());
    std::stable_sort(all.begin(), all.end(),
                     [](const Detection& a, const Detection& b) { return a.score > b.score; });
    return all;
}

void depth_features(const float* depth_mm, int w, int h, double fx, double fy, double cx,
                    double cy, float* out, int64_t out_row, int64_t out_stride_plane) {
    G2L_CHECK(depth_mm && out && w > 0 && h > 0 && out_row >= w &&
                  out_stride_plane >= out_row * int64_t(h),
              "depth_features: bad sizes (", w, " x ", h, ", row ", out_row, ", plane ",
              out_stride_plane, ")");
    G2L_CHECK(std::isfinite(fx) && std::isfinite(fy) && fx > 0 && fy > 0 && std::isfinite(cx) &&
                  std::isfinite(cy),
              "depth_features: the intrinsics must be finite with fx, fy > 0, got fx ", fx,
              ", fy ", fy, ", cx ", cx, ", cy ", cy);
    const size_t n = size_t(w) * size_t(h);
    std::unique_ptr<float[]> z(new float[n]);  // every element written below
    // The per-pixel loops run on OpenMP's threads by rows (each pixel written once, on its own:
    // the same features whatever the thread count).
#pragma omp parallel for schedule(static)
    for (size_t i = 0; i < n; ++i) {
        const float v = depth_mm[i];
        z[i] = std::isfinite(v) && v > 0 ? v : 0.f;
    }
    // Summed-area tables of the measured depth and of the measured count, for the window means
    // of the normals' smoothing and of the relief.
    // The two tables are built side by side (one per thread, each by the same recurrence).
    // (Only their first row and column are zeroed: the recurrence writes every other element.)
    const size_t W1 = size_t(w) + 1;
    std::unique_ptr<double[]> sz(new double[W1 * (size_t(h) + 1)]), sn(new double[W1 * (size_t(h) + 1)]);
#pragma omp parallel for schedule(static, 1)
    for (int table = 0; table < 2; ++table) {
        double* q = table == 0 ? sz.get() : sn.get();
        std::fill(q, q + W1, 0.0);
        for (int y = 1; y <= h; ++y) q[size_t(y) * W1] = 0.0;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const float v = z[size_t(y) * size_t(w) + size_t(x)];
                const size_t i = size_t(y + 1) * W1 + size_t(x + 1);
                q[i] = (table == 0 ? double(v) : (v > 0 ? 1.0 : 0.0)) + q[i - 1] + q[i - W1] -
                       q[i - W1 - 1];
            }
    }
    // The mean measured z in the window of radius `rad` around (x, y) (the pixel's own window
    // holds at least the pixel when it is measured); 0 when none is.
    auto window_mean = [&](int x, int y, int rad) {
        const int x0 = std::max(0, x - rad), x1 = std::min(w, x + rad + 1);
        const int y0 = std::max(0, y - rad), y1 = std::min(h, y + rad + 1);
        auto rect = [&](const std::unique_ptr<double[]>& q) {
            return q[size_t(y1) * W1 + size_t(x1)] - q[size_t(y0) * W1 + size_t(x1)] -
                   q[size_t(y1) * W1 + size_t(x0)] + q[size_t(y0) * W1 + size_t(x0)];
        };
        const double count = rect(sn);
        return count > 0 ? rect(sz) / count : 0.0;
    };
    // Normals come from the depth smoothed over (2 kNormalSmooth + 1)^2 measured pixels: the
    // sensor's per-pixel noise would otherwise swamp the slope over a few millimetres.
    std::unique_ptr<float[]> zs(new float[n]);  // every element written below
#pragma omp parallel for schedule(static)
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            zs[i] = z[i] > 0 ? float(window_mean(x, y, kNormalSmooth)) : 0.f;
        }
    auto point = [&](int x, int y, Eigen::Vector3d* p) {
        if (x < 0 || y < 0 || x >= w || y >= h) return false;
        const double v = zs[size_t(y) * size_t(w) + size_t(x)];
        if (v <= 0) return false;
        *p = Eigen::Vector3d((x - cx) * v / fx, (y - cy) * v / fy, v);
        return true;
    };
    // The difference between the points on either side along one image axis (central where
    // both are measured, else one-sided against the centre).
    auto tangent = [&](int x, int y, int dx, int dy, const Eigen::Vector3d& c, Eigen::Vector3d* t) {
        Eigen::Vector3d a, b;
        const bool ha = point(x + dx, y + dy, &a), hb = point(x - dx, y - dy, &b);
        if (ha && hb) *t = a - b;
        else if (ha) *t = a - c;
        else if (hb) *t = c - b;
        else return false;
        return true;
    };
    const int s = kNormalStep, r = kReliefRadius;
#pragma omp parallel for schedule(static)
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const int64_t o = int64_t(y) * out_row + x;
            float f[kDepthChannels] = {0, 0, 0, 0, 0, 0};
            Eigen::Vector3d c;
            if (point(x, y, &c)) {
                const double v = z[size_t(y) * size_t(w) + size_t(x)];
                f[0] = 1;
                f[1] = float(std::clamp((v - 1000.0) / 500.0, -2.0, 4.0));
                f[2] = float(std::clamp((v - window_mean(x, y, r)) / 30.0, -3.0, 3.0));
                Eigen::Vector3d tx, ty;
                if (tangent(x, y, s, 0, c, &tx) && tangent(x, y, 0, s, c, &ty)) {
                    Eigen::Vector3d nrm = tx.cross(ty);
                    const double len = nrm.norm();
                    if (len > 1e-12) {
                        nrm /= len;
                        if (nrm.dot(c) > 0) nrm = -nrm;  // towards the camera
                        f[3] = float(nrm.x()), f[4] = float(nrm.y()), f[5] = float(nrm.z());
                    }
                }
            }
            for (int k = 0; k < kDepthChannels; ++k) out[k * out_stride_plane + o] = f[k];
        }
}

Tensor detector_input(const DetectorFrame& f, DetectorInput input, int downscale, int* in_w,
                      int* in_h) {
    G2L_CHECK(f.width > 0 && f.height > 0, "detector_input: empty frame (", f.width, " x ",
              f.height, ")");
    G2L_CHECK(downscale == 1 || downscale == 2 || downscale == 4,
              "detector_input: downscale must be 1, 2 or 4, got ", downscale);
    G2L_CHECK(!uses_rgb(input) || f.rgb, "detector_input: the ", to_string(input),
              " detector needs the frame's RGB image, and the frame has none");
    G2L_CHECK(!uses_depth(input) || f.depth_mm, "detector_input: the ", to_string(input),
              " detector needs the frame's depth image, and the frame has none");
    const int w = f.width / downscale, h = f.height / downscale;
    G2L_CHECK(w > 0 && h > 0, "detector_input: image ", f.width, " x ", f.height,
              " is smaller than the downscale ", downscale);
    const int W = (w + 15) / 16 * 16, H = (h + 15) / 16 * 16;
    const int C = detector_input_channels(input);
    Tensor x = Tensor::zeros({1, C, H, W});  // host: filled from the host image
    float* px = x.data<float>();
    const size_t plane = size_t(H) * size_t(W);
    if (uses_rgb(input)) {
        const float norm = 1.f / float(downscale * downscale);
#pragma omp parallel for schedule(static)
        for (int y = 0; y < h; ++y)
            for (int xx = 0; xx < w; ++xx)
                for (int c = 0; c < 3; ++c) {
                    float s = 0;
                    for (int dy = 0; dy < downscale; ++dy)
                        for (int dx = 0; dx < downscale; ++dx)
                            s += float(f.rgb[(size_t(y * downscale + dy) * size_t(f.width) +
                                              size_t(xx * downscale + dx)) * 3 + size_t(c)]);
                    px[size_t(c) * plane + size_t(y) * size_t(W) + size_t(xx)] =
                        (s * norm / 255.f - 0.5f) / 0.25f;
                }
    }
    if (uses_depth(input)) {
        std::vector<float> z(size_t(w) * size_t(h), 0.f);
#pragma omp parallel for schedule(static)
        for (int y = 0; y < h; ++y)
            for (int xx = 0; xx < w; ++xx) {
                float s = 0;
                int m = 0;
                for (int dy = 0; dy < downscale; ++dy)
                    for (int dx = 0; dx < downscale; ++dx) {
                        const float v = f.depth_mm[size_t(y * downscale + dy) * size_t(f.width) +
                                                   size_t(xx * downscale + dx)];
                        if (std::isfinite(v) && v > 0) s += v, ++m;
                    }
                z[size_t(y) * size_t(w) + size_t(xx)] = m ? s / float(m) : 0.f;
            }
        const double k = 1.0 / downscale;  // pixel centres: (u + 0.5) k - 0.5
        float* pd = px + (uses_rgb(input) ? 3 * plane : 0);
        depth_features(z.data(), w, h, f.fx * k, f.fy * k, (f.cx + 0.5) * k - 0.5,
                       (f.cy + 0.5) * k - 0.5, pd, W, int64_t(plane));
    }
    if (in_w) *in_w = W;
    if (in_h) *in_h = H;
    return x;
}

Tensor detector_input(const uint8_t* rgb, int width, int height, int downscale, int* in_w,
                      int* in_h) {
    DetectorFrame f;
    f.rgb = rgb, f.width = width, f.height = height;
    G2L_CHECK(rgb && width > 0 && height > 0, "detector_input: empty image (", width, " x ",
              height, ")");
    return detector_input(f, DetectorInput::rgb, downscale, in_w, in_h);
}

void save_detector(const std::string& path, const Detector& net,
                   const std::vector<int>& object_ids, int downscale) {
    std::vector<std::pair<std::string, Tensor>> tensors;
    for (const auto& [name, t] : net.state_dict()) tensors.emplace_back("model." + name, t);
    const json meta{{"format", kDetectorExportFormat},
                    {"version", 1},
                    {"num_classes", net.config().num_classes},
                    {"width", net.config().width},
                    {"object_ids", object_ids},
                    {"downscale", downscale},
                    {"input", to_string(net.config().input)},
                    {"stride", Detector::kStride}};
    save_checkpoint(path, tensors, meta.dump());
}

bool is_detector_export(const std::string& path) {
    const Checkpoint ck = load_checkpoint(path);
    const json meta = parse_json_strict(ck.meta_json, path + " (metadata)");
    return meta.is_object() && meta.value("format", "") == kDetectorExportFormat;
}

LoadedDetector load_detector(const std::string& path) {
    const Checkpoint ck = load_checkpoint(path);
    const json meta = parse_json_strict(ck.meta_json, path + " (metadata)");
    G2L_CHECK(meta.is_object() && meta.value("format", "") == kDetectorExportFormat, "'", path,
              "' is not a detector export (metadata format '",
              meta.is_object() ? meta.value("format", "") : std::string(), "', expected '",
              kDetectorExportFormat, "')");
    // Written by our exporter; read strictly like every JSON file (core/json_reader.h).
    JsonReader r(meta, "detector export '" + path + "' (metadata)");
    LoadedDetector d;
    DetectorConfig dc;
    for (const char* k : {"num_classes", "width", "downscale", "object_ids"}) r.require(k);
    r.integer("num_classes", dc.num_classes);
    r.integer("width", dc.width);
    r.integer("downscale", d.downscale);
    std::string input = to_string(dc.input);
    r.text("input", input);
    dc.input = parse_detector_input(input, "'" + path + "': input");
    G2L_CHECK(d.downscale == 1 || d.downscale == 2 || d.downscale == 4, "'", path,
              "': downscale must be 1, 2 or 4, got ", d.downscale);
    G2L_CHECK(dc.num_classes >= 1 && dc.num_classes <= 10000 && dc.width >= 1 &&
                  dc.width <= 4096,
              "'", path, "': num_classes ", dc.num_classes, " / width ", dc.width,
              " out of range");
    r.ints("object_ids", d.object_ids);
    r.ignore("format");  // checked above
    int version = 1, stride = Detector::kStride;
    r.integer("version", version);
    r.integer("stride", stride);
    G2L_CHECK(version == 1 && stride == Detector::kStride, "'", path, "': detector export version ",
              version, " with stride ", stride, " (this build reads version 1, stride ",
              Detector::kStride, ")");
    r.finish();
    G2L_CHECK(int(d.object_ids.size()) == dc.num_classes, "'", path, "': ", d.object_ids.size(),
              " object ids for ", dc.num_classes, " classes");
    d.net = std::make_unique<Detector>(dc);
    std::map<std::string, Tensor> sd;
    for (const auto& [name, t] : ck.tensors) {
        G2L_CHECK(name.rfind("model.", 0) == 0, "'", path, "': unexpected tensor '", name, "'");
        sd[name.substr(6)] = t;
    }
    d.net->load_state_dict(sd, true);
    d.net->eval();
    return d;
}

std::vector<Detection> detect(Detector& net, int downscale, const uint8_t* rgb, int width,
                              int height, float min_score, int max_per_class, bool mirror) {
    G2L_CHECK(rgb && width > 0 && height > 0, "detect: empty image (", width, " x ", height, ")");
    DetectorFrame f;
    f.rgb = rgb, f.width = width, f.height = height;
    return detect(net, downscale, f, min_score, max_per_class, mirror);
}

std::vector<Detection> detect(Detector& net, int downscale, const DetectorFrame& frame,
                              float min_score, int max_per_class, bool mirror) {
    const DetectorInput input = net.config().input;
    const int width = frame.width, height = frame.height;
    int iw = 0, ih = 0;
    const Tensor x = detector_input(frame, input, downscale, &iw, &ih);
    autograd::NoGradGuard ng;
    net.eval();
    const DetOut o = net.forward(x);
    Tensor prob = sigmoid(o.heat);
    if (mirror) {
        // The frame mirrored left-right; its map is mirrored back over the cells that cover
        // the image (cell x of the mirrored input is cell cols - 1 - x of the image when the
        // input width is a whole number of cells; else the odd column is the plain pass's).
        DetectorFrame mf = frame;
        std::vector<uint8_t> m;
        std::vector<float> md;
        if (frame.rgb) {
            m.resize(size_t(width) * size_t(height) * 3);
            for (int y = 0; y < height; ++y)
                for (int xx = 0; xx < width; ++xx)
                    for (int c = 0; c < 3; ++c)
                        m[(size_t(y) * width + xx) * 3 + c] =
                            frame.rgb[(size_t(y) * width + size_t(width - 1 - xx)) * 3 + c];
            mf.rgb = m.data();
        }
        if (frame.depth_mm) {
            md.resize(size_t(width) * size_t(height));
            for (int y = 0; y < height; ++y)
                for (int xx = 0; xx < width; ++xx)
                    md[size_t(y) * width + xx] = frame.depth_mm[size_t(y) * width + size_t(width - 1 - xx)];
            mf.depth_mm = md.data();
            mf.cx = (width - 1) - frame.cx;
        }
        int mw = 0, mh = 0;
        const Tensor pm = sigmoid(net.forward(detector_input(mf, input, downscale, &mw, &mh)).heat);
        const int64_t K = prob.size(1), hh = prob.size(2), ww = prob.size(3);
        const int64_t cols = std::min<int64_t>(ww, (width / downscale) / Detector::kStride);
        float* p = prob.data<float>();
        const float* q = pm.data<float>();
        for (int64_t k = 0; k < K; ++k)
            for (int64_t y = 0; y < hh; ++y)
                for (int64_t c = 0; c < cols; ++c) {
                    float& v = p[(k * hh + y) * ww + c];
                    v = 0.5f * (v + q[(k * hh + y) * ww + (cols - 1 - c)]);
                }
    }
    {  // cells whose centre lies in the zero padding (outside the image) cannot be peaks
        const int64_t K = prob.size(1), hh = prob.size(2), ww = prob.size(3);
        const double real_w = double(width / downscale), real_h = double(height / downscale);
        float* p = prob.data<float>();
        for (int64_t k = 0; k < K; ++k)
            for (int64_t y = 0; y < hh; ++y)
                for (int64_t x = 0; x < ww; ++x)
                    if ((double(x) + 0.5) * Detector::kStride >= real_w ||
                        (double(y) + 0.5) * Detector::kStride >= real_h)
                        p[(k * hh + y) * ww + x] = -1.f;
    }
    std::vector<Detection> dets = decode_detections(
        prob.data<float>(), o.size.data<float>(), o.offset.data<float>(), int(o.heat.size(1)),
        int(o.heat.size(3)), int(o.heat.size(2)), min_score, max_per_class + 8, Detector::kStride);
    // Input pixels -> image pixels; peaks in the zero padding (outside the image) are dropped
    // and the sub-cell offset may not carry a peak off the image.
    std::vector<Detection> out;
    std::map<int, int> per_class;
    for (Detection d : dets) {
        const float s = float(downscale);
        d.peak_x *= s, d.peak_y *= s, d.x *= s, d.y *= s, d.w *= s, d.h *= s;
        if (d.peak_x < -0.5f * Detector::kStride * s || d.peak_y < -0.5f * Detector::kStride * s ||
            d.peak_x >= float(width) + 0.5f * Detector::kStride * s ||
            d.peak_y >= float(height) + 0.5f * Detector::kStride * s)
            continue;
        d.peak_x = std::clamp(d.peak_x, 0.f, float(width) - 0.5f);
        d.peak_y = std::clamp(d.peak_y, 0.f, float(height) - 0.5f);
        if (per_class[d.cls]++ >= max_per_class) continue;
        out.push_back(d);
    }
    return out;
}

}  // namespace g2l::nn
