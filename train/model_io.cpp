// SPDX-License-Identifier: MIT
#include "train/model_io.h"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/checkpoint.h"
#include "core/json.h"
#include "core/json_reader.h"
#include "train/run_dir.h"
#include "geometry/model_info.h"

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
    mc.class_heads = cfg.model.class_heads;
    return mc;
}

namespace {

const json& key(const json& j, const char* k, const std::string& path) {
    return nn::metadata_key(j, k, path);
}

json model_json(const nn::G2LConfig& c) { return nn::g2l_config_json(c); }

json objects_json(const std::map<int, nn::ModelObjectInfo>& objects) {
    json out = json::array();
    for (const auto& [id, o] : objects)
        out.push_back({{"obj_id", id}, {"diameter", o.diameter}, {"symmetric", o.symmetric}});
    return out;
}

// The objects' diameters for a checkpoint written before they were stored: from the
// models_info.json of the training config's data sources (synthetic models_root, BOP root).
json objects_from_config(const json& meta, const std::string& path) {
    std::map<int, nn::ModelObjectInfo> found;
    std::vector<std::string> tried;
    if (meta.contains("config") && meta.at("config").contains("data")) {
        const json& d = meta.at("config").at("data");
        for (const char* part : {"train", "val"}) {
            if (!d.contains(part)) continue;
            for (const auto& src : d.at(part)) {
                std::string root = src.value("models_root", src.value("root", std::string()));
                if (root.empty()) continue;
                const std::string info = root + "/models/models_info.json";
                tried.push_back(info);
                if (!std::filesystem::exists(info)) continue;
                for (const auto& [id, mi] : geom::load_models_info_json(info))
                    if (!found.count(id)) found[id] = {mi.diameter, mi.symmetric};
            }
        }
    }
    json out = json::array();
    for (const auto& p : key(meta, "classes", path)) {
        const int id = p.at(0);
        std::string where;
        for (const auto& t : tried) where += (where.empty() ? "" : ", ") + t;
        G2L_CHECK(found.count(id), "export of '", path, "': the checkpoint does not store the "
                  "diameter of object ", id, " and no models_info.json of its config has it (tried: ",
                  where.empty() ? std::string("none") : where, ")");
        out.push_back({{"obj_id", id}, {"diameter", found[id].diameter},
                       {"symmetric", found[id].symmetric}});
    }
    return out;
}
nn::G2LConfig model_from_json(const json& j) { return nn::g2l_config_from_json(j); }


// The checkpoint's JSON metadata; throws g2l::Error naming the file when it is not JSON.
json read_meta(const Checkpoint& ck, const std::string& path) {
    return parse_json_strict(ck.meta_json, "checkpoint '" + path + "': metadata");
}

}  // namespace

