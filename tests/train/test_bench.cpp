// SPDX-License-Identifier: MIT
// g2l_bench's refinement figure runs what it says: the refinement finds the pose (bench_refine
// throws otherwise), and it reports its four figures. No time is asserted (benchmarks print
// numbers; docs/results.md records them).
#include <catch2/catch.hpp>
#include <cmath>

#include "core/error.h"
#include "tools/bench.h"

using namespace g2l;
using Catch::Matchers::Contains;

TEST_CASE("bench_refine: four figures, the grid's build and both paths timed", "[train][bench]") {
    const auto figs = tools::bench_refine(1);
    REQUIRE(figs.size() == 4);
    CHECK(figs[0].name == "refine_ms");
    CHECK(figs[1].name == "refine_ms_p90");
    CHECK(figs[2].name == "refine_tree_ms");
    CHECK(figs[3].name == "refine_prepare_ms");
    for (const auto& f : figs) {
        CHECK(f.unit == "ms");
        CHECK(std::isfinite(f.value));
        CHECK(f.value > 0);
    }
    CHECK(figs[0].value <= figs[1].value);  // median <= p90
    CHECK_THAT(figs[0].detail, Contains("1000 observed points"));
    CHECK_THROWS_WITH(tools::bench_refine(0), Contains("reps must be >= 1"));
}

TEST_CASE("bench_training: the GEMM work of a step, counted, grows with the batch",
          "[train][bench]") {
    // Every GEMM of a step is per sample (1x1 convolutions, their dx / dW) or has the batch as one
    // side (the fully connected layers), so twice the batch is exactly twice the FLOPs.
    const auto get = [](const std::vector<tools::BenchFigure>& figs, const std::string& name) {
        for (const auto& f : figs)
            if (f.name == name) return f.value;
        FAIL("no figure " << name);
        return 0.0;
    };
    const auto two = tools::bench_training(1, 0.125, 2, 64, 32);
    const auto four = tools::bench_training(1, 0.125, 4, 64, 32);
    const double g2 = get(two, "train_step_gemm_gflop"), g4 = get(four, "train_step_gemm_gflop");
    CHECK(g2 > 0);
    CHECK(g4 == Approx(2 * g2).epsilon(1e-12));
    // The rate is that work over the step's time.
    CHECK(get(two, "train_gemm_gflops") ==
          Approx(g2 / (get(two, "train_step_ms") * 1e-3)).epsilon(1e-9));
}
