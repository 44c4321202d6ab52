// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <cmath>
#include <map>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/checkpoint.h"
#include "core/rng.h"
#include "nn/optim.h"
#include "nn/schedule.h"
#include "testing.h"

using namespace g2l;
using Catch::Contains;

namespace {

Tensor param(const std::vector<double>& v, DType dt = DType::F64) {
    Tensor t = Tensor::from_vector<double>(v, {int64_t(v.size())}).to(dt);
    t.set_requires_grad();
    return t;
}

void set_grad(Tensor& p, const std::vector<double>& g) {
    p.set_grad(Tensor::from_vector<double>(g, {int64_t(g.size())}).to(p.dtype()));
}

std::vector<double> values(const Tensor& t) { return t.to(DType::F64).to_vector<double>(); }

nn::ParamGroup group(const std::string& name, std::vector<std::pair<std::string, Tensor>> ps,
                     double lr_mult = 1.0, double wd = 0.0) {
    nn::ParamGroup g;
    g.name = name;
    g.params = std::move(ps);
    g.lr_mult = lr_mult;
    g.weight_decay = wd;
    return g;
}

}  // namespace

// Two Adam steps on p0 = [1, -2, 0.5], lr 0.1, betas (0.9, 0.999), eps 1e-8, by hand:
// step 1, g = [0.5, -1, 2]: m = 0.1 g = [0.05, -0.1, 0.2], v = 0.001 g^2 = [2.5e-4, 1e-3, 4e-3];
//   bc1 = 0.1, bc2 = 0.001 -> m_hat = g, v_hat = g^2, p -= 0.1 * g / (|g| + 1e-8):
//   p1 = [1 - 0.1*0.5/0.50000001, -2 + 0.1/1.00000001, 0.5 - 0.2/2.00000001]
//      = [0.900000002, -1.900000001, 0.4000000005]
// step 2, g = [1, 1, -1]: m = 0.9 m + 0.1 g = [0.145, 0.01, 0.08],
//   v = 0.999 v + 0.001 g^2 = [0.00124975, 0.001999, 0.004996]; bc1 = 0.19, bc2 = 0.001999
//   m_hat = [0.763157894736842, 0.0526315789473684, 0.421052631578947]
//   v_hat = [0.625187593796907, 1.0, 2.49924962481244], sqrt = [0.790687..., 1, 1.580901...]
//   p2 = p1 - 0.1 m_hat / (sqrt(v_hat) + 1e-8)
//      = [0.803481800638509, -1.90526315884211, 0.373366296702432]
TEST_CASE("adam: two steps match the hand-computed values (f64 and f32)", "[optim]") {
    for (DType dt : {DType::F64, DType::F32}) {
        Tensor p = param({1.0, -2.0, 0.5}, dt);
        nn::AdamOptions o;
        o.lr = 0.1;
        nn::Adam adam({group("all", {{"p", p}})}, o);
        const double tol = dt == DType::F64 ? 1e-12 : 2e-6;
        set_grad(p, {0.5, -1.0, 2.0});
        const uint64_t v0 = p.version();
        adam.step();
        REQUIRE(p.version() > v0);
        REQUIRE(p.is_leaf());
        REQUIRE(p.requires_grad());
        auto p1 = values(p);
        CHECK(p1[0] == Approx(0.900000002).margin(tol).epsilon(0));
        CHECK(p1[1] == Approx(-1.900000001).margin(tol).epsilon(0));
        CHECK(p1[2] == Approx(0.4000000005).margin(tol).epsilon(0));
        set_grad(p, {1.0, 1.0, -1.0});
        adam.step();
        auto p2 = values(p);
        CHECK(p2[0] == Approx(0.803481800638509).margin(tol).epsilon(0));
        CHECK(p2[1] == Approx(-1.90526315884211).margin(tol).epsilon(0));
        CHECK(p2[2] == Approx(0.373366296702432).margin(tol).epsilon(0));
        CHECK(adam.step_count() == 2);
        // the moments are exposed through state_tensors()
        std::map<std::string, Tensor> st;
        for (auto& kv : adam.state_tensors()) st.emplace(kv.first, kv.second);
        auto m = values(st.at("adam.m.p")), v = values(st.at("adam.v.p"));
        CHECK(m[0] == Approx(0.145).margin(tol).epsilon(0));
        CHECK(m[2] == Approx(0.08).margin(tol).epsilon(0));
        CHECK(v[1] == Approx(0.001999).margin(tol * 1e-2).epsilon(0));
        CHECK(st.at("adam.step.p").item<int32_t>() == 2);
    }
}

