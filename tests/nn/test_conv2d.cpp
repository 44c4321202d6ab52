// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <chrono>
#include <cmath>
#include <iostream>

#include "core/rng.h"
#include "core/threads.h"
#include "gradcheck.h"
#include "nn/ops/conv2d.h"
#include "opsa_helpers.h"

using namespace g2l;

namespace {

struct ConvCase {
    int64_t B, Cin, H, W, Cout, kh, kw, sh, sw, ph, pw, dh, dw, groups;
};

int64_t out_size(int64_t n, int64_t k, int64_t s, int64_t p, int64_t d) {
    return (n + 2 * p - d * (k - 1) - 1) / s + 1;
}

// Brute-force direct convolution in double, straight from the definition.
std::vector<double> ref_forward(const ConvCase& c, const std::vector<double>& x,
                                const std::vector<double>& w, const std::vector<double>& b) {
    const int64_t Ho = out_size(c.H, c.kh, c.sh, c.ph, c.dh);
    const int64_t Wo = out_size(c.W, c.kw, c.sw, c.pw, c.dw);
    const int64_t cig = c.Cin / c.groups, cog = c.Cout / c.groups;
    std::vector<double> y(size_t(c.B * c.Cout * Ho * Wo));
    for (int64_t n = 0; n < c.B; ++n)
        for (int64_t co = 0; co < c.Cout; ++co)
            for (int64_t oh = 0; oh < Ho; ++oh)
                for (int64_t ow = 0; ow < Wo; ++ow) {
                    double s = b.empty() ? 0.0 : b[size_t(co)];
                    for (int64_t ci = 0; ci < cig; ++ci)
                        for (int64_t i = 0; i < c.kh; ++i)
                            for (int64_t j = 0; j < c.kw; ++j) {
                                const int64_t ih = oh * c.sh - c.ph + i * c.dh;
                                const int64_t iw = ow * c.sw - c.pw + j * c.dw;
                                if (ih < 0 || ih >= c.H || iw < 0 || iw >= c.W) continue;
                                const int64_t cx = (co / cog) * cig + ci;
                                s += w[size_t(((co * cig + ci) * c.kh + i) * c.kw + j)] *
                                     x[size_t(((n * c.Cin + cx) * c.H + ih) * c.W + iw)];
                            }
                    y[size_t(((n * c.Cout + co) * Ho + oh) * Wo + ow)] = s;
                }
    return y;
}

// Brute-force gradients (scatter form of the same loops) for upstream gradient dy.
void ref_backward(const ConvCase& c, const std::vector<double>& x, const std::vector<double>& w,
                  const std::vector<double>& dy, std::vector<double>& dx,
                  std::vector<double>& dw, std::vector<double>& db) {
    const int64_t Ho = out_size(c.H, c.kh, c.sh, c.ph, c.dh);
    const int64_t Wo = out_size(c.W, c.kw, c.sw, c.pw, c.dw);
    const int64_t cig = c.Cin / c.groups, cog = c.Cout / c.groups;
    dx.assign(x.size(), 0.0);
    dw.assign(w.size(), 0.0);
    db.assign(size_t(c.Cout), 0.0);
    for (int64_t n = 0; n < c.B; ++n)
        for (int64_t co = 0; co < c.Cout; ++co)
            for (int64_t oh = 0; oh < Ho; ++oh)
                for (int64_t ow = 0; ow < Wo; ++ow) {
                    const double d = dy[size_t(((n * c.Cout + co) * Ho + oh) * Wo + ow)];
                    db[size_t(co)] += d;
                    for (int64_t ci = 0; ci < cig; ++ci)
                        for (int64_t i = 0; i < c.kh; ++i)
                            for (int64_t j = 0; j < c.kw; ++j) {
                                const int64_t ih = oh * c.sh - c.ph + i * c.dh;
                                const int64_t iw = ow * c.sw - c.pw + j * c.dw;
                                if (ih < 0 || ih >= c.H || iw < 0 || iw >= c.W) continue;
                                const size_t xi = size_t(
                                    ((n * c.Cin + (co / cog) * cig + ci) * c.H + ih) * c.W + iw);
                                const size_t wi = size_t(((co * cig + ci) * c.kh + i) * c.kw + j);
                                dw[wi] += d * x[xi];
                                dx[xi] += d * w[wi];
                            }
                }
}

struct Inputs {
    Tensor x, w, b;
};

Inputs make_inputs(const ConvCase& c, uint64_t seed, DType dt, bool bias = true) {
    Rng rng(seed);
    Inputs in;
    in.x = Tensor::randn({c.B, c.Cin, c.H, c.W}, rng, dt);
    in.w = Tensor::randn({c.Cout, c.Cin / c.groups, c.kh, c.kw}, rng, dt);
    if (bias) in.b = Tensor::randn({c.Cout}, rng, dt);
    return in;
}

Tensor run(const ConvCase& c, const Inputs& in) {
    return nn::conv2d(in.x, in.w, in.b, {c.sh, c.sw}, {c.ph, c.pw}, {c.dh, c.dw}, c.groups);
}

std::vector<double> as_f64(const Tensor& t) { return t.to(DType::F64).to_vector<double>(); }

double max_rel_err(const std::vector<double>& got, const std::vector<double>& ref) {
    REQUIRE(got.size() == ref.size());
    double scale = 1e-30, err = 0;
    for (size_t i = 0; i < ref.size(); ++i) scale = std::max(scale, std::fabs(ref[i]));
    for (size_t i = 0; i < ref.size(); ++i) err = std::max(err, std::fabs(got[i] - ref[i]));
    return err / scale;
}

// Awkward sizes: odd spatial sizes, asymmetric kernels / strides / padding, dilation, groups
// (incl. depthwise), the direct 1x1 path, and sizes that span several forward tiles and dw
// row/column tiles (Cin 64 x 3x3 -> K = 576 > 256; Cout 40 > 32), a small image.
const std::vector<ConvCase> kCases = {
    {1, 1, 5, 5, 1, 3, 3, 1, 1, 0, 0, 1, 1, 1},    {2, 3, 7, 9, 4, 3, 3, 1, 1, 1, 1, 1, 1, 1},
    {2, 4, 9, 8, 6, 3, 2, 2, 1, 1, 0, 1, 2, 2},    {1, 6, 11, 7, 6, 3, 3, 2, 2, 1, 1, 2, 2, 6},
    {3, 5, 6, 5, 7, 1, 1, 1, 1, 0, 0, 1, 1, 1},    {2, 4, 7, 7, 8, 1, 1, 2, 2, 0, 0, 1, 1, 2},
    {1, 3, 13, 10, 5, 5, 4, 3, 2, 2, 1, 1, 1, 1},  {2, 8, 6, 6, 4, 2, 2, 1, 1, 1, 1, 3, 1, 4},
    {2, 64, 20, 19, 40, 3, 3, 1, 1, 1, 1, 1, 1, 1}, {1, 2, 3, 3, 2, 5, 5, 1, 1, 1, 1, 1, 1, 1},
    // A small image (a detector's deep layer: 300 columns, one forward tile).
    {1, 32, 15, 20, 24, 3, 3, 1, 1, 1, 1, 1, 1, 1},
};

}  // namespace

