// SPDX-License-Identifier: MIT
// The writing half of a config's one key list: a visitor (`visit_config(IO&, Config&)`)
// calls the same methods on a strict reader (core/json_reader.h, OrderedJsonReader: parse)
// or on this writer (print every key, defaults included, in visiting order). Each config
// then lists its keys once (train/config.cpp, train/detector_config.cpp).
#pragma once

#include <array>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/error.h"

namespace g2l {

/// Writes every visited field into a JSON object, in visiting order.
class JsonWriter {
public:
    using json = nlohmann::ordered_json;
    explicit JsonWriter(json& j) : j_(j) {}
    void require(const char*) const {}
    void num(const char* k, double v) { j_[k] = v; }
    template <class T>
    void integer(const char* k, T v) { j_[k] = v; }
    void boolean(const char* k, bool v) { j_[k] = v; }
    void text(const char* k, const std::string& v) { j_[k] = v; }
    void choice(const char* k, const std::string& v, const std::vector<std::string>&) { j_[k] = v; }
    void ints(const char* k, const std::vector<int>& v) { j_[k] = v; }
    void texts(const char* k, const std::vector<std::string>& v) { j_[k] = v; }
    void num3(const char* k, const std::array<double, 3>& v) { j_[k] = v; }
    template <size_t N>
    void nums(const char* k, const std::array<double, N>& v) { j_[k] = v; }
    void raw_object(const char* k, const std::string& v) {
        json x;
        try {
            x = json::parse(v);
        } catch (const json::exception& e) {
            G2L_CHECK(false, "config_to_json: '", k, "' holds invalid JSON text: ", e.what());
        }
        j_[k] = std::move(x);
    }
    template <class F>
    void object(const char* k, F&& f) {
        json sub = json::object();
        JsonWriter w(sub);
        f(w);
        j_[k] = std::move(sub);
    }
    template <class T, class F>
    void list(const char* k, std::vector<T>& v, F&& f) {
        json arr = json::array();
        for (T& e : v) {
            json sub = json::object();
            JsonWriter w(sub);
            f(w, e);
            arr.push_back(std::move(sub));
        }
        j_[k] = std::move(arr);
    }

private:
    json& j_;
};

}  // namespace g2l
