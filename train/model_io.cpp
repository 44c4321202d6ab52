// SPDX-License-Identifier: MIT
#include "train/model_io.h"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/checkpoint.h"

namespace g2l::train {

using json = nlohmann::json;

nn::G2LConfig model_config(const TrainConfig& cfg, int num_keypoints) {
    nn::G2LConfig mc;
    mc.num_classes = cfg.model.num_classes;
    mc.num_keypoints = num_keypoints;
    mc.evf = cfg.model.evf;
    mc.rre = cfg.model.rre;
    mc.width = cfg.model.width;
    mc.dropout = cfg.model.dropout;
    mc.seed = cfg.seed;
    mc.out_scale_mm = cfg.model.out_scale_mm;
    mc.rot_unit = cfg.model.rot_unit;
    return mc;
}

namespace {

json model_json(const nn::G2LConfig& c) {
    return {{"num_classes", c.num_classes}, {"num_keypoints", c.num_keypoints}, {"evf", c.evf},
            {"rre", c.rre}, {"width", c.width}, {"dropout", c.dropout}, {"seed", c.seed},
            {"rre_dropout", c.rre_dropout}, {"out_scale_mm", c.out_scale_mm},
            {"rot_unit", c.rot_unit}};
}

// The inverse of model_json. Keys added after the first checkpoints default to the behaviour
// those files were trained with (out_scale_mm: 2026-11-23). Throws json::exception.
nn::G2LConfig model_from_json(const json& mj) {
    nn::G2LConfig c;
    c.num_classes = mj.at("num_classes");
    c.num_keypoints = mj.at("num_keypoints");
    c.evf = mj.at("evf");
    c.rre = mj.at("rre");
    c.width = mj.at("width");
    c.dropout = mj.at("dropout");
    c.seed = mj.at("seed");
    c.rre_dropout = mj.at("rre_dropout");
    c.out_scale_mm = mj.value("out_scale_mm", 1.0);
    c.rot_unit = mj.value("rot_unit", std::string("mm"));  // added 2026-12-01
    return c;
}

const json& key(const json& j, const char* k, const std::string& path) {
    G2L_CHECK(j.is_object() && j.contains(k), "checkpoint '", path, "': metadata has no '", k,
              "' (not a g2l training checkpoint?)");
    return j.at(k);
}

// The checkpoint's JSON metadata; throws g2l::Error naming the file when it is not JSON.
json read_meta(const Checkpoint& ck, const std::string& path) {
    try {
        return json::parse(ck.meta_json);
    } catch (const std::exception& e) {
        G2L_CHECK(false, "checkpoint '", path, "': metadata is not JSON: ", e.what());
    }
    return {};
}

}  // namespace

void save_training_checkpoint(const std::string& path, const nn::G2LNet& net,
                              const nn::Adam& adam, const TrainConfig& cfg,
                              const std::map<int, int>& class_of, const KeypointTable& keypoints,
                              const ResumeState& st) {
    std::vector<std::pair<std::string, Tensor>> tensors;
    for (const auto& [name, t] : net.state_dict()) tensors.emplace_back("model." + name, t);
    for (auto& p : adam.state_tensors()) tensors.push_back(p);
    json meta;
    meta["format"] = "g2l-train";
    meta["model"] = model_json(net.config());
    json ids = json::array(), kps = json::array();
    for (const auto& [id, cls] : class_of) ids.push_back({id, cls});
    for (const auto& k : keypoints) {
        json one = json::array();
        for (const auto& p : k) one.push_back({p.x(), p.y(), p.z()});
        kps.push_back(one);
    }
    meta["classes"] = ids;
    meta["keypoints"] = kps;
    meta["sampling"] = {{"crop", cfg.sampling.crop}, {"radius_scale", cfg.sampling.radius_scale},
                        {"points", cfg.sampling.points}, {"seg_points", cfg.sampling.seg_points}};
    meta["resume"] = {{"epoch", st.epoch}, {"pos", st.pos}, {"global_step", st.global_step},
                      {"epoch_batches", st.epoch_batches}, {"epoch_loss", st.epoch_loss},
                      {"best_val", st.best_val}, {"seconds", st.seconds},
                      {"adam_step", adam.step_count()}};
    meta["config"] = json::parse(config_to_json(cfg));
    save_checkpoint(path, tensors, meta.dump());
}

ResumeState load_training_checkpoint(const std::string& path, nn::G2LNet& net, nn::Adam& adam) {
    const Checkpoint ck = load_checkpoint(path);
    const json meta = read_meta(ck, path);
    G2L_CHECK(meta.value("format", "") == "g2l-train", "checkpoint '", path,
              "' is not a g2l training checkpoint (format '", meta.value("format", ""), "')");
    json saved_model;
    try {
        saved_model = model_json(model_from_json(key(meta, "model", path)));
    } catch (const json::exception& e) {
        G2L_CHECK(false, "checkpoint '", path, "': malformed metadata: ", e.what());
    }
    G2L_CHECK(saved_model == model_json(net.config()), "checkpoint '", path,
              "' was trained with model ", meta.at("model").dump(), " but the config builds ",
              model_json(net.config()).dump());
    std::map<std::string, Tensor> model;
    for (const auto& [name, t] : ck.tensors)
        if (name.rfind("model.", 0) == 0) model.emplace(name.substr(6), t);
    try {
        net.load_state_dict(model);
    } catch (const Error& e) {
        G2L_CHECK(false, "checkpoint '", path, "': ", e.what());
    }
    const json& r = key(meta, "resume", path);
    ResumeState st;
    int64_t adam_step = 0;
    try {
        adam_step = r.at("adam_step").get<int64_t>();
        st.epoch = r.at("epoch").get<int>();
        st.pos = r.at("pos").get<int64_t>();
        st.global_step = r.at("global_step").get<int64_t>();
        st.epoch_batches = r.at("epoch_batches").get<int64_t>();
        st.epoch_loss = r.at("epoch_loss").get<double>();
        st.best_val = r.at("best_val").get<double>();
        st.seconds = r.value("seconds", 0.0);  // absent in checkpoints from before 2026-11-23
    } catch (const json::exception& e) {
        G2L_CHECK(false, "checkpoint '", path, "': malformed resume metadata: ", e.what());
    }
    adam.load_state(ck.tensors, adam_step);
    return st;
}

LoadedModel load_model(const std::string& path) {
    const Checkpoint ck = load_checkpoint(path);
    const json meta = read_meta(ck, path);
    const std::string format = meta.value("format", "");
    G2L_CHECK(format == "g2l-train" || format == "g2l-model", "checkpoint '", path,
              "' is not a g2l model checkpoint or export (format '", format, "')");
    LoadedModel m;
    try {
        m.net = std::make_unique<nn::G2LNet>(model_from_json(key(meta, "model", path)));
        for (const auto& p : key(meta, "classes", path)) m.class_of[p.at(0)] = p.at(1);
        for (const auto& k : key(meta, "keypoints", path)) {
            std::vector<Eigen::Vector3f> one;
            for (const auto& p : k) one.emplace_back(p.at(0), p.at(1), p.at(2));
            m.keypoints.push_back(one);
        }
        m.crop = key(meta, "sampling", path).at("crop");
        m.radius_scale = meta.at("sampling").at("radius_scale");
        // Added 2026-12-01; older files fed the whole crop (0 = no sampling).
        m.points = meta.at("sampling").value("points", 0);
        m.seg_points = meta.at("sampling").value("seg_points", 2000);
        m.config_json = meta.contains("config") ? meta.at("config").dump(2) : "{}";
    } catch (const json::exception& e) {
        G2L_CHECK(false, "checkpoint '", path, "': malformed metadata: ", e.what());
    }
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

int64_t export_model(const std::string& checkpoint_path, const std::string& out_path) {
    (void)load_model(checkpoint_path);  // everything an export needs is there and consistent
    const Checkpoint ck = load_checkpoint(checkpoint_path);
    const json meta = read_meta(ck, checkpoint_path);
    json out;
    out["format"] = "g2l-model";
    for (const char* k : {"model", "classes", "keypoints", "sampling", "config"})
        if (meta.contains(k)) out[k] = meta.at(k);
    if (meta.contains("resume")) {
        const json& r = meta.at("resume");
        out["trained"] = {{"epoch", r.value("epoch", 0)}, {"global_step", r.value("global_step", 0)},
                          {"seconds", r.value("seconds", 0.0)}, {"best_val", r.value("best_val", -1.0)},
                          {"source", checkpoint_path}};
    }
    std::vector<std::pair<std::string, Tensor>> tensors;
    for (const auto& [name, t] : ck.tensors)
        if (name.rfind("model.", 0) == 0) tensors.emplace_back(name, t);
    save_checkpoint(out_path, tensors, out.dump());
    std::error_code ec;
    const auto size = std::filesystem::file_size(out_path, ec);
    G2L_CHECK(!ec, "export '", out_path, "': cannot stat the written file: ", ec.message());
    return int64_t(size);
}

void truncate_jsonl(const std::string& path, const std::string& k, int64_t max_value) {
    std::ifstream in(path);
    if (!in) return;
    std::vector<std::string> keep;
    std::string line;
    while (std::getline(in, line)) {
        if (line.empty()) continue;
        try {
            const json j = json::parse(line);
            if (j.contains(k) && j.at(k).get<int64_t>() > max_value) continue;
        } catch (const json::exception&) {
            continue;  // a torn last line from a killed run
        }
        keep.push_back(line);
    }
    in.close();
    const std::string tmp = path + ".tmp";
    {
        std::ofstream out(tmp, std::ios::trunc);
        for (const auto& l : keep) out << l << "\n";
    }
    std::filesystem::rename(tmp, path);
}

}  // namespace g2l::train