TEST_CASE("conv2d: forward matches a brute-force direct convolution", "[nn][opsb]") {
    for (const DType dt : {DType::F64, DType::F32}) {
        for (size_t k = 0; k < kCases.size(); ++k) {
            const ConvCase& c = kCases[k];
            for (const bool bias : {true, false}) {
                INFO("case " << k << " dtype " << dtype_name(dt) << " bias " << bias);
                const Inputs in = make_inputs(c, 100 + k, dt, bias);
                const Tensor y = run(c, in);
                REQUIRE(y.shape() == Shape{c.B, c.Cout, out_size(c.H, c.kh, c.sh, c.ph, c.dh),
                                           out_size(c.W, c.kw, c.sw, c.pw, c.dw)});
                const auto ref = ref_forward(c, as_f64(in.x), as_f64(in.w),
                                             bias ? as_f64(in.b) : std::vector<double>());
                CHECK(max_rel_err(as_f64(y), ref) < (dt == DType::F64 ? 1e-13 : 2e-6));
            }
        }
    }
}

TEST_CASE("conv2d: a hand-computed 3x3 example with padding and stride", "[nn][opsb]") {
    // x = 1..9 on a 3x3 plane, w = all ones 3x3, pad 1, stride 2: each output sums the in-image
    // part of a 3x3 window centred on the corners, plus bias 0.5.
    std::vector<float> xv(9);
    for (int i = 0; i < 9; ++i) xv[size_t(i)] = float(i + 1);
    const Tensor x = Tensor::from_vector(xv, {1, 1, 3, 3});
    const Tensor w = Tensor::ones({1, 1, 3, 3});
    const Tensor b = Tensor::from_vector<float>({0.5f}, {1});
    const auto y = nn::conv2d(x, w, b, {2, 2}, {1, 1}).to_vector<float>();
    REQUIRE(y == std::vector<float>{12.5f, 16.5f, 24.5f, 28.5f});
}

