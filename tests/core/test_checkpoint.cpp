// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "core/checkpoint.h"
#include "core/json.h"
#include "core/rng.h"
#include "testing.h"

using namespace g2l;
using Catch::Contains;
namespace fs = std::filesystem;

namespace {

void write_bytes(const std::string& path, const std::string& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), std::streamsize(bytes.size()));
}

bool same_bytes(const Tensor& a, const Tensor& b) {
    return a.dtype() == b.dtype() && a.shape() == b.shape() &&
           std::memcmp(a.data(), b.data(), a.nbytes()) == 0;
}

uint64_t u64_at(const std::string& s, size_t pos) {
    uint64_t v;
    std::memcpy(&v, s.data() + pos, 8);
    return v;
}

/// A small checkpoint: f32 [2, 3], f64 [4], i32 [2, 2, 1], a 0-d and an empty tensor.
std::vector<std::pair<std::string, Tensor>> sample() {
    Rng rng(5);
    return {{"net.w", Tensor::randn({2, 3}, rng)},
            {"net.b", Tensor::randn({4}, rng, DType::F64)},
            {"idx", Tensor::from_vector<int32_t>({1, -2, 2147483647, -2147483647 - 1}, {2, 2, 1})},
            {"scalar", Tensor::scalar(-0.0, DType::F64)},
            {"empty", Tensor::zeros({0, 5})}};
}

const char* kMeta = "{\"model\": {\"points\": 1024, \"name\": \"ape \\u00e9\"}, \"step\": 7}";

}  // namespace

TEST_CASE("checkpoint: round trip is bitwise for f32, f64, i32 tensors and metadata",
          "[checkpoint]") {
    const std::string dir = testing::temp_dir("ckpt");
    const std::string path = dir + "/model.g2l";
    auto tensors = sample();
    // Awkward float values must survive untouched: NaN payload, -0, denormal, infinity.
    float* w = tensors[0].second.data<float>();
    const uint32_t nan_bits = 0x7fc01234u;
    std::memcpy(&w[0], &nan_bits, 4);
    w[1] = -0.0f;
    w[2] = 1e-40f;
    w[3] = -INFINITY;
    save_checkpoint(path, tensors, kMeta);

    const Checkpoint ck = load_checkpoint(path);
    CHECK(ck.meta_json == kMeta);
    REQUIRE(ck.tensors.size() == tensors.size());
    for (const auto& [name, t] : tensors) {
        INFO(name);
        REQUIRE(ck.tensors.count(name) == 1);
        CHECK(same_bytes(ck.tensors.at(name), t));
        CHECK(ck.tensors.at(name).device().is_cpu());
    }
    // Layout facts from docs/checkpoint.md: magic, version, meta length, 64-byte aligned data,
    // end magic.
    const std::string bytes = testing::read_file(path);
    CHECK(bytes.substr(0, 4) == "G2LW");
    CHECK(bytes[4] == 1);
    CHECK(u64_at(bytes, 8) == std::strlen(kMeta));
    CHECK(bytes.substr(bytes.size() - 8) == std::string("G2LWEND\0", 8));
    // The first record follows the tensor count: name "net.w" at 20 + meta + 4.
    const size_t rec = 20 + std::strlen(kMeta);
    CHECK(bytes.substr(rec + 4, 5) == "net.w");
    const uint64_t offset = u64_at(bytes, rec + 4 + 5 + 2 + 16);
    CHECK(offset % 64 == 0);
    CHECK(std::memcmp(bytes.data() + offset, tensors[0].second.data(), 24) == 0);

    // Saving twice gives identical files (deterministic, padding zeroed).
    save_checkpoint(dir + "/again.g2l", tensors, kMeta);
    CHECK(testing::read_file(dir + "/again.g2l") == bytes);
}

TEST_CASE("checkpoint: save is atomic and leaves no temporary file", "[checkpoint]") {
    const std::string dir = testing::temp_dir("ckpt_tmp");
    const std::string path = dir + "/a.g2l";
    save_checkpoint(path, sample(), "{}");
    save_checkpoint(path, {{"x", Tensor::ones({3})}}, "{\"v\": 2}");  // overwrite in place
    CHECK(testing::dir_entries(dir) == std::vector<std::string>{"a.g2l"});
    const Checkpoint ck = load_checkpoint(path);
    CHECK(ck.meta_json == "{\"v\": 2}");
    CHECK(ck.tensors.size() == 1);
    CHECK(ck.tensors.at("x").to_vector<float>() == std::vector<float>{1, 1, 1});

    // A failed save (bad directory) throws naming the temp file and leaves nothing behind.
    REQUIRE_THROWS_WITH(save_checkpoint(dir + "/no/such/dir/b.g2l", sample(), "{}"),
                        Contains("no/such/dir/b.g2l.tmp."));
    // A save that fails during the rename (target is a directory) removes its temp file.
    fs::create_directories(dir + "/blocker.g2l/inside");
    REQUIRE_THROWS_WITH(save_checkpoint(dir + "/blocker.g2l", sample(), "{}"),
                        Contains("renaming") && Contains("blocker.g2l"));
    CHECK(testing::dir_entries(dir) == std::vector<std::string>{"a.g2l", "blocker.g2l"});
}

