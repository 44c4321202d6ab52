// SPDX-License-Identifier: MIT
#include "data/detections.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/error.h"
#include "core/json.h"

namespace g2l::data {

using json = nlohmann::json;

std::vector<Detection> parse_bop_detections(const std::string& text, const std::string& what) {
    const json j = parse_json_strict(text, "detections '" + what + "'");
    G2L_CHECK(j.is_array(), "detections '", what, "': expected a JSON array of detections, got ",
              j.type_name());
    std::vector<Detection> out;
    out.reserve(j.size());
    for (size_t i = 0; i < j.size(); ++i) {
        const json& e = j[i];
        G2L_CHECK(e.is_object(), "detections '", what, "' entry ", i, ": expected an object, got ",
                  e.type_name());
        for (auto it = e.begin(); it != e.end(); ++it) {
            static const char* known[] = {"scene_id", "image_id", "im_id", "category_id",
                                          "obj_id", "bbox", "score", "time", "segmentation",
                                          "peak"};
            bool ok = false;
            for (const char* k : known) ok |= it.key() == k;
            G2L_CHECK(ok, "detections '", what, "' entry ", i, ": unknown key '", it.key(), "'");
        }
        auto integer = [&](const char* k, int lo) {
            const json& v = e.at(k);
            G2L_CHECK(v.is_number_integer() && v.get<int64_t>() >= lo && v.get<int64_t>() < (1 << 30),
                      "detections '", what, "' entry ", i, ": '", k, "' must be an integer >= ",
                      lo, ", got ", v.dump());
            return int(v.get<int64_t>());
        };
        auto number = [&](const json& v, const char* k) {
            G2L_CHECK(v.is_number() && std::isfinite(v.get<double>()), "detections '", what,
                      "' entry ", i, ": '", k, "' must be a finite number, got ", v.dump());
            return v.get<double>();
        };
        Detection d;
        G2L_CHECK(e.contains("category_id") != e.contains("obj_id"), "detections '", what,
                  "' entry ", i, ": needs exactly one of 'category_id' and 'obj_id'");
        d.obj_id = integer(e.contains("category_id") ? "category_id" : "obj_id", 1);
        if (e.contains("scene_id")) d.scene_id = integer("scene_id", 0);
        G2L_CHECK(!(e.contains("image_id") && e.contains("im_id")), "detections '", what,
                  "' entry ", i, ": both 'image_id' and 'im_id'");
        if (e.contains("image_id")) d.image_id = integer("image_id", 0);
        if (e.contains("im_id")) d.image_id = integer("im_id", 0);
        G2L_CHECK(e.contains("bbox"), "detections '", what, "' entry ", i, ": no 'bbox'");
        const json& b = e.at("bbox");
        G2L_CHECK(b.is_array() && b.size() == 4, "detections '", what, "' entry ", i,
                  ": 'bbox' must be [x, y, w, h], got ", b.dump());
        d.x = number(b[0], "bbox");
        d.y = number(b[1], "bbox");
        d.w = number(b[2], "bbox");
        d.h = number(b[3], "bbox");
        G2L_CHECK(d.w >= 0 && d.h >= 0, "detections '", what, "' entry ", i,
                  ": bbox width and height must be >= 0, got ", b.dump());
        if (e.contains("score")) d.score = number(e.at("score"), "score");
        if (e.contains("time")) d.time = number(e.at("time"), "time");
        if (e.contains("peak")) {  // g2l's extension: the heat-map peak pixel [x, y]
            const json& p = e.at("peak");
            G2L_CHECK(p.is_array() && p.size() == 2, "detections '", what, "' entry ", i,
                      ": 'peak' must be [x, y], got ", p.dump());
            d.peak_x = number(p[0], "peak");
            d.peak_y = number(p[1], "peak");
            G2L_CHECK(d.peak_x >= 0 && d.peak_y >= 0, "detections '", what, "' entry ", i,
                      ": 'peak' must be >= 0, got ", p.dump());
        }
        out.push_back(d);
    }
    return out;
}

std::vector<Detection> load_bop_detections(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    G2L_CHECK(f.good(), "detections '", path, "': cannot open the file");
    std::ostringstream ss;
    ss << f.rdbuf();
    G2L_CHECK(!f.bad(), "detections '", path, "': read error");
    return parse_bop_detections(ss.str(), path);
}

}  // namespace g2l::data