TEST_CASE("conv2d: gradients match brute-force references (multi-tile sizes)", "[nn][opsb]") {
    // Case 8 spans several dw tiles; the last case has P = 4096 columns, more than one backward
    // slab in f64 (16 MiB / (576 * 8 B) = 3640 columns).
    std::vector<ConvCase> cases = kCases;
    cases.push_back({1, 64, 64, 64, 3, 3, 3, 1, 1, 1, 1, 1, 1, 1});
    for (size_t k = 0; k < cases.size(); ++k) {
        const ConvCase& c = cases[k];
        INFO("case " << k);
        Inputs in = make_inputs(c, 200 + k, DType::F64);
        in.x.set_requires_grad();
        in.w.set_requires_grad();
        in.b.set_requires_grad();
        const Tensor y = run(c, in);
        Rng rng(300 + k);
        const Tensor dy = Tensor::randn(y.shape(), rng, DType::F64);
        y.backward(dy);
        std::vector<double> dx, dw, db;
        ref_backward(c, as_f64(in.x), as_f64(in.w), as_f64(dy), dx, dw, db);
        CHECK(max_rel_err(as_f64(in.x.grad()), dx) < 1e-13);
        CHECK(max_rel_err(as_f64(in.w.grad()), dw) < 1e-13);
        CHECK(max_rel_err(as_f64(in.b.grad()), db) < 1e-13);
    }
}

TEST_CASE("conv2d: analytic grads of x, w, b match finite differences", "[nn][grad][opsb]") {
    const std::vector<ConvCase> cases = {
        {2, 4, 5, 6, 6, 3, 2, 2, 1, 1, 1, 1, 2, 2},  // groups, stride, dilation, asymmetric
        {1, 3, 4, 5, 2, 1, 1, 1, 1, 0, 0, 1, 1, 1},  // direct 1x1 path
        {1, 2, 5, 5, 3, 3, 3, 2, 2, 1, 1, 1, 1, 1},  // strided 3x3 with padding
    };
    for (size_t k = 0; k < cases.size(); ++k) {
        const ConvCase& c = cases[k];
        INFO("case " << k);
        Inputs in = make_inputs(c, 400 + k, DType::F64);
        in.x.set_requires_grad();
        in.w.set_requires_grad();
        in.b.set_requires_grad();
        testing::gradcheck(
            [c](const std::vector<Tensor>& t) {
                return nn::conv2d(t[0], t[1], t[2], {c.sh, c.sw}, {c.ph, c.pw}, {c.dh, c.dw},
                                  c.groups);
            },
            {in.x, in.w, in.b});
    }
}

