// SPDX-License-Identifier: MIT
#include "data/detections.h"

#include <array>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/error.h"
#include "core/json.h"
#include "core/json_reader.h"

namespace g2l::data {

using json = nlohmann::json;

std::vector<Detection> parse_bop_detections(const std::string& text, const std::string& what) {
    const json j = parse_json_strict(text, "detections '" + what + "'");
    G2L_CHECK(j.is_array(), "detections '", what, "': expected a JSON array of detections, got ",
              j.type_name());
    std::vector<Detection> out;
    out.reserve(j.size());
    const std::string src = "detections '" + what + "'";
    for (size_t i = 0; i < j.size(); ++i) {
        JsonReader e(j[i], src, "[" + std::to_string(i) + "]");
        auto integer = [&](const char* k, int lo) {
            int v = 0;
            e.integer(k, v);
            G2L_CHECK(v >= lo && v < (1 << 30), src, ": '", e.at(k), "' must be an integer >= ",
                      lo, ", got ", v);
            return v;
        };
        Detection d;
        // BOP detection files are COCO-style (category_id); obj_id is accepted too, but not both,
        // so an entry can never disagree with itself.
        G2L_CHECK(e.has("category_id") != e.has("obj_id"), src, ": '", e.at("category_id"),
                  "': needs exactly one of 'category_id' and 'obj_id'");
        d.obj_id = integer(e.has("category_id") ? "category_id" : "obj_id", 1);
        if (e.has("scene_id")) d.scene_id = integer("scene_id", 0);
        // Same for the image: BOP detections say image_id, its GT and results files im_id.
        G2L_CHECK(!(e.has("image_id") && e.has("im_id")), src, ": '", e.at("image_id"),
                  "': both 'image_id' and 'im_id'");
        if (e.has("image_id")) d.image_id = integer("image_id", 0);
        if (e.has("im_id")) d.image_id = integer("im_id", 0);
        e.require("bbox");
        std::array<double, 4> b{};
        e.nums<4>("bbox", b);
        d.x = b[0], d.y = b[1], d.w = b[2], d.h = b[3];
        G2L_CHECK(d.w >= 0 && d.h >= 0, src, ": '", e.at("bbox"),
                  "' width and height must be >= 0, got ", d.w, " x ", d.h);
        e.num("score", d.score);
        e.num("time", d.time);
        if (e.has("peak")) {  // g2l's extension: the heat-map peak pixel [x, y]
            std::array<double, 2> p{};
            e.nums<2>("peak", p);
            d.peak_x = p[0], d.peak_y = p[1];
            G2L_CHECK(d.peak_x >= 0 && d.peak_y >= 0, src, ": '", e.at("peak"),
                      "' must be >= 0, got [", d.peak_x, ", ", d.peak_y, "]");
        }
        e.ignore("segmentation");  // BOP's RLE mask: not used
        // Any other key is an error (typos such as "scroe" must not pass silently).
        e.finish();
        out.push_back(d);
    }
    return out;
}

namespace {

// A whole file's text; `what` ("detections", "results") names it in errors.
std::string read_text(const std::string& path, const char* what) {
    std::ifstream f(path, std::ios::binary);
    G2L_CHECK(f.good(), what, " '", path, "': cannot open the file");
    std::ostringstream ss;
    ss << f.rdbuf();
    G2L_CHECK(!f.bad(), what, " '", path, "': read error");
    return ss.str();
}

}  // namespace

std::vector<Detection> load_bop_detections(const std::string& path) {
    return parse_bop_detections(read_text(path, "detections"), path);
}

namespace {

// The numbers of one CSV field ("1 0 0 0 1 0 0 0 1"), each finite; throws naming the line.
std::vector<double> csv_numbers(const std::string& field, const std::string& what, int line,
                                const char* name) {
    std::vector<double> v;
    const char* p = field.c_str();
    while (true) {
        while (*p == ' ' || *p == '\t' || *p == '\r') ++p;
        if (!*p) break;
        char* end = nullptr;
        const double x = std::strtod(p, &end);
        G2L_CHECK(end != p && std::isfinite(x), "results '", what, "' line ", line, ": ", name,
                  " '", field, "' is not a list of finite numbers");
        v.push_back(x);
        p = end;
    }
    return v;
}

}  // namespace

std::vector<PoseRow> parse_bop_results_csv(const std::string& text, const std::string& what) {
    std::istringstream in(text);
    std::string line;
    std::vector<PoseRow> rows;
    int n = 0;
    while (std::getline(in, line)) {
        ++n;
        // Tolerate CRLF line ends (files written on Windows).
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (n == 1) {
            // The exact BOP Challenge header: a file without it is most likely another
            // format, whose columns would otherwise be misread.
            G2L_CHECK(line == "scene_id,im_id,obj_id,score,R,t,time", "results '", what,
                      "': the first line must be the BOP header 'scene_id,im_id,obj_id,score,R,"
                      "t,time', got '", line, "'");
            continue;
        }
        if (line.empty()) continue;
        std::vector<std::string> f;
        size_t start = 0;
        for (size_t k = 0; k <= line.size(); ++k)
            // A plain split: BOP fields are never quoted (R and t are space-separated).
            if (k == line.size() || line[k] == ',') f.push_back(line.substr(start, k - start)), start = k + 1;
        G2L_CHECK(f.size() == 7, "results '", what, "' line ", n, ": expected 7 comma-separated "
                  "fields (scene_id,im_id,obj_id,score,R,t,time), got ", f.size());
        const char* names[] = {"scene_id", "im_id", "obj_id"};
        int ids[3];
        for (int k = 0; k < 3; ++k) {
            const std::vector<double> v = csv_numbers(f[size_t(k)], what, n, names[k]);
            // Whole numbers only; obj_id starts at 1 as BOP ids do, scene and image ids at 0.
            G2L_CHECK(v.size() == 1 && v[0] == std::floor(v[0]) && v[0] >= (k == 2 ? 1 : 0) &&
                          v[0] < 2e9,
                      "results '", what, "' line ", n, ": ", names[k], " '", f[size_t(k)],
                      "' is not an integer >= ", k == 2 ? 1 : 0);
            ids[k] = int(v[0]);
        }
        PoseRow r;
        r.scene_id = ids[0], r.image_id = ids[1], r.obj_id = ids[2];
        const std::vector<double> score = csv_numbers(f[3], what, n, "score");
        const std::vector<double> R = csv_numbers(f[4], what, n, "R");
        const std::vector<double> t = csv_numbers(f[5], what, n, "t");
        const std::vector<double> time = csv_numbers(f[6], what, n, "time");
        G2L_CHECK(score.size() == 1 && time.size() == 1, "results '", what, "' line ", n,
                  ": score and time must be one number each");
        G2L_CHECK(R.size() == 9 && t.size() == 3, "results '", what, "' line ", n, ": R needs 9 "
                  "numbers and t 3, got ", R.size(), " and ", t.size());
        r.score = score[0], r.time = time[0];
        for (int k = 0; k < 9; ++k) r.R[size_t(k)] = R[size_t(k)];
        for (int k = 0; k < 3; ++k) r.t[size_t(k)] = t[size_t(k)];
        rows.push_back(r);
    }
    G2L_CHECK(n >= 1, "results '", what, "' is empty (no BOP header line)");
    return rows;
}

std::vector<PoseRow> load_bop_results_csv(const std::string& path) {
    return parse_bop_results_csv(read_text(path, "results"), path);
}

}  // namespace g2l::data
