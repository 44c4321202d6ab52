// SPDX-License-Identifier: MIT
// Catch2 main for every test executable. A run in which every test case that ran was skipped
// (testing::mark_skipped: no ../shared/data, no OpenMP, ...) exits with testing::kSkipExitCode,
// which tests/CMakeLists.txt gives CTest as SKIP_RETURN_CODE: CTest then reports the test as
// "Skipped" instead of "Passed". A run with at least one test that did run exits as Catch2 says.
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>

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
    const int result = Catch::Session().run(argc, argv);
    if (result == 0 && g_cases_run > 0 && g2l::testing::skipped_cases() == g_cases_run)
        return g2l::testing::kSkipExitCode;
    return result;
}