TEST_CASE("conv2d: only the requested gradients are computed", "[nn][opsb]") {
    const ConvCase c{1, 2, 5, 5, 3, 3, 3, 1, 1, 1, 1, 1, 1, 1};
    Inputs in = make_inputs(c, 7, DType::F64);
    in.w.set_requires_grad();  // frozen input and bias: only dw
    run(c, in).backward(Tensor::ones({1, 3, 5, 5}, DType::F64));
    REQUIRE(in.w.grad().defined());
    REQUIRE_FALSE(in.x.grad().defined());
    REQUIRE_FALSE(in.b.grad().defined());
    std::vector<double> dx, dw, db;
    ref_backward(c, as_f64(in.x), as_f64(in.w), std::vector<double>(75, 1.0), dx, dw, db);
    CHECK(max_rel_err(as_f64(in.w.grad()), dw) < 1e-13);
}

TEST_CASE("conv2d: results are bitwise identical with 1 and 2 threads", "[nn][opsb]") {
    for (const ConvCase& c : {ConvCase{2, 64, 33, 31, 48, 3, 3, 1, 1, 1, 1, 1, 1, 1},
                              ConvCase{2, 32, 30, 30, 40, 1, 1, 1, 1, 0, 0, 1, 1, 1},
                              ConvCase{1, 16, 25, 27, 16, 3, 3, 2, 2, 1, 1, 1, 1, 4},
                              ConvCase{1, 64, 15, 20, 64, 3, 3, 1, 1, 1, 1, 1, 1, 1}}) {
        std::vector<Tensor> runs[2];
        for (int threads = 1; threads <= 2; ++threads) {
            testing::opsa::with_threads(threads, [&] {
                Inputs in = make_inputs(c, 11, DType::F32);
                in.x.set_requires_grad();
                in.w.set_requires_grad();
                in.b.set_requires_grad();
                const Tensor y = run(c, in);
                Rng rng(12);
                y.backward(Tensor::randn(y.shape(), rng));
                runs[threads - 1] = {y, in.x.grad(), in.w.grad(), in.b.grad()};
            });
        }
        for (size_t k = 0; k < 4; ++k) CHECK(testing::opsa::bitwise_equal(runs[0][k], runs[1][k]));
    }
}

