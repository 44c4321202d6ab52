// SPDX-License-Identifier: MIT
// Helpers shared by the test executables.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace g2l::testing {

/// Directory of the small fixtures shipped in the repository (tests/data).
std::string fixture_dir();

/// ../shared/data if it exists (or $G2L_SHARED_DATA), else std::nullopt. When it is missing the
/// caller's test must be skipped LOUDLY: call skip_without_shared_data(what) and return.
std::optional<std::string> shared_data_dir();

/// Prints a loud "SKIPPED" line on stderr and records a Catch2 WARN naming the test
/// (mark_skipped). With G2L_REQUIRE_SHARED_DATA set (CI, when ../shared/data exists) it fails
/// the test instead: a data test never goes green by skipping.
void skip_without_shared_data(const std::string& what);

/// Exit code of a test run whose every test case was skipped (CTest SKIP_RETURN_CODE).
constexpr int kSkipExitCode = 77;

/// Marks the running test case as skipped: prints "*** SKIPPED: why ***" on stderr, records a
/// Catch2 WARN, and counts the case once (a run whose every case is skipped exits with
/// kSkipExitCode, so CTest shows it as skipped, not passed). The caller returns afterwards.
void mark_skipped(const std::string& why);

/// Number of distinct test cases marked skipped in this process.
int skipped_cases();

/// A fresh empty temporary directory (removed at process exit is not guaranteed).
std::string temp_dir(const std::string& tag);

/// A file's bytes ("" when it cannot be opened).
std::string read_file(const std::string& path);

/// The names of a directory's entries, sorted.
std::vector<std::string> dir_entries(const std::string& dir);

}  // namespace g2l::testing
