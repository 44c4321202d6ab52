// SPDX-License-Identifier: MIT
#include "nn/models/g2l_io.h"

#include <cmath>

#include "core/checkpoint.h"
#include "core/json.h"

namespace g2l::nn {

using json = nlohmann::json;

json g2l_config_json(const G2LConfig& c) {
    return {{"num_classes", c.num_classes}, {"num_keypoints", c.num_keypoints}, {"evf", c.evf},
            {"rre", c.rre}, {"width", c.width}, {"dropout", c.dropout}, {"seed", c.seed},
            {"rre_dropout", c.rre_dropout}, {"out_scale_mm", c.out_scale_mm},
            {"rot_unit", c.rot_unit}, {"class_heads", c.class_heads}};
}

G2LConfig g2l_config_from_json(const json& mj) {
    G2LConfig c;
    c.num_classes = mj.at("num_classes");
    c.num_keypoints = mj.at("num_keypoints");
    c.evf = mj.at("evf");
    c.rre = mj.at("rre");
    c.width = mj.at("width");
    c.dropout = mj.at("dropout");
    c.seed = mj.at("seed");
    c.rre_dropout = mj.at("rre_dropout");
    c.out_scale_mm = mj.value("out_scale_mm", 1.0);        // added 2026-11-23
    c.rot_unit = mj.value("rot_unit", std::string("mm"));  // added 2026-12-01
    c.class_heads = mj.value("class_heads", false);         // added 2026-12-02
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
    try {
        m.net = std::make_unique<G2LNet>(g2l_config_from_json(key(meta, "model", path)));
        for (const auto& p : key(meta, "classes", path)) m.class_of[p.at(0)] = p.at(1);
        for (const auto& k : key(meta, "keypoints", path)) {
            std::vector<Eigen::Vector3f> one;
            for (const auto& p : k) one.emplace_back(p.at(0), p.at(1), p.at(2));
            m.keypoints.push_back(one);
        }
        const json& s = key(meta, "sampling", path);
        m.crop = s.at("crop");
        m.radius_scale = s.at("radius_scale");
        // Added 2026-12-01; older files fed the whole crop (0 = no sampling).
        m.points = s.value("points", 0);
        m.seg_points = s.value("seg_points", 2000);
        if (meta.contains("objects"))  // added 2026-12-02
            for (const auto& o : meta.at("objects"))
                m.objects[o.at("obj_id").get<int>()] = {o.at("diameter").get<double>(),
                                                        o.value("symmetric", false)};
        m.config_json = meta.contains("config") ? meta.at("config").dump(2) : "{}";
    } catch (const json::exception& e) {
        G2L_CHECK(false, "checkpoint '", path, "': malformed metadata: ", e.what());
    }
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
    G2L_CHECK(m.crop == "sphere" || m.crop == "slab" || m.crop == "frustum", "checkpoint '", path,
              "': unknown crop '", m.crop, "'");
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