// p = 10, g = -0.5, lr 0.1, wd 0.1, first step (update = lr * sign of the effective gradient):
//   Adam (L2):  g' = -0.5 + 0.1*10 = 0.5 > 0       -> p = 10 - 0.1          = 9.9
//   AdamW:      p = 10 * (1 - 0.1*0.1) = 9.9, g < 0 -> p = 9.9 + 0.1         = 10.0
//   no decay:                                          p = 10 + 0.1          = 10.1
TEST_CASE("adam: L2 weight decay and decoupled (AdamW) weight decay", "[optim]") {
    auto one_step = [](bool decoupled, double wd) {
        Tensor p = param({10.0});
        nn::AdamOptions o;
        o.lr = 0.1;
        o.decoupled = decoupled;
        nn::Adam adam({group("g", {{"w", p}}, 1.0, wd)}, o);
        set_grad(p, {-0.5});
        adam.step();
        return values(p)[0];
    };
    CHECK(one_step(false, 0.1) == Approx(9.9).epsilon(0).margin(1e-8).epsilon(0));
    CHECK(one_step(true, 0.1) == Approx(10.0).epsilon(0).margin(1e-8));
    CHECK(one_step(false, 0.0) == Approx(10.1).epsilon(0).margin(1e-8));
    CHECK(one_step(true, 0.0) == Approx(10.1).epsilon(0).margin(1e-8));

    // Second AdamW step by hand (g = -0.5 again): p = 10.0 * 0.99 = 9.9; m = -0.095, v =
    // 0.0004995, bc1 = 0.19, bc2 = 0.001999 -> m_hat = -0.5, v_hat = 0.25 -> p = 9.9 + 0.1.
    Tensor p = param({10.0});
    nn::AdamOptions o;
    o.lr = 0.1;
    o.decoupled = true;
    nn::Adam adam({group("g", {{"w", p}}, 1.0, 0.1)}, o);
    for (int i = 0; i < 2; ++i) {
        set_grad(p, {-0.5});
        adam.step();
    }
    CHECK(values(p)[0] == Approx(10.0).epsilon(0).margin(1e-7));
}

TEST_CASE("adam: per-group lr multipliers and set_lr", "[optim]") {
    // A constant gradient makes m_hat = g and v_hat = g^2, so every step moves by
    // lr * lr_mult * g / (|g| + eps) ~= lr * lr_mult.
    Tensor a = param({1.0, 2.0}), b = param({1.0, 2.0});
    nn::AdamOptions o;
    o.lr = 0.01;
    nn::Adam adam({group("x1", {{"a", a}}), group("x10", {{"b", b}}, 10.0)}, o);
    set_grad(a, {3.0, -3.0});
    set_grad(b, {3.0, -3.0});
    adam.step();
    CHECK(values(a)[0] == Approx(0.99).epsilon(0).margin(1e-8));
    CHECK(values(a)[1] == Approx(2.01).epsilon(0).margin(1e-8));
    CHECK(values(b)[0] == Approx(0.9).epsilon(0).margin(1e-8));
    CHECK(values(b)[1] == Approx(2.1).epsilon(0).margin(1e-8));
    adam.set_lr(0.001);
    CHECK(adam.lr() == 0.001);
    adam.step();  // gradients are still set: same direction, new base lr
    CHECK(values(a)[0] == Approx(0.989).epsilon(0).margin(1e-8));
    CHECK(values(b)[0] == Approx(0.89).epsilon(0).margin(1e-8));
    REQUIRE_THROWS_WITH(adam.set_lr(-1.0), Contains("-1"));
    REQUIRE_THROWS_WITH(adam.set_lr(NAN), Contains("nan"));
}

