// SPDX-License-Identifier: MIT
#include "data/simple_yaml.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "core/error.h"

namespace g2l::data {

namespace {

std::string trim(const std::string& s) {
    const size_t b = s.find_first_not_of(" \t\r");
    if (b == std::string::npos) return "";
    const size_t e = s.find_last_not_of(" \t\r");
    return s.substr(b, e - b + 1);
}

// Strips a `#` comment (the files hold no strings, so any '#' starts one).
std::string strip_comment(const std::string& s) {
    const size_t p = s.find('#');
    return p == std::string::npos ? s : s.substr(0, p);
}

double parse_number(const std::string& tok, const std::string& file, int line) {
    const std::string t = trim(tok);
    G2L_CHECK(!t.empty(), file, ":", line, ": empty number");
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(t.c_str(), &end);
    G2L_CHECK(end == t.c_str() + t.size() && errno == 0 && std::isfinite(v), file, ":", line, ": '",
              t, "' is not a finite number");
    return v;
}

// Parses the body of a `[a, b, c]` list (without brackets).
std::vector<double> parse_list(const std::string& body, const std::string& file, int line) {
    std::vector<double> out;
    if (trim(body).empty()) return out;
    size_t start = 0;
    while (true) {
        const size_t comma = body.find(',', start);
        out.push_back(parse_number(body.substr(start, comma - start), file, line));
        if (comma == std::string::npos) break;
        start = comma + 1;
    }
    return out;
}

struct Parser {
    const std::string& file;
    std::ifstream in;
    int line_no = 0;

    bool next(std::string* line) {
        if (!std::getline(in, *line)) return false;
        ++line_no;
        *line = strip_comment(*line);
        return true;
    }

    // `key: value` (value may be a list continued on the following lines).
    void parse_field(const std::string& text, YamlRecord* rec) {
        const size_t colon = text.find(':');
        G2L_CHECK(colon != std::string::npos, file, ":", line_no, ": expected 'key: value', got '",
                  text, "'");
        const std::string key = trim(text.substr(0, colon));
        G2L_CHECK(!key.empty() && key.find_first_of(" []{}-") == std::string::npos, file, ":",
                  line_no, ": bad key '", key, "'");
        G2L_CHECK(!rec->fields.count(key), file, ":", line_no, ": duplicated key '", key, "'");
        std::string value = trim(text.substr(colon + 1));
        YamlValue v;
        v.line = line_no;
        G2L_CHECK(!value.empty(), file, ":", line_no, ": key '", key, "' has no value");
        if (value.front() == '[') {
            const int first = line_no;
            std::string more;
            while (value.find(']') == std::string::npos) {
                G2L_CHECK(next(&more), file, ":", first, ": list of key '", key,
                          "' has no closing ']'");
                value += " " + trim(more);
            }
            const size_t close = value.find(']');
            G2L_CHECK(trim(value.substr(close + 1)).empty(), file, ":", line_no,
                      ": unexpected text after ']' in key '", key, "'");
            v.numbers = parse_list(value.substr(1, close - 1), file, first);
            v.is_list = true;
        } else {
            v.numbers = {parse_number(value, file, line_no)};
        }
        rec->fields.emplace(key, std::move(v));
    }
};

}  // namespace

std::map<int, YamlBlock> parse_int_keyed_yaml(const std::string& path) {
    G2L_CHECK(std::filesystem::is_regular_file(path), "YAML file not found: '", path, "'");
    Parser p{path, std::ifstream(path)};
    G2L_CHECK(p.in.good(), "cannot open '", path, "'");
    std::map<int, YamlBlock> blocks;
    YamlBlock* cur = nullptr;
    std::string raw;
    while (p.next(&raw)) {
        if (trim(raw).empty()) continue;
        const bool indented = raw[0] == ' ' || raw[0] == '\t';
        const std::string text = trim(raw);
        // YAML lets a block sequence sit at its parent key's column (gt.yml writes `- cam_R..`
        // at column 0), so a '-' line is a list item at any indentation.
        if (!indented && text[0] != '-') {
            // Top-level `<int>:` with an optional empty `[]` / `{}` value.
            const size_t colon = text.find(':');
            G2L_CHECK(colon != std::string::npos, path, ":", p.line_no,
                      ": expected a top-level '<int>:' key, got '", text, "'");
            const std::string key = trim(text.substr(0, colon));
            const std::string rest = trim(text.substr(colon + 1));
            char* end = nullptr;
            const long id = std::strtol(key.c_str(), &end, 10);
            G2L_CHECK(!key.empty() && end == key.c_str() + key.size() && id >= 0, path, ":",
                      p.line_no, ": top-level key '", key, "' is not a non-negative integer");
            G2L_CHECK(rest.empty() || rest == "[]" || rest == "{}", path, ":", p.line_no,
                      ": unsupported value after key ", key, ": '", rest, "'");
            G2L_CHECK(!blocks.count(static_cast<int>(id)), path, ":", p.line_no,
                      ": duplicated top-level key ", id);
            cur = &blocks[static_cast<int>(id)];
            cur->line = p.line_no;
            cur->is_list = rest == "[]";
            continue;
        }
        G2L_CHECK(cur != nullptr, path, ":", p.line_no,
                  ": item or field before any top-level key: '", text, "'");
        if (text[0] == '-') {
            G2L_CHECK(cur->is_list || cur->records.empty(), path, ":", p.line_no,
                      ": list item '-' inside a map block");
            cur->is_list = true;
            cur->records.emplace_back();
            cur->records.back().line = p.line_no;
            const std::string rest = trim(text.substr(1));
            if (!rest.empty()) p.parse_field(rest, &cur->records.back());
            continue;
        }
        if (cur->records.empty()) {
            G2L_CHECK(!cur->is_list, path, ":", p.line_no, ": field outside a list item: '", text,
                      "'");
            cur->records.emplace_back();
            cur->records.back().line = p.line_no;
        }
        p.parse_field(text, &cur->records.back());
    }
    return blocks;
}

const std::vector<double>& yaml_numbers(const YamlRecord& rec, const std::string& key, size_t n,
                                        const std::string& file) {
    const auto it = rec.fields.find(key);
    G2L_CHECK(it != rec.fields.end(), file, ":", rec.line, ": missing key '", key, "'");
    G2L_CHECK(it->second.numbers.size() == n, file, ":", it->second.line, ": key '", key,
              "' must have ", n, " number(s), got ", it->second.numbers.size());
    return it->second.numbers;
}

}  // namespace g2l::data
