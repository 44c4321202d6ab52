// SPDX-License-Identifier: MIT
#include "nn/models/g2l_engine.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <string>

#include "core/error.h"
#include "geometry/kabsch.h"
#include "kernels/gemm.h"
#include "nn/modules/layers.h"

namespace g2l::nn {

namespace {

using Clock = std::chrono::steady_clock;
using MatD = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using VecD = Eigen::VectorXd;
using MatF = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

double ms_since(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// A folded affine layer: y = W x + b, then ReLU if `relu`. W is [cout, cin] row-major.
struct Affine {
    int64_t cout = 0, cin = 0;
    std::vector<float> w, b;
    kernels::PackedGemmA packed;  // a layer run_points runs: w in the GEMM's panels, w dropped
    bool relu = false;
};

Affine to_affine(const MatD& W, const VecD& b, bool relu) {
    Affine a;
    a.cout = W.rows();
    a.cin = W.cols();
    a.w.resize(size_t(W.size()));
    for (int64_t r = 0; r < W.rows(); ++r)
        for (int64_t c = 0; c < W.cols(); ++c) a.w[size_t(r * W.cols() + c)] = float(W(r, c));
    a.b.resize(size_t(b.size()));
    for (int64_t r = 0; r < b.size(); ++r) a.b[size_t(r)] = float(b[r]);
    a.relu = relu;
    return a;
}

// A layer that run_points runs: its weights go into the GEMM's panels once, and its rows (only
// run_vec and class_rows read rows) are dropped.
void pack_for_points(Affine* a) {
    a->packed = kernels::PackedGemmA(false, a->cout, a->cin, a->w.data(), a->cin);
    std::vector<float>().swap(a->w);
}

// The state dict of the net, read as double matrices / vectors.
struct Dict {
    std::map<std::string, Tensor> sd;
    const Tensor& at(const std::string& name) const {
        const auto it = sd.find(name);
        G2L_CHECK(it != sd.end(), "PoseEngine: the network has no tensor '", name, "'");
        return it->second;
    }
    bool has(const std::string& name) const { return sd.count(name) > 0; }
    MatD mat(const std::string& name) const {
        const Tensor& t = at(name);
        G2L_CHECK(t.dim() == 2, "PoseEngine: '", name, "' is ", t.desc(), ", expected 2-D");
        const std::vector<float> v = t.to(DType::F32).to_vector<float>();
        MatD m(t.size(0), t.size(1));
        for (int64_t r = 0; r < m.rows(); ++r)
            for (int64_t c = 0; c < m.cols(); ++c) m(r, c) = v[size_t(r * m.cols() + c)];
        return m;
    }
    VecD vec(const std::string& name) const {
        const Tensor& t = at(name);
        const std::vector<float> v = t.to(DType::F32).to_vector<float>();
        VecD out(int64_t(v.size()));
        for (size_t i = 0; i < v.size(); ++i) out[int64_t(i)] = v[i];
        return out;
    }
    // weight and bias of a conv / linear layer ("<prefix>.weight", "<prefix>.bias" or zeros).
    void layer(const std::string& prefix, MatD* W, VecD* b) const {
        *W = mat(prefix + ".weight");
        *b = has(prefix + ".bias") ? vec(prefix + ".bias") : VecD::Zero(W->rows());
    }
    // Folds the eval-mode BatchNorm `bn` into W, b: s = gamma / sqrt(var + eps),
    // W <- diag(s) W, b <- s (b - mean) + beta.
    void fold_bn(const std::string& bn, MatD* W, VecD* b) const {
        const VecD gamma = vec(bn + ".weight"), beta = vec(bn + ".bias");
        const VecD mean = vec(bn + ".running_mean"), var = vec(bn + ".running_var");
        G2L_CHECK(gamma.size() == W->rows(), "PoseEngine: '", bn, "' has ", gamma.size(),
                  " channels for a layer of ", W->rows());
        for (int64_t r = 0; r < W->rows(); ++r) {
            const double s = gamma[r] / std::sqrt(var[r] + 1e-5);
            W->row(r) *= s;
            (*b)[r] = s * ((*b)[r] - mean[r]) + beta[r];
        }
    }
    // conv/fc <prefix>.<layer>{i} with its BN <prefix>.bn{i}.
    Affine folded(const std::string& prefix, const std::string& layer, int i, bool relu) const {
        MatD W;
        VecD b;
        const std::string k = std::to_string(i);
        this->layer(prefix + "." + layer + k, &W, &b);
        fold_bn(prefix + ".bn" + k, &W, &b);
        return to_affine(W, b, relu);
    }
};

// PointNet backbone: conv1..4 (+BN, ReLU) and conv5 (+BN) kept in double for fusing into the
// heads that read pf.
struct Backbone {
    Affine l[5];
    MatD W5;
    VecD b5;
    int64_t c1 = 0, c2 = 0, c5 = 0;
};

Backbone load_backbone(const Dict& d, const std::string& prefix) {
    Backbone bb;
    for (int i = 1; i <= 4; ++i) bb.l[i - 1] = d.folded(prefix, "conv", i, true);
    d.layer(prefix + ".conv5", &bb.W5, &bb.b5);
    d.fold_bn(prefix + ".bn5", &bb.W5, &bb.b5);
    bb.l[4] = to_affine(bb.W5, bb.b5, false);
    bb.c1 = bb.l[1].cout;
    bb.c2 = bb.l[3].cout;
    bb.c5 = bb.l[4].cout;
    return bb;
}

// A head over [prefix (P channels), x1, x2, pf] per point and [g, onehot] per object. The
// first layer keeps [W_P | W_x1 | W_x2 + W_pf W5] for the points (`point`) and W_g, W_onehot
// for the per-object bias  b' + W_pf b5 + W_g g + W_onehot[:, class].
struct Head {
    Affine point;             // cin = P + c1 + c2
    std::vector<float> wg;    // [cout, c5]
    std::vector<float> wc;    // [cout, C] (column-major by class would be nicer; small anyway)
    int64_t c5 = 0, C = 0;
    std::vector<Affine> rest;
};

Head load_head(const Dict& d, const std::string& prefix, int64_t P, const Backbone& bb,
               int64_t num_classes, int layers, bool relu_last) {
    MatD W;
    VecD b;
    d.layer(prefix + ".conv1", &W, &b);
    d.fold_bn(prefix + ".bn1", &W, &b);
    const int64_t c1 = bb.c1, c2 = bb.c2, c5 = bb.c5;
    G2L_CHECK(W.cols() == P + c1 + c2 + c5 + c5 + num_classes, "PoseEngine: '", prefix,
              ".conv1' has ", W.cols(), " input channels, expected ", P + c1 + c2 + 2 * c5 + num_classes);
    const MatD Wpf = W.middleCols(P + c1 + c2, c5);
    MatD Wp(W.rows(), P + c1 + c2);
    Wp.leftCols(P + c1) = W.leftCols(P + c1);
    Wp.rightCols(c2) = W.middleCols(P + c1, c2) + Wpf * bb.W5;
    const VecD bias = b + Wpf * bb.b5;
    Head h;
    h.point = to_affine(Wp, bias, layers > 1 || relu_last);
    const MatD Wg = W.middleCols(P + c1 + c2 + c5, c5), Wc = W.rightCols(num_classes);
    h.wg.assign(size_t(Wg.size()), 0.f);
    for (int64_t r = 0; r < Wg.rows(); ++r)
        for (int64_t c = 0; c < c5; ++c) h.wg[size_t(r * c5 + c)] = float(Wg(r, c));
    h.wc.assign(size_t(Wc.size()), 0.f);
    for (int64_t r = 0; r < Wc.rows(); ++r)
        for (int64_t c = 0; c < num_classes; ++c) h.wc[size_t(r * num_classes + c)] = float(Wc(r, c));
    h.c5 = c5;
    h.C = num_classes;
    for (int i = 2; i <= layers; ++i)
        h.rest.push_back(d.folded(prefix, "conv", i, i < layers || relu_last));
    return h;
}

Affine load_plain(const Dict& d, const std::string& prefix, bool relu) {
    MatD W;
    VecD b;
    d.layer(prefix, &W, &b);
    return to_affine(W, b, relu);
}

void grow(std::vector<float>* v, size_t n) {
    if (v->size() < n) v->resize(n);
}

}  // namespace

struct PoseEngine::Impl {
    G2LConfig cfg;
    int64_t K3 = 0;  // 3K
    Backbone seg_bb, feat_bb;  // feat_bb: block A's backbone (or block B's own without A)
    Head seg_head, evf_head, rot_head, rre_head;
    Affine seg_out, evf_out, rot_out, rre_out;
    Affine t_mlp[3], t_fc[2], t_out;
    Affine rot_fc[3];
    bool evf = true, rre = true;