TEST_CASE("adam: parameters without a gradient are skipped and keep their own step", "[optim]") {
    Tensor a = param({1.0}), b = param({5.0, 6.0});
    nn::AdamOptions o;
    o.lr = 0.1;
    nn::Adam adam({group("g", {{"a", a}, {"b", b}})}, o);
    set_grad(a, {1.0});
    const uint64_t vb = b.version();
    adam.step();
    CHECK(values(b) == std::vector<double>{5.0, 6.0});  // bitwise untouched
    CHECK(b.version() == vb);
    adam.zero_grad();
    CHECK_FALSE(a.grad().defined());
    // b's first real step: its own t = 1, so the bias-corrected update is lr * sign(g) = 0.1
    // (with the global t = 2 it would be 0.1 * 0.526 / 0.707 = 0.0744).
    set_grad(b, {2.0, -2.0});
    adam.step();
    CHECK(values(b)[0] == Approx(4.9).epsilon(0).margin(1e-8));
    CHECK(values(b)[1] == Approx(6.1).epsilon(0).margin(1e-8));
    CHECK(values(a)[0] == Approx(0.9).epsilon(0).margin(1e-8));  // a skipped this time
    std::map<std::string, Tensor> st;
    for (auto& kv : adam.state_tensors()) st.emplace(kv.first, kv.second);
    CHECK(st.at("adam.step.a").item<int32_t>() == 1);
    CHECK(st.at("adam.step.b").item<int32_t>() == 1);
    CHECK(adam.step_count() == 2);
}

TEST_CASE("adam: state saved (through a checkpoint file) and loaded continues identically",
          "[optim]") {
    Rng rng(11);
    const Tensor w0 = Tensor::randn({4, 3}, rng), b0 = Tensor::randn({3}, rng);
    std::vector<Tensor> grads;
    for (int i = 0; i < 6; ++i) grads.push_back(Tensor::randn({4, 3}, rng));
    auto make = [](Tensor& w, Tensor& b) {
        nn::AdamOptions o;
        o.lr = 0.05;
        o.beta2 = 0.99;
        return nn::Adam({group("w", {{"w", w}}, 2.0, 0.01), group("b", {{"b", b}})}, o);
    };
    auto do_step = [&](nn::Adam& adam, Tensor& w, Tensor& b, int i) {
        w.set_grad(grads[size_t(i)].clone());
        // b has a gradient only on even steps: exercises the per-parameter step counts
        if (i % 2 == 0) b.set_grad(Tensor::full({3}, 0.1 * (i + 1)));
        else b.zero_grad();
        adam.step();
    };
    Tensor w = w0.clone().set_requires_grad(), b = b0.clone().set_requires_grad();
    nn::Adam adam = make(w, b);
    for (int i = 0; i < 3; ++i) do_step(adam, w, b, i);

    const std::string dir = testing::temp_dir("optim");
    auto saved = adam.state_tensors();
    saved.emplace_back("model.w", w);
    saved.emplace_back("model.b", b);
    save_checkpoint(dir + "/s.g2l", saved, "{\"step\": 3}");
    const Checkpoint ck = load_checkpoint(dir + "/s.g2l");

    Tensor w2 = ck.tensors.at("model.w").clone().set_requires_grad();
    Tensor b2 = ck.tensors.at("model.b").clone().set_requires_grad();
    nn::Adam adam2 = make(w2, b2);
    adam2.load_state(ck.tensors, 3);
    CHECK(adam2.step_count() == 3);
    for (int i = 3; i < 6; ++i) {
        do_step(adam, w, b, i);
        do_step(adam2, w2, b2, i);
    }
    CHECK(w.to_vector<float>() == w2.to_vector<float>());
    CHECK(b.to_vector<float>() == b2.to_vector<float>());
    CHECK(adam2.step_count() == 6);
}

