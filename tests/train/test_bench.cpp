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