    // Buffers (grown on demand, never shrunk).
    std::vector<float> xin, a, feat, pf, h1, h2, small;
    std::vector<float> g, bias, vec_a, vec_b;
    std::vector<int64_t> start;  // segment starts (objects side by side), size n + 1
    struct Work {
        std::vector<int> all, obj, sub;
        Eigen::Vector3f mean = Eigen::Vector3f::Zero(), T = Eigen::Vector3f::Zero();
        float scale = 1.f, out_mul = 1.f;
        bool active = false;
    };
    std::vector<Work> work;
    std::vector<int> active;  // indices of the queries in the current stage
    std::vector<int> cls_buf, keep;

    // y [cout, N] = A x (ld N) + bias, ReLU. obj_bias: [segments, cout] replacing A.b.
    void run_points(const Affine& A, const float* x, int64_t N, float* y,
                    const float* obj_bias) const {
        kernels::GemmEpilogue ep;
        ep.relu = A.relu;
        ep.bias = obj_bias ? obj_bias : A.b.data();
        if (obj_bias) ep.segments = start.data(), ep.num_segments = int64_t(start.size()) - 1;
        kernels::gemm_packed_a_cpu(A.packed, N, x, N, y, N, &ep);
    }

    // out[s, c] = max over the points of segment s of x[c, :] (x: [C, N]).
    void max_points(const float* x, int64_t C, int64_t N, float* out) const {
        const int64_t S = int64_t(start.size()) - 1;
#pragma omp parallel for schedule(static) if (C * N > 32768)
        for (int64_t c = 0; c < C; ++c)
            for (int64_t s = 0; s < S; ++s) {
                // 16 running maxima (they vectorize; one chain would be a compare per cycle),
                // NaN skipped as by std::max(m, x) on one chain
                constexpr int L = 16;
                float lane[L];
                for (float& v : lane) v = -INFINITY;
                const float* row = x + c * N;
                int64_t n = start[size_t(s)];
                const int64_t end = start[size_t(s + 1)];
                for (; n + L <= end; n += L)
                    for (int l = 0; l < L; ++l) lane[l] = std::max(lane[l], row[n + l]);
                float m = -INFINITY;
                for (; n < end; ++n) m = std::max(m, row[n]);
                for (const float v : lane) m = std::max(m, v);
                out[s * C + c] = m;
            }
    }

