// SPDX-License-Identifier: MIT
// Catch2 main for every test executable. A run in which every test case that ran was skipped
// (testing::mark_skipped: no ../shared/data, no OpenMP, ...) exits with testing::kSkipExitCode,
// which tests/CMakeLists.txt gives CTest as SKIP_RETURN_CODE: CTest then reports the test as
// "Skipped" instead of "Passed". A run with at least one test that did run exits as Catch2 says.
// A run whose filter matched no test case fails (exit 3): a misspelt tag in CI or in a CTest
// entry must not pass silently (listing the tests, as catch_discover_tests does, is not a run).
// Recycled CPU blocks are poisoned with NaN bytes (core/storage.h) in every test binary, so that
// a kernel that reads an output it never wrote fails here instead of reading a stale value.
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>

#include <cstdio>
#include <string>

#include "core/storage.h"
#include "testing.h"

namespace {
int g_cases_run = 0;

struct CaseCounter : Catch::TestEventListenerBase {
    using TestEventListenerBase::TestEventListenerBase;
    void testCaseStarting(Catch::TestCaseInfo const&) override { ++g_cases_run; }
};
}  // namespace

CATCH_REGISTER_LISTENER(CaseCounter)

int main(int argc, char* argv[]) {
    g2l::Storage::set_cpu_cache_poison(true);
    bool listing = false;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        listing |= a.rfind("--list", 0) == 0 || a == "-l" || a == "-t" || a == "-h" ||
                   a == "-?" || a == "--help";
    }
    const int result = Catch::Session().run(argc, argv);
    if (result == 0 && g_cases_run == 0 && !listing) {
        std::fprintf(stderr, "no test case matched the filter: nothing was tested\n");
        return 3;
    }
    if (result == 0 && g_cases_run > 0 && g2l::testing::skipped_cases() == g_cases_run)
        return g2l::testing::kSkipExitCode;
    return result;
}
