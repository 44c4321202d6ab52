// SPDX-License-Identifier: MIT
#include "nn/models/g2l_io.h"

#include <cmath>

#include "core/checkpoint.h"
#include "core/json.h"
#include "core/json_reader.h"

namespace g2l::nn {

using json = nlohmann::json;

json g2l_config_json(const G2LConfig& c) {
    return {{"num_classes", c.num_classes}, {"num_keypoints", c.num_keypoints}, {"evf", c.evf},
            {"rre", c.rre}, {"width", c.width}, {"dropout", c.dropout}, {"seed", c.seed},
            {"rre_dropout", c.rre_dropout}, {"out_scale_mm", c.out_scale_mm},
            {"rot_unit", c.rot_unit}, {"class_heads", c.class_heads}};
}

G2LConfig g2l_config_from_json(const json& mj, const std::string& source) {
    JsonReader r(mj, source, "model");
    G2LConfig c;
    for (const char* k : {"num_classes", "num_keypoints", "evf", "rre", "width", "dropout",
                          "seed", "rre_dropout"})
        r.require(k);
    r.integer("num_classes", c.num_classes);
    r.integer("num_keypoints", c.num_keypoints);
    r.boolean("evf", c.evf);
    r.boolean("rre", c.rre);
    r.num("width", c.width);
    r.num("dropout", c.dropout);
    r.integer("seed", c.seed);
    r.num("rre_dropout", c.rre_dropout);
    r.num("out_scale_mm", c.out_scale_mm);  // added 2026-11-23 (1 before)
    r.text("rot_unit", c.rot_unit);         // added 2026-12-01 ("mm" before)
    r.boolean("class_heads", c.class_heads);  // added 2026-12-02 (false before)
    r.finish();
    G2L_CHECK(c.num_classes >= 1 && c.num_classes <= 100000 && c.num_keypoints >= 1 &&
                  c.num_keypoints <= 1000 && c.width > 0 && c.width <= 64 && c.dropout >= 0 &&
                  c.dropout < 1 && c.rre_dropout >= 0 && c.rre_dropout < 1 && c.out_scale_mm > 0,
              source, ": 'model' holds out-of-range values: ", mj.dump());
    return c;
}

const json& metadata_key(const json& j, const char* k, const std::string& path) {
    G2L_CHECK(j.is_object() && j.contains(k), "checkpoint '", path, "': metadata has no '", k,
              "' (not a g2l model checkpoint?)");
    return j.at(k);
}

namespace {
const json& key(const json& j, const char* k, const std::string& path) { return metadata_key(j, k, path); }
}  // namespace

LoadedModel load_model(const std::string& path) {
    const Checkpoint ck = load_checkpoint(path);
    const json meta = parse_json_strict(ck.meta_json, "checkpoint '" + path + "': metadata");
    const std::string format = meta.is_object() ? meta.value("format", "") : "";
    G2L_CHECK(format == "g2l-train" || format == "g2l-model", "checkpoint '", path,
              "' is not a g2l model checkpoint or export (format '", format, "')");
    LoadedModel m;
    m.format = format;
    // The one schema reader (core/json_reader.h): a wrong type or value names the key.
    const std::string src = "checkpoint '" + path + "' (metadata)";
    JsonReader r(meta, src);
    m.net = std::make_unique<G2LNet>(g2l_config_from_json(key(meta, "model", path), src));
    r.ignore("model");
    for (const char* k : {"classes", "keypoints", "sampling"}) (void)key(meta, k, path);
    r.members([&](const std::string& k, const json& v, const std::string& at) {
        if (k == "classes") {  // [[obj_id, class], ...]
            G2L_CHECK(v.is_array(), src, ": 'classes' must be an array of [obj_id, class]");
            for (size_t i = 0; i < v.size(); ++i) {
                const std::string p = at + "[" + std::to_string(i) + "]";
                G2L_CHECK(v[i].is_array() && v[i].size() == 2, src, ": '", p,
                          "' must be [obj_id, class], got ", v[i].dump());
                m.class_of[r.as_int<int>(v[i][0], p + "[0]")] = r.as_int<int>(v[i][1], p + "[1]");
            }
        } else if (k == "keypoints") {  // per class, K points [x, y, z] (mm)
            G2L_CHECK(v.is_array(), src, ": 'keypoints' must be an array of keypoint sets");
            for (size_t c = 0; c < v.size(); ++c) {
                const std::string pc = at + "[" + std::to_string(c) + "]";
                G2L_CHECK(v[c].is_array(), src, ": '", pc, "' must be an array of points");
                std::vector<Eigen::Vector3f> one;
                for (size_t i = 0; i < v[c].size(); ++i) {
                    const std::vector<double> p =
                        r.as_nums(v[c][i], pc + "[" + std::to_string(i) + "]", 3);
                    one.emplace_back(float(p[0]), float(p[1]), float(p[2]));
                }
                m.keypoints.push_back(one);
            }
        } else if (k == "sampling") {
            JsonReader s(v, src, at);
            std::string crop = geom::to_string(m.crop);
            s.text("crop", crop);
            m.crop = geom::parse_crop(crop, "checkpoint '" + path + "': sampling.crop");
            s.num("radius_scale", m.radius_scale);
            // Added 2026-12-01; older files fed the whole crop (0 = no sampling).
            m.points = 0;
            s.integer("points", m.points);
            m.seg_points = 2000;
            s.integer("seg_points", m.seg_points);
            s.require("crop");
            s.require("radius_scale");
            s.finish();
        } else if (k == "objects") {  // added 2026-12-02: [{obj_id, diameter, symmetric}]
            G2L_CHECK(v.is_array(), src, ": 'objects' must be an array of objects");
            for (size_t i = 0; i < v.size(); ++i) {
                JsonReader o(v[i], src, at + "[" + std::to_string(i) + "]");
                int id = 0;
                ModelObjectInfo mo;
                o.require("obj_id");
                o.require("diameter");
                o.integer("obj_id", id);
                o.num("diameter", mo.diameter);
                o.boolean("symmetric", mo.symmetric);
                o.finish();
                m.objects[id] = mo;
            }
        } else if (k == "config") {
            m.config_json = v.dump(2);
        }
        // format (checked above), resume (the trainer's), and keys a later version adds
    });
    if (m.config_json.empty()) m.config_json = "{}";
    G2L_CHECK(!m.class_of.empty(), "checkpoint '", path, "': no classes");
    for (const auto& [id, cls] : m.class_of)
        G2L_CHECK(cls >= 0 && cls < int(m.keypoints.size()) &&
                      cls < m.net->config().num_classes,
                  "checkpoint '", path, "': object ", id, " has class ", cls, " but there are ",
                  m.keypoints.size(), " keypoint sets and ", m.net->config().num_classes,
                  " classes");
    for (const auto& k : m.keypoints)
        G2L_CHECK(int(k.size()) == m.net->config().num_keypoints, "checkpoint '", path, "': a set of ",
                  k.size(), " keypoints where the network predicts ",
                  m.net->config().num_keypoints);
    for (const auto& [id, o] : m.objects)
        G2L_CHECK(std::isfinite(o.diameter) && o.diameter > 0, "checkpoint '", path,
                  "': object ", id, " has diameter ", o.diameter);
    G2L_CHECK(std::isfinite(m.radius_scale) && m.radius_scale > 0 && m.points >= 0 &&
                  m.seg_points >= 1,
              "checkpoint '", path, "': bad sampling settings (radius_scale ", m.radius_scale,
              ", points ", m.points, ", seg_points ", m.seg_points, ")");
    std::map<std::string, Tensor> model;
    for (const auto& [name, t] : ck.tensors)
        if (name.rfind("model.", 0) == 0) model.emplace(name.substr(6), t);
    try {
        m.net->load_state_dict(model);
    } catch (const Error& e) {
        G2L_CHECK(false, "checkpoint '", path, "': ", e.what());
    }
    m.net->eval();
    return m;
}

}  // namespace g2l::nn
