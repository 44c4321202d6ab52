// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/atomic_file.h"
#include "testing.h"

using namespace g2l;
using Catch::Contains;
namespace fs = std::filesystem;

TEST_CASE("AtomicFile: whole or nothing, the temporary removed, failures name the file",
          "[core][io]") {
    const std::string dir = testing::temp_dir("atomic_file");
    const std::string path = dir + "/a.txt";

    // Replaces the old contents only on commit, durable or not.
    write_file_atomic(path, "old");
    CHECK(testing::read_file(path) == "old");
    {
        AtomicFile f(path);
        f.write("new ", 4);
        f.write("bytes", 5);
        CHECK(testing::read_file(path) == "old");  // not yet
        CHECK(fs::exists(f.temp_path()));
        f.commit(/*durable=*/false);
        REQUIRE_THROWS_WITH(f.commit(), Contains("committed twice"));
        REQUIRE_THROWS_WITH(f.write("x", 1), Contains("write after commit"));
    }
    CHECK(testing::read_file(path) == "new bytes");
    CHECK(testing::dir_entries(dir) == std::vector<std::string>{"a.txt"});

    // An exception before commit leaves the old file and no temporary.
    try {
        AtomicFile f(path);
        f.write("half", 4);
        throw std::runtime_error("killed halfway");
    } catch (const std::runtime_error&) {
    }
    CHECK(testing::read_file(path) == "new bytes");
    CHECK(testing::dir_entries(dir) == std::vector<std::string>{"a.txt"});

    // A folder that does not exist, and a rename onto a folder: the message names the file and
    // the OS's reason, and nothing is left behind.
    REQUIRE_THROWS_WITH(write_file_atomic(dir + "/no/such/b.txt", "x"),
                        Contains("cannot write '" + dir + "/no/such/b.txt'") &&
                            Contains("No such file or directory"));
    fs::create_directories(dir + "/blocker/inside");
    REQUIRE_THROWS_WITH(write_file_atomic(dir + "/blocker", "x"),
                        Contains("cannot write '" + dir + "/blocker'") && Contains("renaming"));
    CHECK(testing::dir_entries(dir) == std::vector<std::string>{"a.txt", "blocker"});
    write_file_atomic(dir + "/empty.txt", "");
    CHECK(fs::file_size(dir + "/empty.txt") == 0);
}
