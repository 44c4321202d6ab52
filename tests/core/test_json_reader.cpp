// SPDX-License-Identifier: MIT
// The one strict schema reader (core/json_reader.h): types, ranges, lengths, unknown keys and
// key paths, in the one message style every JSON file of g2l reports with.
#include <catch2/catch.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/json.h"
#include "core/json_reader.h"

using Catch::Contains;
using g2l::JsonReader;
using nlohmann::json;

namespace {

json parse(const std::string& text) { return g2l::parse_json_strict(text, "t.json"); }

}  // namespace

TEST_CASE("JsonReader reads every type and leaves absent keys at their defaults", "[core]") {
    const json j = parse(R"({"a": 1.5, "n": 7, "big": 1e3, "b": true, "s": "x", "c": "sphere",
        "ids": [1, 2, 3], "ss": ["p", "q"], "v3": [1, 2, 3], "sub": {"k": -4},
        "list": [{"k": 1}, {"k": 2}], "u": 18446744073709551615})");
    JsonReader r(j, "t.json");
    double a = 0, missing = 42;
    int n = 0, big = 0;
    bool b = false;
    std::string s, c;
    std::vector<int> ids;
    std::vector<std::string> ss;
    std::array<double, 3> v3{};
    int k = 0;
    std::vector<int> list;
    uint64_t u = 0;
    r.num("a", a);
    r.num("missing", missing);
    r.integer("n", n);
    r.integer("big", big);
    r.boolean("b", b);
    r.text("s", s);
    r.choice("c", c, {"sphere", "slab"});
    r.ints("ids", ids);
    r.texts("ss", ss);
    r.num3("v3", v3);
    r.object("sub", [&](JsonReader& sub) { sub.integer("k", k); });
    r.list("list", list, [](JsonReader& e, int& x) { e.integer("k", x); });
    r.integer("u", u);
    r.finish();
    CHECK(a == 1.5);
    CHECK(missing == 42);  // absent: unchanged
    CHECK(n == 7);
    CHECK(big == 1000);  // a whole number written as a float
    CHECK(b);
    CHECK(s == "x");
    CHECK(c == "sphere");
    CHECK(ids == std::vector<int>{1, 2, 3});
    CHECK(ss == std::vector<std::string>{"p", "q"});
    CHECK(v3 == std::array<double, 3>{1, 2, 3});
    CHECK(k == -4);
    CHECK(list == std::vector<int>{1, 2});
    CHECK(u == 18446744073709551615ull);
}

TEST_CASE("JsonReader: every bad value names the file, the key path and the value", "[core]") {
    auto fails = [](const std::string& text, const std::string& what, auto&& read) {
        INFO(text);
        const json j = parse(text);
        JsonReader r(j, "t.json");
        REQUIRE_THROWS_WITH((read(r), r.finish()), Contains("t.json: ") && Contains(what));
    };
    int i = 0;
    double d = 0;
    float f = 0;
    uint64_t u = 0;
    std::string s;
    std::array<double, 3> v3{};
    fails(R"({"n": 2.5})", "'n' must be an integer in the range of 32 bits, got 2.5",
          [&](JsonReader& r) { r.integer("n", i); });
    fails(R"({"n": 1e300})", "'n' must be an integer in the range of 32 bits, got 1e+300",
          [&](JsonReader& r) { r.integer("n", i); });
    fails(R"({"n": 4294967296})", "'n' must be an integer in the range of 32 bits",
          [&](JsonReader& r) { r.integer("n", i); });
    fails(R"({"n": -1})", "'n' must be a non-negative integer in the range of 64 bits, got -1",
          [&](JsonReader& r) { r.integer("n", u); });
    fails(R"({"n": "7"})", "'n' must be an integer", [&](JsonReader& r) { r.integer("n", i); });
    fails(R"({"x": "1"})", "'x' must be a number, got \"1\"", [&](JsonReader& r) { r.num("x", d); });
    fails(R"({"x": 1e300})", "'x' is out of the float range, got 1e+300",
          [&](JsonReader& r) { r.num("x", f); });
    fails(R"({"b": 1})", "'b' must be true or false, got 1",
          [&](JsonReader& r) { bool b; r.boolean("b", b); });
    fails(R"({"c": "cube"})", "'c' must be one of \"sphere\", \"slab\", got \"cube\"",
          [&](JsonReader& r) { r.choice("c", s, {"sphere", "slab"}); });
    fails(R"({"v": [1, 2]})", "'v' must be an array of 3 numbers, got [1,2]",
          [&](JsonReader& r) { r.num3("v", v3); });
    fails(R"({"v": [1, null, 3]})", "'v[1]' must be a number, got null",
          [&](JsonReader& r) { r.num3("v", v3); });
    fails(R"({"ids": [1, "2"]})", "'ids[1]' must be an integer",
          [&](JsonReader& r) { std::vector<int> v; r.ints("ids", v); });
    fails(R"({"sub": {"deep": {"x": "y"}}})", "'sub.deep.x' must be a number, got \"y\"",
          [&](JsonReader& r) {
              r.object("sub", [&](JsonReader& a) {
                  a.object("deep", [&](JsonReader& b) { b.num("x", d); });
              });
          });
    fails(R"({"list": [{"k": 1}, {"k": 1, "kk": 2}]})", "unknown key 'list[1].kk' (known: k)",
          [&](JsonReader& r) {
              std::vector<int> v;
              r.list("list", v, [](JsonReader& e, int& x) { e.integer("k", x); });
          });
    fails(R"({"list": [1]})", "'list[0]' must be a JSON object, got 1", [&](JsonReader& r) {
        std::vector<int> v;
        r.list("list", v, [](JsonReader& e, int& x) { e.integer("k", x); });
    });
    fails(R"({"lr": 1, "lrr": 2})", "unknown key 'lrr' (known: lr)",
          [&](JsonReader& r) { r.num("lr", d); });
    fails(R"({})", "'need' is required", [&](JsonReader& r) { r.require("need"); });
    fails(R"({"s": "averyveryveryveryveryveryveryveryveryveryveryveryveryveryveryveryveryverylongvalue"})",
          "got \"averyveryvery", [&](JsonReader& r) { r.integer("s", i); });
    REQUIRE_THROWS_WITH(JsonReader(parse("[1]"), "t.json"),
                        Contains("t.json: the top level must be a JSON object, got [1]"));
}