TEST_CASE("checkpoint: every truncation of a small file throws 'truncated'", "[checkpoint]") {
    const std::string dir = testing::temp_dir("ckpt_cut");
    save_checkpoint(dir + "/full.g2l", sample(), kMeta);
    const std::string bytes = testing::read_file(dir + "/full.g2l");
    for (size_t len = 0; len < bytes.size(); ++len) {
        INFO("cut at " << len << " of " << bytes.size() << " bytes");
        // A fresh name per case: re-truncating one file makes ext4 flush on every close (slow).
        const std::string cut = dir + "/cut" + std::to_string(len) + ".g2l";
        write_bytes(cut, bytes.substr(0, len));
        REQUIRE_THROWS_WITH(load_checkpoint(cut), Contains("truncated") && Contains(cut));
        fs::remove(cut);
    }
}

TEST_CASE("checkpoint: a flipped byte anywhere is a checksum error (or bad magic/version)",
          "[checkpoint]") {
    const std::string dir = testing::temp_dir("ckpt_flip");
    save_checkpoint(dir + "/ok.g2l", sample(), kMeta);
    const std::string bytes = testing::read_file(dir + "/ok.g2l");
    // Every byte before the checksum: magic bytes -> bad magic, version -> unsupported version,
    // anything else (metadata, records, padding, data) -> checksum mismatch.
    for (size_t i = 0; i + 16 < bytes.size(); ++i) {
        INFO("flipped byte " << i);
        std::string b = bytes;
        b[i] = char(b[i] ^ 0x20);
        const std::string bad = dir + "/bad" + std::to_string(i) + ".g2l";
        write_bytes(bad, b);
        if (i < 4) {
            REQUIRE_THROWS_WITH(load_checkpoint(bad), Contains("bad magic"));
        } else if (i < 8) {
            REQUIRE_THROWS_WITH(load_checkpoint(bad), Contains("unsupported version"));
        } else {
            REQUIRE_THROWS_WITH(load_checkpoint(bad),
                                Contains("checksum mismatch") && Contains(bad));
        }
        fs::remove(bad);
    }
    const std::string bad = dir + "/bad.g2l";
    // A flipped checksum byte is a mismatch too.
    std::string b = bytes;
    b[bytes.size() - 12] ^= 1;
    write_bytes(bad, b);
    REQUIRE_THROWS_WITH(load_checkpoint(bad), Contains("checksum mismatch"));
}

TEST_CASE("checkpoint: bad magic, missing file, unsupported version, trailing bytes",
          "[checkpoint]") {
    const std::string dir = testing::temp_dir("ckpt_bad");
    REQUIRE_THROWS_WITH(load_checkpoint(dir + "/nope.g2l"),
                        Contains("nope.g2l") && Contains("missing"));
    REQUIRE_THROWS_WITH(load_checkpoint(dir), Contains("not a regular file"));
    write_bytes(dir + "/png.g2l", std::string("\x89PNG\r\n\x1a\n", 8) + std::string(100, 'x'));
    REQUIRE_THROWS_WITH(load_checkpoint(dir + "/png.g2l"),
                        Contains("png.g2l") && Contains("not a g2l checkpoint"));

    save_checkpoint(dir + "/ok.g2l", sample(), "{}");
    std::string bytes = testing::read_file(dir + "/ok.g2l");
    std::string v2 = bytes;
    v2[4] = 2;
    write_bytes(dir + "/v2.g2l", v2);
    REQUIRE_THROWS_WITH(load_checkpoint(dir + "/v2.g2l"),
                        Contains("unsupported version 2") && Contains("v2.g2l"));
    write_bytes(dir + "/long.g2l", bytes + "junk");
    REQUIRE_THROWS_WITH(load_checkpoint(dir + "/long.g2l"), Contains("long.g2l"));
}

TEST_CASE("checkpoint: save rejects duplicate names, undefined tensors, bad metadata",
          "[checkpoint]") {
    const std::string dir = testing::temp_dir("ckpt_save");
    const std::string p = dir + "/x.g2l";
    REQUIRE_THROWS_WITH(save_checkpoint(p, {{"a", Tensor::ones({1})}, {"a", Tensor::ones({2})}},
                                        "{}"),
                        Contains("duplicate tensor name 'a'") && Contains(p));
    REQUIRE_THROWS_WITH(save_checkpoint(p, {{"u", Tensor()}}, "{}"), Contains("'u' is undefined"));
    REQUIRE_THROWS_WITH(save_checkpoint(p, {{"", Tensor::ones({1})}}, "{}"),
                        Contains("empty tensor name"));
    REQUIRE_THROWS_WITH(save_checkpoint(p, {{"a", Tensor::ones({1})}}, "{not json"),
                        Contains("not valid JSON") && Contains("{not json"));
    REQUIRE_THROWS_WITH(save_checkpoint(p, {{"a", Tensor::ones({1, 1, 1, 1, 1, 1, 1, 1, 1})}},
                                        "{}"),
                        Contains("'a' has 9 dims"));
    CHECK_FALSE(fs::exists(p));
}

