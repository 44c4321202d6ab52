// SPDX-License-Identifier: MIT
#include "core/json.h"

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <vector>

#include "core/error.h"

namespace g2l {

namespace {

template <class J>
J parse_strict(const std::string& text, const std::string& source) {
    // One set of keys per open object (a stack: objects nest); the path names where we are.
    std::vector<std::set<std::string>> keys;
    std::vector<std::string> path;
    std::string duplicate;
    // nlohmann keeps the last value of a repeated key without a word; a config with a key given
    // twice is almost always an editing mistake, so the parser callback records duplicates.
    const typename J::parser_callback_t cb = [&](int /*depth*/, typename J::parse_event_t ev,
                                                 J& parsed) {
        using E = typename J::parse_event_t;
        if (ev == E::object_start) {
            keys.emplace_back();
        } else if (ev == E::object_end) {
            if (!keys.empty()) keys.pop_back();
        } else if (ev == E::key && !keys.empty()) {
            const std::string k = parsed.template get<std::string>();
            // path[d] is the current key at object depth d (arrays add no level): "a.b.c" paths.
            path.resize(keys.size());
            path.back() = k;
            // Only the first duplicate is kept; it is reported after parsing, so syntax errors win.
            if (!keys.back().insert(k).second && duplicate.empty()) {
                for (size_t i = 0; i < path.size(); ++i) duplicate += (i ? "." : "") + path[i];
            }
        }
        return true;
    };
    J j;
    try {
        // Strict JSON: a comment is a syntax error here, not skipped.
        j = J::parse(text, cb, /*allow_exceptions=*/true, /*ignore_comments=*/false);
    } catch (const nlohmann::json::parse_error& e) {
        std::string what = e.what();
        // nlohmann's message starts "[json.exception.parse_error.101] parse error at line 1,
        // column 5: ..."; keep its useful part.
        const auto p = what.find("parse error");
        if (p != std::string::npos) what = what.substr(p);
        G2L_CHECK(false, source, ": invalid JSON at byte ", e.byte, ": ", what);
    } catch (const nlohmann::json::exception& e) {
        G2L_CHECK(false, source, ": invalid JSON: ", e.what());
    }
    G2L_CHECK(duplicate.empty(), source, ": duplicate key '", duplicate,
              "' (each key may appear once per object)");
    return j;
}

}  // namespace

nlohmann::json parse_json_strict(const std::string& text, const std::string& source) {
    return parse_strict<nlohmann::json>(text, source);
}

nlohmann::ordered_json parse_json_strict_ordered(const std::string& text, const std::string& source) {
    return parse_strict<nlohmann::ordered_json>(text, source);
}

nlohmann::json parse_json_file(const std::string& path) {
    std::error_code ec;
    G2L_CHECK(std::filesystem::exists(path, ec), "'", path, "': no such file");
    G2L_CHECK(std::filesystem::is_regular_file(path, ec), "'", path, "': not a regular file");
    std::ifstream f(path, std::ios::binary);
    G2L_CHECK(f.good(), "'", path, "': cannot open the file");
    std::ostringstream ss;
    ss << f.rdbuf();
    G2L_CHECK(!f.bad(), "'", path, "': read error");
    return parse_json_strict(ss.str(), "'" + path + "'");
}

}  // namespace g2l