    // y = A x (+ b, ReLU) for one vector.
    static void run_vec(const Affine& A, const float* x, float* y) {
        Eigen::Map<const MatF> W(A.w.data(), A.cout, A.cin);
        Eigen::Map<const Eigen::VectorXf> xv(x, A.cin);
        Eigen::Map<Eigen::VectorXf> yv(y, A.cout);
        yv.noalias() = W * xv;
        for (int64_t r = 0; r < A.cout; ++r) {
            const float v = yv[r] + A.b[size_t(r)];
            yv[r] = A.relu && v < 0.f ? 0.f : v;
        }
    }

    // Per-object first-layer biases of `h`: bias[s] = point.b + W_g g[s] + W_c[:, class(s)].
    void head_bias(const Head& h, const float* g_all, const std::vector<int>& cls) {
        const int64_t S = int64_t(cls.size()), cout = h.point.cout;
        grow(&bias, size_t(S * cout));
        Eigen::Map<const MatF> Wg(h.wg.data(), cout, h.c5);
        for (int64_t s = 0; s < S; ++s) {
            Eigen::Map<const Eigen::VectorXf> gv(g_all + s * h.c5, h.c5);
            Eigen::Map<Eigen::VectorXf> bv(bias.data() + s * cout, cout);
            bv.noalias() = Wg * gv;
            for (int64_t r = 0; r < cout; ++r)
                bv[r] += h.point.b[size_t(r)] + h.wc[size_t(r * h.C + cls[size_t(s)])];
        }
    }