TEST_CASE("conv2d: bad shapes and arguments throw naming the shapes", "[nn][errors][opsb]") {
    const Tensor x = Tensor::zeros({1, 4, 5, 5});
    const Tensor w = Tensor::zeros({2, 4, 3, 3});
    // Channel mismatch.
    REQUIRE_THROWS_WITH(nn::conv2d(x, Tensor::zeros({2, 3, 3, 3})),
                        Catch::Contains("channel mismatch") && Catch::Contains("[1, 4, 5, 5]") &&
                            Catch::Contains("[2, 3, 3, 3]"));
    REQUIRE_THROWS_WITH(nn::conv2d(x, w, Tensor(), {1, 1}, {0, 0}, {1, 1}, 2),
                        Catch::Contains("channel mismatch"));
    REQUIRE_THROWS_WITH(nn::conv2d(x, Tensor::zeros({3, 2, 3, 3}), Tensor(), {1, 1}, {0, 0},
                                   {1, 1}, 2),
                        Catch::Contains("groups = 2") && Catch::Contains("Cout = 3"));
    // Kernel larger than the padded input (also through dilation).
    REQUIRE_THROWS_WITH(nn::conv2d(x, Tensor::zeros({2, 4, 7, 3})),
                        Catch::Contains("larger than the padded input 5x5") &&
                            Catch::Contains("7x3"));
    REQUIRE_NOTHROW(nn::conv2d(x, Tensor::zeros({2, 4, 7, 3}), Tensor(), {1, 1}, {1, 0}));
    REQUIRE_THROWS_WITH(nn::conv2d(x, w, Tensor(), {1, 1}, {0, 0}, {3, 1}),
                        Catch::Contains("extent 7x3"));
    // Bad stride, dilation, padding, groups.
    REQUIRE_THROWS_WITH(nn::conv2d(x, w, Tensor(), {0, 1}),
                        Catch::Contains("stride must be >= 1, got (0, 1)"));
    REQUIRE_THROWS_WITH(nn::conv2d(x, w, Tensor(), {1, 1}, {0, 0}, {1, 0}),
                        Catch::Contains("dilation must be >= 1"));
    REQUIRE_THROWS_WITH(nn::conv2d(x, w, Tensor(), {1, 1}, {-1, 0}),
                        Catch::Contains("padding must be >= 0, got (-1, 0)"));
    REQUIRE_THROWS_WITH(nn::conv2d(x, w, Tensor(), {1, 1}, {0, 0}, {1, 1}, 0),
                        Catch::Contains("groups must be >= 1"));
    // Wrong ranks, bias shape, dtypes.
    REQUIRE_THROWS_WITH(nn::conv2d(Tensor::zeros({4, 5, 5}), w),
                        Catch::Contains("[B, Cin, H, W]") && Catch::Contains("[4, 5, 5]"));
    REQUIRE_THROWS_WITH(nn::conv2d(x, Tensor::zeros({2, 4, 3})),
                        Catch::Contains("[Cout, Cin/groups, kh, kw]"));
    REQUIRE_THROWS_WITH(nn::conv2d(x, w, Tensor::zeros({3})),
                        Catch::Contains("bias must be [Cout] = [2]") && Catch::Contains("[3]"));
    REQUIRE_THROWS_WITH(nn::conv2d(x, Tensor::zeros({2, 4, 3, 3}, DType::F64)),
                        Catch::Contains("f32[1, 4, 5, 5]") && Catch::Contains("f64[2, 4, 3, 3]"));
    REQUIRE_THROWS_WITH(nn::conv2d(Tensor::zeros({1, 4, 5, 5}, DType::I32),
                                   Tensor::zeros({2, 4, 3, 3}, DType::I32)),
                        Catch::Contains("conv2d") && Catch::Contains("i32"));
    REQUIRE_THROWS_WITH(nn::conv2d(Tensor::zeros({0, 4, 5, 5}), w), Catch::Contains("empty"));
    REQUIRE_THROWS_WITH(nn::conv2d(Tensor(), w), Catch::Contains("x is undefined"));
}

TEST_CASE("conv2d: forward throughput on [1,64,104,104] x [128,64,3,3]", "[.bench]") {
    Rng rng(5);
    const Tensor x = Tensor::randn({1, 64, 104, 104}, rng);
    const Tensor w = Tensor::randn({128, 64, 3, 3}, rng);
    const Tensor b = Tensor::randn({128}, rng);
    const double flop = 2.0 * 128 * 64 * 9 * 104 * 104;
    nn::conv2d(x, w, b, {1, 1}, {1, 1});  // warm-up
    const int iters = 20;
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < iters; ++i) nn::conv2d(x, w, b, {1, 1}, {1, 1});
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "conv2d fwd [1,64,104,104]x[128,64,3,3] pad 1, " << num_threads()
              << " threads: " << 1e3 * s / iters << " ms/iter, " << flop * iters / s * 1e-9
              << " GFLOP/s\n";
    Tensor xg = x.clone(), wg = w.clone();
    xg.set_requires_grad();
    wg.set_requires_grad();
    const Tensor dy = Tensor::randn({1, 128, 104, 104}, rng);
    const auto t1 = std::chrono::steady_clock::now();
    for (int i = 0; i < 5; ++i) {
        xg.zero_grad();
        wg.zero_grad();
        nn::conv2d(xg, wg, b, {1, 1}, {1, 1}).backward(dy);
    }
    const double s1 = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
    std::cout << "conv2d fwd+bwd (dx, dw): " << 1e3 * s1 / 5 << " ms/iter, "
              << 3 * flop * 5 / s1 * 1e-9 << " GFLOP/s\n";
    CHECK(s > 0);
}
