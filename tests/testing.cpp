// SPDX-License-Identifier: MIT
#include "testing.h"

#include <catch2/catch.hpp>
#include <cstdlib>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <iostream>
#include <random>
#include <set>

namespace fs = std::filesystem;

namespace g2l::testing {

std::string fixture_dir() { return G2L_TEST_DATA_DIR; }

std::optional<std::string> shared_data_dir() {
    if (const char* env = std::getenv("G2L_SHARED_DATA")) {
        if (fs::is_directory(env)) return std::string(env);
    }
    if (fs::is_directory(G2L_SHARED_DATA_DIR)) return std::string(G2L_SHARED_DATA_DIR);
    return std::nullopt;
}

namespace {
std::set<std::string>& skipped_names() {
    static std::set<std::string> s;
    return s;
}
}  // namespace

void mark_skipped(const std::string& why) {
    std::cerr << "\n*** SKIPPED: " << why << " ***\n";
    WARN("SKIPPED: " << why);
    skipped_names().insert(Catch::getResultCapture().getCurrentTestName());
}

int skipped_cases() { return int(skipped_names().size()); }

void skip_without_shared_data(const std::string& what) {
    // CI sets G2L_REQUIRE_SHARED_DATA when ../shared/data is there: a data test that still cannot
    // find its data is then a failure, never a green skip.
    if (const char* req = std::getenv("G2L_REQUIRE_SHARED_DATA"); req && *req && std::string(req) != "0") {
        FAIL(what << " needs ../shared/data (not found at " << G2L_SHARED_DATA_DIR
                  << ") and G2L_REQUIRE_SHARED_DATA=" << req << " makes that a failure");
    }
    mark_skipped(what + " needs ../shared/data (not found at " + G2L_SHARED_DATA_DIR +
                 "; set G2L_SHARED_DATA to point at it)");
}

std::string temp_dir(const std::string& tag) {
    std::random_device rd;
    const fs::path p = fs::temp_directory_path() /
                       ("g2l_test_" + tag + "_" + std::to_string(rd()) + std::to_string(rd()));
    fs::create_directories(p);
    return p.string();
}

std::string read_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

std::vector<std::string> dir_entries(const std::string& dir) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

}  // namespace g2l::testing