void save_training_checkpoint(const std::string& path, const nn::G2LNet& net,
                              const nn::Adam& adam, const TrainConfig& cfg,
                              const std::map<int, int>& class_of, const KeypointTable& keypoints,
                              const ResumeState& st,
                              const std::map<int, nn::ModelObjectInfo>& objects) {
    const std::vector<std::pair<std::string, Tensor>> tensors =
        checkpoint_tensors(net.state_dict(), adam);
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
    if (!objects.empty()) meta["objects"] = objects_json(objects);
    meta["sampling"] = {{"crop", geom::to_string(cfg.sampling.crop)}, {"radius_scale", cfg.sampling.radius_scale},
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
    try {
        net.load_state_dict(model_state_of(ck.tensors));
    } catch (const Error& e) {
        G2L_CHECK(false, "checkpoint '", path, "': ", e.what());
    }
    ResumeState st;
    int64_t adam_step = 0;
    JsonReader r(key(meta, "resume", path), "checkpoint '" + path + "' (metadata)", "resume");
    for (const char* k :
         {"adam_step", "epoch", "pos", "global_step", "epoch_batches", "epoch_loss", "best_val"})
        r.require(k);
    r.integer("adam_step", adam_step);
    r.integer("epoch", st.epoch);
    r.integer("pos", st.pos);
    r.integer("global_step", st.global_step);
    r.integer("epoch_batches", st.epoch_batches);
    r.num("epoch_loss", st.epoch_loss);
    r.num("best_val", st.best_val);
    r.num("seconds", st.seconds);  // absent in checkpoints from before 2026-11-23
    r.finish();
    G2L_CHECK(adam_step >= 0 && st.epoch >= 0 && st.pos >= 0 && st.global_step >= 0 &&
                  st.epoch_batches >= 0,
              "checkpoint '", path, "': negative counters in the resume metadata");
    adam.load_state(ck.tensors, adam_step);
    return st;
}

namespace {

// The metadata of an inference export made from a checkpoint's metadata.
json export_meta(const json& meta, const std::string& checkpoint_path) {
    json out;
    out["format"] = "g2l-model";
    for (const char* k : {"model", "classes", "keypoints", "sampling", "config"})
        if (meta.contains(k)) out[k] = meta.at(k);
    out["objects"] = meta.contains("objects") ? meta.at("objects")
                                              : objects_from_config(meta, checkpoint_path);
    if (meta.contains("resume")) {
        const json& r = meta.at("resume");
        out["trained"] = {{"epoch", r.value("epoch", 0)}, {"global_step", r.value("global_step", 0)},
                          {"seconds", r.value("seconds", 0.0)}, {"best_val", r.value("best_val", -1.0)},
                          {"source", checkpoint_path}};
    }
    return out;
}

int64_t written_size(const std::string& out_path) {
    std::error_code ec;
    const auto size = std::filesystem::file_size(out_path, ec);
    G2L_CHECK(!ec, "export '", out_path, "': cannot stat the written file: ", ec.message());
    return int64_t(size);
}

}  // namespace

int64_t export_model(const std::string& checkpoint_path, const std::string& out_path) {
    (void)nn::load_model(checkpoint_path);  // everything an export needs is there and consistent
    const Checkpoint ck = load_checkpoint(checkpoint_path);
    const json out = export_meta(read_meta(ck, checkpoint_path), checkpoint_path);
    std::vector<std::pair<std::string, Tensor>> tensors;
    for (const auto& [name, t] : ck.tensors)
        if (name.rfind("model.", 0) == 0) tensors.emplace_back(name, t);
    save_checkpoint(out_path, tensors, out.dump());
    return written_size(out_path);
}

int64_t export_average(const std::vector<std::string>& checkpoints, const std::string& out_path) {
    G2L_CHECK(checkpoints.size() >= 2, "average: give at least two checkpoints, got ",
              checkpoints.size());
    const std::string& first = checkpoints.front();
    std::vector<Checkpoint> cks;
    std::vector<json> metas;
    for (const std::string& p : checkpoints) {
        (void)nn::load_model(p);  // each one is a complete, consistent checkpoint
        cks.push_back(load_checkpoint(p));
        metas.push_back(read_meta(cks.back(), p));
        for (const char* k : {"model", "classes", "keypoints", "sampling"})
            G2L_CHECK(metas.back().value(k, json()) == metas.front().value(k, json()), "average: '",
                      p, "' has another '", k, "' than '", first,
                      "' (average checkpoints of one run only)");
    }
    std::vector<std::pair<std::string, Tensor>> tensors;
    const double n = double(cks.size());
    for (const auto& [name, t0] : cks.front().tensors) {
        if (name.rfind("model.", 0) != 0) continue;
        Tensor sum = t0.clone();
        for (size_t i = 1; i < cks.size(); ++i) {
            const auto it = cks[i].tensors.find(name);
            G2L_CHECK(it != cks[i].tensors.end(), "average: '", checkpoints[i], "' has no tensor '",
                      name, "' ('", first, "' has)");
            const Tensor& t = it->second;
            G2L_CHECK(t.shape() == t0.shape() && t.dtype() == t0.dtype(), "average: tensor '", name,
                      "' is ", t.desc(), " in '", checkpoints[i], "' but ", t0.desc(), " in '",
                      first, "'");
            if (t.dtype() == DType::F32) {
                float* a = sum.data<float>();
                const float* b = t.data<float>();
                for (int64_t k = 0; k < t.numel(); ++k) a[k] += b[k];
            } else {
                sum = t.clone();  // integer buffers (e.g. step counters): the last checkpoint's
            }
        }
        if (sum.dtype() == DType::F32) {
            float* a = sum.data<float>();
            for (int64_t k = 0; k < sum.numel(); ++k) a[k] = float(double(a[k]) / n);
        }
        tensors.emplace_back(name, std::move(sum));
    }
    for (size_t i = 1; i < cks.size(); ++i)
        for (const auto& [name, t] : cks[i].tensors)
            G2L_CHECK(name.rfind("model.", 0) != 0 || cks.front().tensors.count(name), "average: '",
                      checkpoints[i], "' has a tensor '", name, "' that '", first, "' has not");
    // The latest checkpoint's metadata, and where the average came from.
    json out = export_meta(metas.back(), checkpoints.back());
    json sources = json::array();
    for (size_t i = 0; i < checkpoints.size(); ++i) {
        const json r = metas[i].value("resume", json::object());
        sources.push_back({{"source", checkpoints[i]}, {"epoch", r.value("epoch", 0)},
                           {"global_step", r.value("global_step", 0)}});
    }
    out["trained"]["averaged"] = sources;
    save_checkpoint(out_path, tensors, out.dump());
    return written_size(out_path);
}

}  // namespace g2l::train
