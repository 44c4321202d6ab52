// SPDX-License-Identifier: MIT
// The skip mechanism itself (tests/test_main.cpp): a hidden case that marks itself skipped. The
// CTest entry "testing: a run whose every case skipped exits 77" runs it alone and expects 77
// (CTest's SKIP_RETURN_CODE), so a test that cannot run is reported as skipped, never passed.
#include <catch2/catch.hpp>

#include "testing.h"

TEST_CASE("hidden: a test case that skips itself", "[.skipdemo]") {
    g2l::testing::mark_skipped("demonstration of the skip exit code");
    CHECK(g2l::testing::skipped_cases() == 1);
}