// Files that carry a valid checksum but a semantically bad header (a buggy or hostile writer):
// the reader must still refuse them with a precise message. We patch one field and recompute
// the FNV-1a checksum the same way the format defines it.
TEST_CASE("checkpoint: valid checksum but bad dtype, duplicate names, misaligned data",
          "[checkpoint]") {
    const std::string dir = testing::temp_dir("ckpt_sem");
    auto reseal = [](std::string b) {
        uint64_t h = 0xcbf29ce484222325ull;
        for (size_t i = 0; i + 16 < b.size(); ++i) h = (h ^ uint8_t(b[i])) * 0x100000001b3ull;
        std::memcpy(&b[b.size() - 16], &h, 8);
        return b;
    };
    save_checkpoint(dir + "/ok.g2l", {{"aa", Tensor::ones({2})}, {"ab", Tensor::ones({3})}}, "{}");
    const std::string bytes = testing::read_file(dir + "/ok.g2l");
    CHECK(reseal(bytes) == bytes);  // the test's checksum is the format's checksum
    // meta "{}" -> records start at 22; record 0: u32 len, "aa", dtype at 28, ndim 29, dim 30..37
    std::string b = bytes;
    b[28] = 7;
    write_bytes(dir + "/dtype.g2l", reseal(b));
    REQUIRE_THROWS_WITH(load_checkpoint(dir + "/dtype.g2l"),
                        Contains("'aa' has bad dtype code 7") && Contains("dtype.g2l"));
    b = bytes;
    b[27] = 'b';  // "aa" -> "ab": duplicate of the second tensor
    write_bytes(dir + "/dup.g2l", reseal(b));
    REQUIRE_THROWS_WITH(load_checkpoint(dir + "/dup.g2l"), Contains("duplicate tensor name 'ab'"));
    b = bytes;
    b[38] = char(b[38] + 4);  // offset of "aa" += 4
    write_bytes(dir + "/align.g2l", reseal(b));
    REQUIRE_THROWS_WITH(load_checkpoint(dir + "/align.g2l"), Contains("not 64-byte aligned"));
    b = bytes;
    b[46] = 12;  // nbytes of "aa" (f32[2] = 8) -> 12
    write_bytes(dir + "/nbytes.g2l", reseal(b));
    REQUIRE_THROWS_WITH(load_checkpoint(dir + "/nbytes.g2l"),
                        Contains("needs 8 bytes, header says 12"));
}

TEST_CASE("parse_json_strict: duplicate keys, syntax errors and trailing text name the source",
          "[core][json]") {
    using Catch::Matchers::Contains;
    CHECK(g2l::parse_json_strict(R"({"a": 1, "b": {"c": [1, 2]}})", "t").at("b").at("c").size() == 2);
    REQUIRE_THROWS_WITH(g2l::parse_json_strict(R"({"lr": 1, "lr": 2})", "cfg.json"),
                        Contains("cfg.json") && Contains("duplicate key 'lr'"));
    REQUIRE_THROWS_WITH(g2l::parse_json_strict(R"({"optim": {"lr": 1, "beta1": 0.9, "lr": 2}})", "c"),
                        Contains("duplicate key 'optim.lr'"));
    // the same key in different objects is fine
    CHECK_NOTHROW(g2l::parse_json_strict(R"([{"x": 1}, {"x": 2}, {"y": {"x": 3}}])", "t"));
    REQUIRE_THROWS_WITH(g2l::parse_json_strict(R"([{"x": 1, "y": {"z": 1}, "x": 2}])", "t"),
                        Contains("duplicate key 'x'"));
    REQUIRE_THROWS_WITH(g2l::parse_json_strict("{\"a\": 1,}", "s"), Contains("s: invalid JSON at byte"));
    REQUIRE_THROWS_WITH(g2l::parse_json_strict("{} {}", "s"), Contains("invalid JSON"));
    REQUIRE_THROWS_WITH(g2l::parse_json_strict("", "empty.json"), Contains("empty.json: invalid JSON"));
    REQUIRE_THROWS_WITH(g2l::parse_json_strict("[NaN]", "s"), Contains("invalid JSON"));
    REQUIRE_THROWS_WITH(g2l::parse_json_strict("// c\n{}", "s"), Contains("invalid JSON"));
    const auto o = g2l::parse_json_strict_ordered(R"({"b": 1, "a": 2})", "t");
    CHECK(o.begin().key() == "b");
    REQUIRE_THROWS_WITH(g2l::parse_json_file("/nonexistent/x.json"), Contains("/nonexistent/x.json"));
}