TEST_CASE("adam: load_state lists every missing, mismatched and unknown name", "[optim]") {
    Tensor a = param({1.0, 2.0}), b = param({3.0});
    nn::Adam adam({group("g", {{"a", a}, {"b", b}})}, {});
    std::map<std::string, Tensor> st;
    for (auto& kv : adam.state_tensors()) st.emplace(kv.first, kv.second);
    st.erase("adam.v.b");
    st["adam.m.a"] = Tensor::zeros({3}, DType::F64);
    st["adam.m.c"] = Tensor::zeros({1}, DType::F64);
    st["model.x"] = Tensor::zeros({7});  // not optimiser state: ignored
    REQUIRE_THROWS_WITH(adam.load_state(st, 5),
                        Contains("3 problem") && Contains("missing 'adam.v.b'") &&
                            Contains("'adam.m.a' is f64[3]") && Contains("expected f64[2]") &&
                            Contains("'adam.m.c' matches no parameter"));
    CHECK(adam.step_count() == 0);  // nothing changed
    st.erase("adam.m.c");
    st["adam.m.a"] = Tensor::full({2}, 0.5, DType::F64);
    st["adam.v.b"] = Tensor::full({1}, 0.25, DType::F64);
    adam.load_state(st, 5);
    CHECK(adam.step_count() == 5);
}

TEST_CASE("adam: rejects bad parameters and hyper-parameters", "[optim][errors]") {
    Tensor a = param({1.0});
    REQUIRE_THROWS_WITH(nn::Adam({group("g", {{"a", a}, {"a", param({2.0})}})}, {}),
                        Contains("duplicate parameter name 'a'"));
    REQUIRE_THROWS_WITH(nn::Adam({group("g", {{"a", a}}), group("h", {{"a2", a}})}, {}),
                        Contains("'a' and 'a2' share storage"));
    REQUIRE_THROWS_WITH(nn::Adam({group("g", {{"x", Tensor::zeros({2})}})}, {}),
                        Contains("'x' of group 'g' does not require grad"));
    REQUIRE_THROWS_WITH(nn::Adam({group("g", {{"i", Tensor::zeros({2}, DType::I32)}})}, {}),
                        Contains("'i'") && Contains("f32 or f64") && Contains("i32"));
    Tensor leaf = param({1.0, 2.0});
    const Tensor derived = leaf.reshape({2, 1});
    REQUIRE_THROWS_WITH(nn::Adam({group("g", {{"d", derived}})}, {}), Contains("not a leaf"));
    REQUIRE_THROWS_WITH(nn::Adam({group("g", {{"u", Tensor()}})}, {}), Contains("undefined"));
    REQUIRE_THROWS_WITH(nn::Adam({group("empty", {})}, {}), Contains("'empty' has no param"));
    REQUIRE_THROWS_WITH(nn::Adam({}, {}), Contains("no parameter groups"));
    REQUIRE_THROWS_WITH(nn::Adam({group("g", {{"a", a}}, -1.0)}, {}), Contains("lr_mult"));
    REQUIRE_THROWS_WITH(nn::Adam({group("g", {{"a", a}}, 1.0, -0.1)}, {}),
                        Contains("weight_decay"));
    nn::AdamOptions o;
    o.beta2 = 1.0;
    REQUIRE_THROWS_WITH(nn::Adam({group("g", {{"a", a}})}, o), Contains("beta2") && Contains("1"));
}