    // Backbone over xin [3, N]: x1, x2 into feat rows [P, P + c1 + c2), g (per segment) into
    // this->g. pf goes through this->pf.
    void run_backbone(const Backbone& bb, int64_t N, int64_t P) {
        grow(&a, size_t(std::max(bb.l[0].cout, bb.l[2].cout) * N));
        grow(&pf, size_t(bb.c5 * N));
        float* x1 = feat.data() + P * N;
        float* x2 = x1 + bb.c1 * N;
        run_points(bb.l[0], xin.data(), N, a.data(), nullptr);
        run_points(bb.l[1], a.data(), N, x1, nullptr);
        run_points(bb.l[2], x1, N, a.data(), nullptr);
        run_points(bb.l[3], a.data(), N, x2, nullptr);
        run_points(bb.l[4], x2, N, pf.data(), nullptr);
        grow(&g, size_t((int64_t(start.size()) - 1) * bb.c5));
        max_points(pf.data(), bb.c5, N, g.data());
    }

    // y [3K] = the rows of `out` for class `cls` (all rows when out has 3K: shared heads) x + b.
    void class_rows(const Affine& out, int cls, const float* x, float* y) const {
        const int64_t r0 = out.cout != K3 ? int64_t(cls) * K3 : 0;
        Eigen::Map<const MatF> W(out.w.data() + r0 * out.cin, K3, out.cin);
        Eigen::Map<const Eigen::VectorXf> xv(x, out.cin);
        Eigen::Map<Eigen::VectorXf> yv(y, K3);
        yv.noalias() = W * xv;
        for (int64_t r = 0; r < K3; ++r) yv[r] += out.b[size_t(r0 + r)];
    }

    // A head followed by the max over each object's points: [S, *c] rows (in h1 or h2).
    const float* pooled_head(const Head& h, int64_t N, int64_t row0, const std::vector<int>& cls,
                             int64_t* c) {
        const float* y = run_head(h, N, row0, cls);
        *c = h.rest.empty() ? h.point.cout : h.rest.back().cout;
        std::vector<float>& pooled = h2.data() == y ? h1 : h2;
        grow(&pooled, size_t(int64_t(cls.size()) * *c));
        max_points(y, *c, N, pooled.data());
        return pooled.data();
    }

    // A head over feat rows [row0, ...) (cin of its first layer) -> its last layer in *out_buf.
    const float* run_head(const Head& h, int64_t N, int64_t row0, const std::vector<int>& cls) {
        head_bias(h, g.data(), cls);
        int64_t widest = h.point.cout;
        for (const auto& l : h.rest) widest = std::max(widest, l.cout);
        grow(&h1, size_t(widest * N));
        grow(&h2, size_t(widest * N));
        run_points(h.point, feat.data() + row0 * N, N, h1.data(), bias.data());
        float* cur = h1.data();
        float* nxt = h2.data();
        for (const auto& l : h.rest) {
            run_points(l, cur, N, nxt, nullptr);
            std::swap(cur, nxt);
        }
        return cur;
    }

