// SPDX-License-Identifier: MIT
// The one strict schema reader behind every JSON file g2l reads (training configs, detector
// configs, scene configs, BOP scene files, camera files, models_info, detection files,
// checkpoint metadata). core/json.h parses (syntax, duplicate keys); this reads one object:
//   - every key it is asked for is remembered, finish() rejects the others, listing the known
//     ones ("unknown key 'optim.lrr' (known: lr, beta1, ...)");
//   - every type and range error names the source and the key path in one style:
//       <source>: '<a.b[2].c>' must be <what>, got <value>
//   - numbers are finite, integers are whole and inside their C++ type (never a wrapping or
//     undefined cast), arrays have the length asked for.
// Optional keys leave the destination unchanged when absent (defaults live in the structs);
// require() makes one mandatory. Range checks that need several fields stay with the caller,
// who names the key with at().
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <type_traits>
#include <vector>

#include "core/error.h"

namespace g2l {

template <class Json>
class BasicJsonReader {
public:
    /// `source` names the file in every message ("config 'a.json'"), `path` is the key path of
    /// this object ("" at the top level). Fails unless `j` is an object.
    BasicJsonReader(const Json& j, std::string source, std::string path = "")
        : j_(j), src_(std::move(source)), path_(std::move(path)) {
        G2L_CHECK(j.is_object(), src_, ": ", path_.empty() ? std::string("the top level")
                                                          : "'" + path_ + "'",
                  " must be a JSON object, got ", brief(j));
    }

    const std::string& source() const { return src_; }
    /// The full key path of key k, for the caller's own messages.
    std::string at(const std::string& k) const { return path_.empty() ? k : path_ + "." + k; }
    bool has(const char* k) const { return j_.contains(k); }

    /// Fails unless key k is present.
    void require(const char* k) const {
        G2L_CHECK(j_.contains(k), src_, ": '", at(k), "' is required");
    }
    /// Marks k as known without reading it (a key another reader handles, or one we accept
    /// from other tools and do not need).
    void ignore(const char* k) { find(k); }
    /// The raw value of k (nullptr when absent), marked as read: for the rare key whose type
    /// decides how it is read.
    const Json* get(const char* k) { return find(k); }

    /// A finite number.
    void num(const char* k, double& v) {
        if (const Json* x = find(k)) v = as_num(*x, at(k));
    }
    void num(const char* k, float& v) {
        if (const Json* x = find(k)) {
            const double d = as_num(*x, at(k));
            G2L_CHECK(std::abs(d) <= std::numeric_limits<float>::max(), src_, ": '", at(k),
                      "' is out of the float range, got ", x->dump());
            v = static_cast<float>(d);
        }
    }
    /// A whole number inside T's range (1e3 is accepted as 1000; 2.5 and 1e300 are not).
    template <class T>
    void integer(const char* k, T& v) {
        static_assert(std::is_integral_v<T>, "integer() reads an integral type");
        if (const Json* x = find(k)) v = as_int<T>(*x, at(k));
    }
    void boolean(const char* k, bool& v) {
        if (const Json* x = find(k)) {
            G2L_CHECK(x->is_boolean(), src_, ": '", at(k), "' must be true or false, got ",
                      brief(*x));
            v = x->template get<bool>();
        }
    }
    void text(const char* k, std::string& v) {
        if (const Json* x = find(k)) v = as_text(*x, at(k));
    }
    /// A string out of a fixed list.
    void choice(const char* k, std::string& v, const std::vector<std::string>& allowed) {
        if (const Json* x = find(k)) {
            const std::string s = as_text(*x, at(k));
            G2L_CHECK(std::find(allowed.begin(), allowed.end(), s) != allowed.end(), src_, ": '",
                      at(k), "' must be one of ", join(allowed, true), ", got ", brief(*x));
            v = s;
        }
    }
    void ints(const char* k, std::vector<int>& v) {
        if (const Json* x = find(k)) {
            G2L_CHECK(x->is_array(), src_, ": '", at(k), "' must be an array of integers, got ",
                      brief(*x));
            v.clear();
            for (size_t i = 0; i < x->size(); ++i)
                v.push_back(as_int<int>((*x)[i], at(k) + "[" + std::to_string(i) + "]"));
        }
    }
    void texts(const char* k, std::vector<std::string>& v) {
        if (const Json* x = find(k)) {
            G2L_CHECK(x->is_array(), src_, ": '", at(k), "' must be an array of strings, got ",
                      brief(*x));
            v.clear();
            for (size_t i = 0; i < x->size(); ++i)
                v.push_back(as_text((*x)[i], at(k) + "[" + std::to_string(i) + "]"));
        }
    }
    /// An array of exactly N finite numbers.
    template <size_t N>
    void nums(const char* k, std::array<double, N>& v) {
        if (const Json* x = find(k)) {
            std::vector<double> d = as_nums(*x, at(k), N);
            std::copy(d.begin(), d.end(), v.begin());
        }
    }
    void num3(const char* k, std::array<double, 3>& v) { nums<3>(k, v); }
    /// An array of n finite numbers (any length when n == 0).
    void nums(const char* k, std::vector<double>& v, size_t n = 0) {
        if (const Json* x = find(k)) v = as_nums(*x, at(k), n);
    }
    /// A JSON object kept as text (checked later by its own reader).
    void raw_object(const char* k, std::string& v) {
        if (const Json* x = find(k)) {
            G2L_CHECK(x->is_object(), src_, ": '", at(k), "' must be a JSON object, got ",
                      brief(*x));
            v = x->dump();
        }
    }
    /// A nested object: f(BasicJsonReader&) reads its keys; its unknown keys are refused.
    template <class F>
    void object(const char* k, F&& f) {
        if (const Json* x = find(k)) {
            BasicJsonReader sub(*x, src_, at(k));
            f(sub);
            sub.finish();
        }
    }
    /// An array of objects; f(BasicJsonReader&, T&) fills each element.
    template <class T, class F>
    void list(const char* k, std::vector<T>& v, F&& f) {
        if (const Json* x = find(k)) {
            G2L_CHECK(x->is_array(), src_, ": '", at(k), "' must be an array of objects, got ",
                      brief(*x));
            v.assign(x->size(), T{});
            for (size_t i = 0; i < x->size(); ++i) {
                BasicJsonReader sub((*x)[i], src_, at(k) + "[" + std::to_string(i) + "]");
                f(sub, v[i]);
                sub.finish();
            }
        }
    }
    /// Objects keyed by data, not by schema (BOP's {"0": [...], "1": [...]}): f(key, value,
    /// path) for every member, all of them read.
    template <class F>
    void members(F&& f) {
        for (auto it = j_.begin(); it != j_.end(); ++it) {
            seen_.insert(it.key());
            f(it.key(), it.value(), at(it.key()));
        }
    }
    /// Rejects every key that was not read, naming the known ones.
    void finish() const {
        for (auto it = j_.begin(); it != j_.end(); ++it) {
            if (seen_.count(it.key())) continue;
            G2L_CHECK(false, src_, ": unknown key '", at(it.key()), "' (known: ",
                      join(known_, false), ")");
        }
    }

