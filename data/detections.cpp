// SPDX-License-Identifier: MIT
#include "data/detections.h"

#include <array>
#include <cmath>
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
        G2L_CHECK(e.has("category_id") != e.has("obj_id"), src, ": '", e.at("category_id"),
                  "': needs exactly one of 'category_id' and 'obj_id'");
        d.obj_id = integer(e.has("category_id") ? "category_id" : "obj_id", 1);
        if (e.has("scene_id")) d.scene_id = integer("scene_id", 0);
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
        e.finish();
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