    // The stages of PoseEngine::estimate (below it).
    template <class SizeOf>
    int64_t set_segments(const std::vector<PoseQuery>& qs, SizeOf size_of);
    const std::vector<int>& classes(const std::vector<PoseQuery>& qs);
    void segment(const std::vector<PoseQuery>& qs, int max_points, int crop_points,
                 std::vector<PoseEstimate>* out);
    void translate(const std::vector<PoseQuery>& qs);
    void rotate(const std::vector<PoseQuery>& qs, std::vector<PoseEstimate>* out);
    void keypoint_poses(const std::vector<PoseQuery>& qs, const float* kp, const float* resid,
                        std::vector<PoseEstimate>* out) const;
};

PoseEngine::PoseEngine(const G2LNet& net) : impl_(std::make_unique<Impl>()) {
    Impl& m = *impl_;
    m.cfg = net.config();
    const_cast<G2LNet&>(net).apply([](Module& mod) {
        if (auto* bn = dynamic_cast<BatchNorm*>(&mod))
            G2L_CHECK(bn->eps == 1e-5, "PoseEngine: a BatchNorm with eps ", bn->eps,
                      " (the engine folds eps 1e-5)");
    });
    Dict d;
    d.sd = net.state_dict();
    const int64_t C = m.cfg.num_classes, K = m.cfg.num_keypoints;
    m.K3 = 3 * K;
    m.evf = m.cfg.evf;
    m.rre = m.cfg.rre;
    m.seg_bb = load_backbone(d, "seg.backbone");
    m.seg_head = load_head(d, "seg.head", 0, m.seg_bb, C, 4, true);
    m.seg_out = load_plain(d, "seg.out", false);
    for (int i = 0; i < 3; ++i) m.t_mlp[i] = d.folded("tnet.mlp", "conv", i + 1, i < 2);
    for (int i = 0; i < 2; ++i) m.t_fc[i] = d.folded("tnet.fc", "fc", i + 1, i < 1);
    m.t_out = load_plain(d, "tnet.out", false);
    m.feat_bb = load_backbone(d, m.evf ? "evf.backbone" : "rot.backbone");
    if (m.evf) {
        m.evf_head = load_head(d, "evf.head", 0, m.feat_bb, C, 4, true);
        m.evf_out = load_plain(d, "evf.out", false);
    }
    m.rot_head = load_head(d, "rot.mlp", m.evf ? m.K3 : 0, m.feat_bb, C, 3, true);
    for (int i = 0; i < 3; ++i) m.rot_fc[i] = d.folded("rot.fc", "fc", i + 1, true);
    m.rot_out = load_plain(d, "rot.out", false);
    if (m.rre) {
        m.rre_head = load_head(d, "rre.mlp", 0, m.feat_bb, C, 2, false);
        m.rre_out = load_plain(d, "rre.out", false);
    }
    for (Backbone* bb : {&m.seg_bb, &m.feat_bb})
        for (Affine& l : bb->l) pack_for_points(&l);
    for (Head* h : {&m.seg_head, &m.evf_head, &m.rot_head, &m.rre_head}) {
        if (h->point.cout == 0) continue;  // a block the config leaves out (evf, rre)
        pack_for_points(&h->point);
        for (Affine& l : h->rest) pack_for_points(&l);
    }
    for (Affine* a : {&m.seg_out, &m.t_mlp[0], &m.t_mlp[1], &m.t_mlp[2]}) pack_for_points(a);
}

PoseEngine::~PoseEngine() = default;
PoseEngine::PoseEngine(PoseEngine&&) noexcept = default;
PoseEngine& PoseEngine::operator=(PoseEngine&&) noexcept = default;

const G2LConfig& PoseEngine::config() const { return impl_->cfg; }

PoseEstimate PoseEngine::estimate(const geom::Points& crop, int class_index,
                                  const std::vector<Eigen::Vector3f>& keypoints, int max_points,
                                  int crop_points) {
    std::vector<PoseEstimate> out;
    estimate({PoseQuery{&crop, class_index, &keypoints}}, max_points, crop_points, &out);
    return out[0];
}

// ---- PoseEngine::estimate's stages (G2L-Net §3.2-3.4), over the active queries side by side ----

// Segments of the active queries with sizes n(q); returns the total.
template <class SizeOf>
int64_t PoseEngine::Impl::set_segments(const std::vector<PoseQuery>&, SizeOf size_of) {
    start.assign(1, 0);
    for (int q : active) start.push_back(start.back() + size_of(q));
    return start.back();
}

const std::vector<int>& PoseEngine::Impl::classes(const std::vector<PoseQuery>& qs) {
    cls_buf.clear();
    for (int q : active) cls_buf.push_back(qs[size_t(q)].class_index);
    return cls_buf;
}

// 1. Segmentation of the crop, centred by the mean of the points it sees; given object
// points replace the seg net's decision; queries left with < 10 object points drop out.
void PoseEngine::Impl::segment(const std::vector<PoseQuery>& qs, int max_points, int crop_points,
                               std::vector<PoseEstimate>* out) {
    std::vector<int>& act = active;
    act.clear();
    for (size_t i = 0; i < qs.size(); ++i) {
        Work& w = work[i];
        const geom::Points& pts = *qs[i].crop;
        w.active = pts.rows() >= 10;
        if (!w.active) {
            (*out)[i].status = "too few crop points";
            continue;
        }
        if (crop_points > 0) {
            even_sample_into(int(pts.rows()), crop_points, &w.all);
        } else {
            w.all.resize(size_t(pts.rows()));
            for (size_t k = 0; k < w.all.size(); ++k) w.all[k] = int(k);
        }
        w.mean.setZero();
        for (int k : w.all) w.mean += pts.row(k).transpose();
        w.mean /= float(w.all.size());
        act.push_back(int(i));
    }
    if (!act.empty()) {
        const int64_t N = set_segments(qs, [&](int q) { return int64_t(work[size_t(q)].all.size()); });
        grow(&xin, size_t(3 * N));
        for (size_t s = 0; s < act.size(); ++s) {
            const Work& w = work[size_t(act[s])];
            const geom::Points& pts = *qs[size_t(act[s])].crop;
            for (size_t n = 0; n < w.all.size(); ++n)
                for (int c = 0; c < 3; ++c)
                    xin[size_t(c * N + start[s] + int64_t(n))] = pts(w.all[n], c) - w.mean[c];
        }
        grow(&feat, size_t((K3 + seg_bb.c1 + seg_bb.c2) * N));
        run_backbone(seg_bb, N, 0);
        const float* h = run_head(seg_head, N, 0, classes(qs));
        grow(&small, size_t(2 * N));
        run_points(seg_out, h, N, small.data(), nullptr);
        for (size_t s = 0; s < act.size(); ++s) {
            Work& w = work[size_t(act[s])];
            w.obj.clear();
            for (size_t n = 0; n < w.all.size(); ++n) {
                const int64_t col = start[s] + int64_t(n);
                if (small[size_t(N + col)] > small[size_t(col)]) w.obj.push_back(w.all[n]);
            }
        }
    }
    for (int q : act) {  // given object points replace the seg net's decision
        Work& w = work[size_t(q)];
        if (const std::vector<uint8_t>* mask = qs[size_t(q)].object_mask) {
            w.obj.clear();
            for (int k : w.all)
                if ((*mask)[size_t(k)]) w.obj.push_back(k);
        }
        if (qs[size_t(q)].object_rows) *qs[size_t(q)].object_rows = w.obj;
    }
    keep.clear();
    for (int q : act) {
        Work& w = work[size_t(q)];
        (*out)[size_t(q)].num_object_points = int(w.obj.size());
        if (w.obj.size() < 10) {
            (*out)[size_t(q)].status = "too few object points";
            continue;
        }
        if (max_points > 0) {
            even_sample_into(int(w.obj.size()), max_points, &w.sub);
            for (int& k : w.sub) k = w.obj[size_t(k)];
            std::swap(w.obj, w.sub);
        }
        keep.push_back(q);
    }
    act.swap(keep);
}

// 2. Translation = mean of the object points + the T-net's residual.
void PoseEngine::Impl::translate(const std::vector<PoseQuery>& qs) {
    const G2LConfig& cfg = this->cfg;
    std::vector<int>& act = active;
    if (!act.empty()) {
        const int64_t N = set_segments(qs, [&](int q) { return int64_t(work[size_t(q)].obj.size()); });
        grow(&xin, size_t(3 * N));
        for (size_t s = 0; s < act.size(); ++s) {
            Work& w = work[size_t(act[s])];
            const geom::Points& pts = *qs[size_t(act[s])].crop;
            w.mean.setZero();
            for (int k : w.obj) w.mean += pts.row(k).transpose();
            w.mean /= float(w.obj.size());
            for (size_t n = 0; n < w.obj.size(); ++n)
                for (int c = 0; c < 3; ++c)
                    xin[size_t(c * N + start[s] + int64_t(n))] = pts(w.obj[n], c) - w.mean[c];
        }
        grow(&h1, size_t(t_mlp[0].cout * N));
        grow(&h2, size_t(std::max(t_mlp[1].cout, t_mlp[2].cout) * N));
        grow(&a, size_t(t_mlp[2].cout * N));
        run_points(t_mlp[0], xin.data(), N, h1.data(), nullptr);
        run_points(t_mlp[1], h1.data(), N, h2.data(), nullptr);
        run_points(t_mlp[2], h2.data(), N, a.data(), nullptr);
        const int64_t c3 = t_mlp[2].cout;
        grow(&g, size_t(int64_t(act.size()) * c3));
        max_points(a.data(), c3, N, g.data());
        grow(&vec_a, size_t(c3 + cfg.num_classes + 1024));
        grow(&vec_b, size_t(1024));
        for (size_t s = 0; s < act.size(); ++s) {
            Work& w = work[size_t(act[s])];
            std::copy(g.data() + int64_t(s) * c3, g.data() + int64_t(s + 1) * c3, vec_a.data());
            std::fill(vec_a.data() + c3, vec_a.data() + c3 + cfg.num_classes, 0.f);
            vec_a[size_t(c3 + qs[size_t(act[s])].class_index)] = 1.f;
            run_vec(t_fc[0], vec_a.data(), vec_b.data());
            run_vec(t_fc[1], vec_b.data(), vec_a.data());
            float res[3];
            run_vec(t_out, vec_a.data(), res);
            const float o = float(cfg.out_scale_mm);
            w.T = w.mean + (o == 1.f ? Eigen::Vector3f(res[0], res[1], res[2])
                                     : Eigen::Vector3f(res[0] * o, res[1] * o, res[2] * o));
            if (const Eigen::Vector3f* given = qs[size_t(act[s])].translation) w.T = *given;
        }
    }
}

// 3. Rotation in the canonical frame (points - T), in units of the object's scale: block A's
// vectors, block B's keypoints, Kabsch, block C's residual, Kabsch again.
void PoseEngine::Impl::rotate(const std::vector<PoseQuery>& qs, std::vector<PoseEstimate>* out) {
    const G2LConfig& cfg = this->cfg;
    std::vector<int>& act = active;
    if (!act.empty()) {
        const int64_t N = set_segments(qs, [&](int q) { return int64_t(work[size_t(q)].obj.size()); });
        const bool unit = cfg.rot_unit != "mm";
        grow(&xin, size_t(3 * N));
        for (size_t s = 0; s < act.size(); ++s) {
            Work& w = work[size_t(act[s])];
            const geom::Points& pts = *qs[size_t(act[s])].crop;
            w.scale = unit ? float(rotation_scale(cfg.rot_unit, *qs[size_t(act[s])].keypoints)) : 1.f;
            w.out_mul = unit ? w.scale : float(cfg.out_scale_mm);
            for (size_t n = 0; n < w.obj.size(); ++n)
                for (int c = 0; c < 3; ++c) {
                    const float v = pts(w.obj[n], c) - w.T[c];
                    xin[size_t(c * N + start[s] + int64_t(n))] = unit ? v / w.scale : v;
                }
        }
        const int64_t P = evf ? K3 : 0;
        grow(&feat, size_t((P + feat_bb.c1 + feat_bb.c2) * N));
        run_backbone(feat_bb, N, P);
        const std::vector<int>& cls = classes(qs);
        if (evf) {
            // Block A: per-point vectors into feat rows [0, 3K) (each object its class's rows).
            const float* h = run_head(evf_head, N, P, cls);
            const bool per_class = evf_out.cout != K3;
            for (size_t s = 0; s < act.size(); ++s) {
                const int64_t r0 = per_class ? int64_t(cls[s]) * K3 : 0;
                const int64_t off = start[s], n = start[s + 1] - off;
                kernels::GemmEpilogue ep;
                ep.bias = evf_out.b.data() + r0;
                kernels::gemm_batched_cpu<float>(false, false, K3, n, evf_out.cin, 1.f,
                                                 evf_out.w.data() + r0 * evf_out.cin,
                                                 evf_out.cin, h + off, N, 0, 0.f,
                                                 feat.data() + off, N, 0, 1, &ep);
            }
        }
        // Block C first (it reads feat rows [P, ...) and this->g, which block B's head keeps).
        grow(&vec_a, size_t(std::max<int64_t>(1024, rot_head.rest.back().cout)));
        grow(&vec_b, size_t(1024));
        std::vector<float>& kp_out = small;  // [S, 3K] keypoints then [S, 3K] residuals
        grow(&kp_out, size_t(2 * int64_t(act.size()) * K3 + 2 * N));
        float* kp = kp_out.data();
        float* resid = kp + int64_t(act.size()) * K3;
        if (rre) {
            int64_t c = 0;
            const float* pooled = pooled_head(rre_head, N, P, cls, &c);
            for (size_t s = 0; s < act.size(); ++s)
                class_rows(rre_out, cls[s], pooled + int64_t(s) * c, resid + int64_t(s) * K3);
        }
        {
            int64_t c = 0;
            const float* pooled = pooled_head(rot_head, N, 0, cls, &c);
            for (size_t s = 0; s < act.size(); ++s) {
                run_vec(rot_fc[0], pooled + int64_t(s) * c, vec_a.data());
                run_vec(rot_fc[1], vec_a.data(), vec_b.data());
                run_vec(rot_fc[2], vec_b.data(), vec_a.data());
                class_rows(rot_out, cls[s], vec_a.data(), kp + int64_t(s) * K3);
            }
        }
        keypoint_poses(qs, kp, resid, out);
    }
}

// Kabsch on block B's keypoints (predicted in the canonical frame, scaled back to mm), then,
// with block C, on those keypoints corrected by its residual (as estimate_pose).
void PoseEngine::Impl::keypoint_poses(const std::vector<PoseQuery>& qs, const float* kp,
                                      const float* resid, std::vector<PoseEstimate>* out) const {
    const int K = cfg.num_keypoints;
    const std::vector<int>& act = active;
    for (size_t s = 0; s < act.size(); ++s) {
        const int q = act[s];
        const Work& w = work[size_t(q)];
        const auto& mk = *qs[size_t(q)].keypoints;
        auto kabsch = [&](auto&& q_of) {
            Eigen::Vector3d pm = Eigen::Vector3d::Zero(), qm = Eigen::Vector3d::Zero();
            for (int k = 0; k < K; ++k) {
                pm += mk[size_t(k)].cast<double>();
                qm += q_of(k);
            }
            pm /= K;
            qm /= K;
            Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
            for (int k = 0; k < K; ++k)
                H += (mk[size_t(k)].cast<double>() - pm) * (q_of(k) - qm).transpose();
            return geom::rotation_from_covariance(H);
        };
        const float* kq = kp + int64_t(s) * K3;
        Eigen::Matrix3d R = kabsch([&](int k) {
            return Eigen::Vector3d(double(kq[3 * k] * w.out_mul), double(kq[3 * k + 1] * w.out_mul),
                                   double(kq[3 * k + 2] * w.out_mul));
        });
        if (rre) {
            const float* rq = resid + int64_t(s) * K3;
            const Eigen::Matrix3d R1 = R;
            R = kabsch([&](int k) {
                const Eigen::Vector3d rp = R1 * mk[size_t(k)].cast<double>();
                return Eigen::Vector3d(double(float(rp[0]) + rq[3 * k] * w.out_mul),
                                       double(float(rp[1]) + rq[3 * k + 1] * w.out_mul),
                                       double(float(rp[2]) + rq[3 * k + 2] * w.out_mul));
            });
        }
        PoseEstimate& e = (*out)[size_t(q)];
        e.pose.R = R;
        e.pose.t = w.T.cast<double>();
        e.ok = true;
        e.status = "ok";
    }
}

void PoseEngine::estimate(const std::vector<PoseQuery>& qs, int max_points, int crop_points,
                          std::vector<PoseEstimate>* out) {
    Impl& m = *impl_;
    const G2LConfig& cfg = m.cfg;
    const int K = cfg.num_keypoints;
    for (size_t i = 0; i < qs.size(); ++i) {
        G2L_CHECK(qs[i].crop && qs[i].keypoints, "PoseEngine::estimate: query ", i,
                  " has a null crop or keypoints");
        G2L_CHECK(qs[i].class_index >= 0 && qs[i].class_index < cfg.num_classes,
                  "PoseEngine::estimate: class index ", qs[i].class_index, " outside [0, ",
                  cfg.num_classes, ")");
        G2L_CHECK(int(qs[i].keypoints->size()) == K, "PoseEngine::estimate: ",
                  qs[i].keypoints->size(), " model keypoints, the network predicts ", K);
        G2L_CHECK(!qs[i].object_mask ||
                      int64_t(qs[i].object_mask->size()) == int64_t(qs[i].crop->rows()),
                  "PoseEngine::estimate: query ", i, " has an object mask of ",
                  qs[i].object_mask ? qs[i].object_mask->size() : 0, " flags for ",
                  qs[i].crop->rows(), " crop points");
        G2L_CHECK(!qs[i].translation || qs[i].translation->allFinite(), "PoseEngine::estimate: query ",
                  i, " has a non-finite translation");
    }
    out->resize(qs.size());
    for (auto& e : *out) e = PoseEstimate{};
    for (const PoseQuery& q : qs)
        if (q.object_rows) q.object_rows->clear();
    if (m.work.size() < qs.size()) m.work.resize(qs.size());
    const double nq = double(std::max<size_t>(1, qs.size()));
    auto t0 = Clock::now();
    m.segment(qs, max_points, crop_points, out);
    const double ms_seg = ms_since(t0) / nq;
    t0 = Clock::now();
    m.translate(qs);
    const double ms_t = ms_since(t0) / nq;
    t0 = Clock::now();
    m.rotate(qs, out);
    const double ms_rot = ms_since(t0) / nq;
    for (auto& e : *out) {
        e.ms_seg = ms_seg;
        e.ms_t = e.num_object_points >= 10 || e.ok ? ms_t : 0;
        e.ms_rot = e.ok ? ms_rot : 0;
    }
}

}  // namespace g2l::nn