    // ---- value checks, for values reached through members() or get() ----------------------
    double as_num(const Json& x, const std::string& p) const {
        G2L_CHECK(x.is_number(), src_, ": '", p, "' must be a number, got ", brief(x));
        const double d = x.template get<double>();
        G2L_CHECK(std::isfinite(d), src_, ": '", p, "' must be finite, got ", x.dump());
        return d;
    }
    std::vector<double> as_nums(const Json& x, const std::string& p, size_t n) const {
        const std::string what = n ? "an array of " + std::to_string(n) + " numbers"
                                   : std::string("an array of numbers");
        G2L_CHECK(x.is_array() && (n == 0 || x.size() == n), src_, ": '", p, "' must be ", what,
                  ", got ", brief(x));
        std::vector<double> out(x.size());
        for (size_t i = 0; i < x.size(); ++i)
            out[i] = as_num(x[i], p + "[" + std::to_string(i) + "]");
        return out;
    }
    std::string as_text(const Json& x, const std::string& p) const {
        G2L_CHECK(x.is_string(), src_, ": '", p, "' must be a string, got ", brief(x));
        return x.template get<std::string>();
    }
    template <class T>
    T as_int(const Json& x, const std::string& p) const {
        bool ok = false;
        T v{};
        if (x.is_number_unsigned()) {
            const uint64_t u = x.template get<uint64_t>();
            ok = u <= uint64_t(std::numeric_limits<T>::max());
            if (ok) v = static_cast<T>(u);
        } else if (x.is_number_integer()) {
            const int64_t i = x.template get<int64_t>();
            ok = i < 0 ? std::is_signed_v<T> && i >= int64_t(std::numeric_limits<T>::min())
                       : uint64_t(i) <= uint64_t(std::numeric_limits<T>::max());
            if (ok) v = static_cast<T>(i);
        } else if (x.is_number_float()) {  // 1e3 or 8.0: whole and in range
            const double d = x.template get<double>();
            ok = std::isfinite(d) && d == std::floor(d) &&
                 d >= static_cast<double>(std::numeric_limits<T>::min()) &&
                 d < std::ldexp(1.0, std::numeric_limits<T>::digits);
            if (ok) v = static_cast<T>(d);
        }
        G2L_CHECK(ok, src_, ": '", p, "' must be ",
                  std::is_signed_v<T> ? "an integer" : "a non-negative integer",
                  " in the range of ", sizeof(T) * 8, " bits, got ", brief(x));
        return v;
    }

private:
    const Json* find(const char* k) {
        if (std::find(known_.begin(), known_.end(), k) == known_.end()) known_.push_back(k);
        seen_.insert(k);
        const auto it = j_.find(k);
        return it == j_.end() ? nullptr : &*it;
    }
    /// A value for a message: its text, cut at 80 characters.
    static std::string brief(const Json& x) {
        std::string s = x.dump();
        if (s.size() > 80) s = s.substr(0, 77) + "...";
        return s;
    }
    static std::string join(const std::vector<std::string>& v, bool quote) {
        std::string s;
        for (const auto& x : v) s += (s.empty() ? "" : ", ") + (quote ? "\"" + x + "\"" : x);
        return s;
    }

    const Json& j_;
    std::string src_;
    std::string path_;
    std::set<std::string> seen_;
    std::vector<std::string> known_;
};

/// The reader for nlohmann::json (most files) and for ordered_json (configs keep key order).
using JsonReader = BasicJsonReader<nlohmann::json>;
using OrderedJsonReader = BasicJsonReader<nlohmann::ordered_json>;

}  // namespace g2l