TEST_CASE("adam: the update does not depend on the OpenMP thread count", "[optim]") {
#ifdef _OPENMP
    const int64_t n = 100003;  // above the kernel's parallel threshold, odd tail
    Rng rng(3);
    const Tensor p0 = Tensor::randn({n}, rng);
    const Tensor g = Tensor::randn({n}, rng);
    auto run = [&](int threads) {
        omp_set_num_threads(threads);
        Tensor p = p0.clone().set_requires_grad();
        nn::Adam adam({group("g", {{"p", p}}, 1.0, 0.01)}, {});
        for (int i = 0; i < 3; ++i) {
            p.set_grad(g.clone());
            adam.step();
        }
        return p.to_vector<float>();
    };
    const int prev = omp_get_max_threads();
    const auto one = run(1), two = run(2);
    omp_set_num_threads(prev);
    CHECK(one == two);
    CHECK(one != p0.to_vector<float>());
#else
    testing::mark_skipped("built without OpenMP: thread-count independence not checked");
#endif
}

TEST_CASE("schedules: paper step decay, official G2L, constant", "[optim]") {
    const nn::StepDecay paper(1e-3, 50, 0.5);
    CHECK(paper.lr_at(0) == 1e-3);
    CHECK(paper.lr_at(49) == 1e-3);
    CHECK(paper.lr_at(50) == 5e-4);
    CHECK(paper.lr_at(99) == 5e-4);
    CHECK(paper.lr_at(100) == 2.5e-4);
    CHECK(paper.lr_at(199) == 1.25e-4);

    const nn::OfficialG2L official(1e-3, 300);  // period 300 // 4 = 75
    CHECK(official.lr_at(0) == 1e-3);
    CHECK(official.lr_at(74) == 1e-3);
    CHECK(official.lr_at(75) == 2.5e-4);
    CHECK(official.lr_at(150) == Approx(6.25e-5).epsilon(1e-15));
    CHECK(official.lr_at(299) == Approx(1e-3 / 64).epsilon(1e-15));
    const nn::OfficialG2L odd(1e-3, 10);  // period 10 // 4 = 2
    CHECK(odd.lr_at(1) == 1e-3);
    CHECK(odd.lr_at(2) == 2.5e-4);

    const nn::Constant c(3e-4);
    CHECK(c.lr_at(0) == 3e-4);
    CHECK(c.lr_at(1000) == 3e-4);

    CHECK(nn::make_schedule("step", 1e-3, 50, 0.5, 0)->lr_at(50) == 5e-4);
    CHECK(nn::make_schedule("official", 1e-3, 0, 0.0, 300)->lr_at(75) == 2.5e-4);
    CHECK(nn::make_schedule("constant", 2e-3, 0, 0.0, 0)->lr_at(7) == 2e-3);
    CHECK_THAT(nn::make_schedule("step", 1e-3, 50, 0.5, 0)->describe(), Contains("50"));
}

TEST_CASE("schedules: reject unknown kinds and bad values", "[optim][errors]") {
    REQUIRE_THROWS_WITH(nn::make_schedule("cosine", 1e-3, 50, 0.5, 300),
                        Contains("unknown schedule kind 'cosine'") && Contains("official"));
    REQUIRE_THROWS_WITH(nn::make_schedule("official", 1e-3, 50, 0.5, 3),
                        Contains("total_epochs must be >= 4") && Contains("3"));
    REQUIRE_THROWS_WITH(nn::StepDecay(1e-3, 0, 0.5), Contains("step_epochs must be >= 1"));
    REQUIRE_THROWS_WITH(nn::StepDecay(1e-3, 50, 0.0), Contains("gamma"));
    REQUIRE_THROWS_WITH(nn::Constant(-1.0), Contains("base learning rate") && Contains("-1"));
    REQUIRE_THROWS_WITH(nn::Constant(1e-3).lr_at(-2), Contains("epoch must be >= 0, got -2"));
}
