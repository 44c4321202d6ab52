// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/autograd.h"
#include "core/rng.h"
#include "core/storage.h"
#include "core/tensor.h"

using namespace g2l;

TEST_CASE("tensor: factories, shape queries and 64-byte aligned storage", "[core]") {
    const Tensor z = Tensor::zeros({2, 3, 4});
    REQUIRE(z.dim() == 3);
    REQUIRE(z.numel() == 24);
    REQUIRE(z.size(-1) == 4);
    REQUIRE(z.strides() == Shape{12, 4, 1});
    REQUIRE(Tensor::scalar(1).strides().empty());
    REQUIRE(z.dtype() == DType::F32);
    REQUIRE(z.device() == Device::cpu());
    REQUIRE(reinterpret_cast<uintptr_t>(z.data()) % 64 == 0);
    REQUIRE(Tensor::full({2}, 2.5, DType::F64).to_vector<double>() == std::vector<double>{2.5, 2.5});
    REQUIRE(Tensor::scalar(3).item<float>() == 3.f);
    REQUIRE(z.desc() == "f32[2, 3, 4] cpu");
}

TEST_CASE("tensor: copies alias, clone copies, reshape is a view", "[core]") {
    Tensor a = Tensor::from_vector<float>({1, 2, 3, 4}, {2, 2});
    Tensor alias = a;
    Tensor copy = a.clone();
    Tensor view = a.reshape({4});
    a.data<float>()[0] = 9;
    REQUIRE(alias.data<float>()[0] == 9);
    REQUIRE(view.data<float>()[0] == 9);
    REQUIRE(copy.data<float>()[0] == 1);
    REQUIRE(view.shares_storage_with(a));
    REQUIRE_FALSE(copy.shares_storage_with(a));
    REQUIRE(a.reshape({-1, 1}).shape() == Shape{4, 1});
}

TEST_CASE("tensor: bad shapes, dtypes and devices are rejected with their values", "[core][errors]") {
    const Tensor a = Tensor::zeros({2, 3});
    REQUIRE_THROWS_WITH(a.reshape({4}), Catch::Contains("[4]") && Catch::Contains("f32[2, 3]"));
    REQUIRE_THROWS_WITH(a.reshape({-1, -1}), Catch::Contains("more than one -1"));
    REQUIRE_THROWS_WITH(a.size(2), Catch::Contains("dimension 2") && Catch::Contains("[2, 3]"));
    REQUIRE_THROWS_WITH(a.data<double>(), Catch::Contains("data<f64>"));
    REQUIRE_THROWS_WITH(Tensor::from_vector<float>({1, 2, 3}, {2, 2}), Catch::Contains("3 values"));
    REQUIRE_THROWS_WITH(Tensor::zeros({-1}), Catch::Contains("negative"));
    REQUIRE_THROWS_WITH(a.item<float>(), Catch::Contains("one element"));
    REQUIRE_THROWS_WITH(Tensor().shape(), Catch::Contains("undefined"));
    REQUIRE_THROWS_WITH(parse_device("gpu"), Catch::Contains("'gpu'"));
    REQUIRE(parse_device("cuda:1") == Device::cuda(1));
    if (!cuda_available()) {
        REQUIRE_THROWS_WITH(a.to(Device::cuda()), Catch::Contains("built without CUDA") ||
                                                      Catch::Contains("cuda"));
    }
}

TEST_CASE("tensor: dtype conversion round trips and is differentiable", "[core]") {
    Tensor a = Tensor::from_vector<double>({1.5, -2.25}, {2});
    a.set_requires_grad();
    Tensor f = a.to(DType::F32);
    REQUIRE(f.to_vector<float>() == std::vector<float>{1.5f, -2.25f});
    f.backward(Tensor::from_vector<float>({1, 2}, {2}));
    REQUIRE(a.grad().to_vector<double>() == std::vector<double>{1, 2});
    REQUIRE(Tensor::from_vector<float>({2.7f}, {1}).to(DType::I32).item<int32_t>() == 2);
}

