// SPDX-License-Identifier: MIT
// Helpers of the libFuzzer targets: a private temporary folder and writing an input to a file
// (the readers under test take paths, as users give them).
#pragma once

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace g2l::fuzz {

inline const std::string& temp_dir() {
    static const std::string dir = [] {
        char tmpl[] = "/tmp/g2l_fuzz_XXXXXX";
        const char* d = mkdtemp(tmpl);
        if (!d) std::abort();
        return std::string(d);
    }();
    return dir;
}

inline void write_file(const std::string& path, const uint8_t* data, size_t size) {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
}

}  // namespace g2l::fuzz