TEST_CASE("rng: deterministic streams, state round trip, distribution moments", "[core]") {
    Rng a(42), b(42);
    for (int i = 0; i < 100; ++i) REQUIRE(a.next_u64() == b.next_u64());
    const auto s = a.state();
    const double u = a.uniform();
    b.set_state(s);
    REQUIRE(b.uniform() == u);
    Rng r(7);
    double sum = 0, sq = 0;
    const int n = 200000;
    for (int i = 0; i < n; ++i) {
        const double x = r.normal();
        sum += x;
        sq += x * x;
    }
    REQUIRE(std::abs(sum / n) < 0.01);
    REQUIRE(std::abs(sq / n - 1) < 0.01);
    for (int i = 0; i < 1000; ++i) {
        const int64_t k = r.randint(-3, 4);
        REQUIRE(k >= -3);
        REQUIRE(k < 4);
    }
    REQUIRE_THROWS_WITH(r.below(0), Catch::Contains("n must be > 0"));
}

TEST_CASE("storage: large CPU blocks are recycled within the cache's limit", "[core]") {
    Storage::release_cpu_cache();
    REQUIRE(Storage::cpu_bytes_cached() == 0);
    const int64_t limit = Storage::cpu_cache_limit();
    const int64_t mib4 = int64_t(4) << 20;
    CHECK_THROWS_WITH(Storage::set_cpu_cache_limit(-1), Catch::Contains("must be >= 0, got -1"));
    if (limit == 0) {  // an AddressSanitizer build (or G2L_CPU_CACHE_MB=0): nothing is kept
        { Tensor t = Tensor::empty({1 << 20}); }
        CHECK(Storage::cpu_bytes_cached() == 0);
        WARN("the CPU block cache is off in this build: only its off state was checked");
        return;
    }
    const void* p = nullptr;
    { const Tensor a = Tensor::empty({1 << 20}); p = a.data(); }  // 4 MiB
    CHECK(Storage::cpu_bytes_cached() == mib4);
    {
        const Tensor b = Tensor::empty({1 << 20});
        CHECK(b.data() == p);
        CHECK(Storage::cpu_bytes_cached() == 0);
        CHECK(std::isnan(b.data<float>()[12345]));  // the tests poison recycled blocks
    }
    {   // up to 1/8 smaller takes it back; half the size does not
        const Tensor c = Tensor::empty({(1 << 20) - 100000});
        CHECK(c.data() == p);
    }
    {
        const Tensor d = Tensor::empty({1 << 19});
        CHECK(d.data() != p);
        CHECK(Storage::cpu_bytes_cached() == mib4);
    }
    {   // zeros() on a recycled (poisoned) block is zero
        const Tensor z = Tensor::zeros({1 << 20});
        CHECK(z.data() == p);
        const std::vector<float> v = z.to_vector<float>();
        CHECK(std::count(v.begin(), v.end(), 0.f) == int64_t(v.size()));
    }
    {   // small blocks go back to malloc
        const int64_t before = Storage::cpu_bytes_cached();
        { const Tensor s = Tensor::empty({1000}); }
        CHECK(Storage::cpu_bytes_cached() == before);
    }
    // A lower limit frees the oldest blocks now, and a block larger than the limit is not kept.
    Storage::set_cpu_cache_limit(int64_t(3) << 20);
    CHECK(Storage::cpu_bytes_cached() <= int64_t(3) << 20);
    { const Tensor big = Tensor::empty({1 << 20}); }
    CHECK(Storage::cpu_bytes_cached() <= int64_t(3) << 20);
    Storage::set_cpu_cache_limit(limit);
    CHECK(Storage::cpu_cache_limit() == limit);
    Storage::release_cpu_cache();
    CHECK(Storage::cpu_bytes_cached() == 0);
}
