// SPDX-License-Identifier: MIT
// TrainConfig <-> JSON. One visitor (visit_config) lists every key once; a strict Reader, a
// Writer and the --set machinery are driven by it, so parse and print cannot drift apart.
#include "train/config.h"
#include "core/json.h"
#include "core/json_reader.h"
#include "core/json_writer.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "core/dtype.h"
#include "core/error.h"

namespace g2l::train {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;
using Choices = std::vector<std::string>;

std::string join_key(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
}

std::string list_str(const Choices& v, bool quote) {
    std::string s;
    for (const auto& x : v) s += (s.empty() ? "" : ", ") + (quote ? "\"" + x + "\"" : x);
    return s;
}

/// The strict reader is the one every JSON file uses (core/json_reader.h).
using Reader = OrderedJsonReader;

/// Writes every visited field (core/json_writer.h).
using Writer = JsonWriter;

const Choices kCrops{"sphere", "frustum", "slab"};
const Choices kKeypoints{"bbx8", "fps4", "fps8", "fps12"};
const Choices kTLosses{"mse", "smooth_l1"};
const Choices kRotUnits{"kp_rms", "mm"};
const Choices kRotCentres{"gt", "pred"};
const Choices kSchedules{"step", "official", "constant"};

template <class IO>
void visit_source(IO& io, SourceConfig& s) {
    io.require("type");
    std::string type = source_kind(s.type).name;
    io.choice("type", type, source_type_names());
    s.type = source_type_named(type).value_or(s.type);  // choice() refused other names
    if (source_kind(s.type).frames) {
        io.text("root", s.root);
        io.text("split", s.split);
        io.texts("scenes", s.scenes);
        io.ints("objects", s.objects);
        io.boolean("models_eval", s.models_eval);
        io.num("min_visib_fract", s.min_visib_fract);
        io.integer("max_frames", s.max_frames);
    } else {
        io.text("models_root", s.models_root);
        io.ints("objects", s.objects);
        io.integer("frames", s.frames);
        io.raw_object("scene", s.scene);
    }
}

/// Every key of the config, once. IO is Reader (parse) or Writer (print).
template <class IO>
void visit_config(IO& io, TrainConfig& c) {
    io.text("name", c.name);
    io.integer("seed", c.seed);
    io.integer("threads", c.threads);
    io.text("device", c.device);
    io.text("run_dir", c.run_dir);
    io.object("data", [&](IO& d) {
        d.ints("object_ids", c.data.object_ids);
        d.list("train", c.data.train, [](IO& s, SourceConfig& e) { visit_source(s, e); });
        d.list("val", c.data.val, [](IO& s, SourceConfig& e) { visit_source(s, e); });
    });
    io.object("sampling", [&](IO& s) {
        SamplingConfig& p = c.sampling;
        std::string crop = geom::to_string(p.crop);
        s.choice("crop", crop, kCrops);
        p.crop = geom::parse_crop(crop, "sampling.crop");  // choice() refused other names
        s.integer("points", p.points);
        s.integer("seg_points", p.seg_points);
        s.num("radius_scale", p.radius_scale);
        s.num("center_jitter_mm", p.center_jitter_mm);
        s.num("box_jitter_frac", p.box_jitter_frac);
        s.num("label_threshold_mm", p.label_threshold_mm);
        s.num("surface_spacing_mm", p.surface_spacing_mm);
        s.integer("min_points", p.min_points);
        s.num("min_visib_fract", p.min_visib_fract);
    });
    io.object("augment", [&](IO& a) {
        a.boolean("enabled", c.augment.enabled);
        a.num3("shift_mm", c.augment.shift_mm);
        a.num("rot_deg", c.augment.rot_deg);
        a.num("point_noise_mm", c.augment.point_noise_mm);
    });
    io.object("model", [&](IO& m) {
        m.integer("num_classes", c.model.num_classes);
        m.choice("keypoints", c.model.keypoints, kKeypoints);
        m.boolean("evf", c.model.evf);
        m.boolean("rre", c.model.rre);
        m.num("width", c.model.width);
        m.num("dropout", c.model.dropout);
        m.num("out_scale_mm", c.model.out_scale_mm);
        m.choice("rot_unit", c.model.rot_unit, kRotUnits);
        m.boolean("class_heads", c.model.class_heads);
        m.text("init", c.model.init);
    });
    io.object("loss", [&](IO& l) {
        l.num("seg", c.loss.seg);
        l.num("t", c.loss.t);
        l.num("vec", c.loss.vec);
        l.num("kp", c.loss.kp);
        l.num("res", c.loss.res);
        l.choice("t_loss", c.loss.t_loss, kTLosses);
        l.boolean("symmetric_targets", c.loss.symmetric_targets);
        l.choice("rot_centre", c.loss.rot_centre, kRotCentres);
        l.num("rot_centre_noise_mm", c.loss.rot_centre_noise_mm);
        l.integer("rot_gt_points_epochs", c.loss.rot_gt_points_epochs);
        l.integer("rot_only_epochs", c.loss.rot_only_epochs);
    });
    io.object("optim", [&](IO& o) {
        OptimConfig& p = c.optim;
        o.num("lr", p.lr);
        o.num("beta1", p.beta1);
        o.num("beta2", p.beta2);
        o.num("eps", p.eps);
        o.num("weight_decay", p.weight_decay);
        o.object("lr_mult", [&](IO& m) {
            m.num("seg", p.lr_mult.seg);
            m.num("tnet", p.lr_mult.tnet);
            m.num("evf", p.lr_mult.evf);
            m.num("rot", p.lr_mult.rot);
            m.num("rre", p.lr_mult.rre);
        });
    });
    io.object("schedule", [&](IO& s) {
        s.choice("kind", c.schedule.kind, kSchedules);
        s.integer("step_epochs", c.schedule.step_epochs);
        s.num("gamma", c.schedule.gamma);
    });
    io.object("train", [&](IO& t) {
        LoopConfig& p = c.train;
        t.integer("epochs", p.epochs);
        t.integer("batch", p.batch);
        t.integer("samples_per_epoch", p.samples_per_epoch);
        t.integer("checkpoint_every", p.checkpoint_every);
        t.integer("val_every", p.val_every);
        t.integer("max_val_samples", p.max_val_samples);
        t.num("time_limit_min", p.time_limit_min);
        t.boolean("time_schedule", p.time_schedule);
        t.integer("log_every", p.log_every);
        t.boolean("prefetch", p.prefetch);
    });
}

json parse_json(const std::string& text, const std::string& source) {
    return parse_json_strict_ordered(text, source);
}

TrainConfig read_config(const json& j, const std::string& source) {
    G2L_CHECK(j.is_object(), source, ": the config must be a JSON object, got ", j.type_name());
    TrainConfig c;
    Reader r(j, source);
    visit_config(r, c);
    r.finish();
    return c;
}

json write_config(const TrainConfig& cfg) {
    TrainConfig c = cfg;
    json j = json::object();
    Writer w(j);
    visit_config(w, c);
    return j;
}

bool all_digits(const std::string& s) {
    return !s.empty() &&
           std::all_of(s.begin(), s.end(), [](char ch) { return ch >= '0' && ch <= '9'; });
}

/// Applies one "a.b.c=value" to the full JSON of a config. Inside a source's "scene" object new
/// keys may be created (the scene parser checks them); everywhere else the path must exist.
void apply_set(json& root, const std::string& set, const std::string& source) {
    const std::string where = cat(source, ": --set '", set, "'");
    const size_t eq = set.find('=');
    G2L_CHECK(eq != std::string::npos && eq > 0, where, ": expected key.path=value");
    const std::string key = set.substr(0, eq), value_text = set.substr(eq + 1);
    std::vector<std::string> parts;
    std::stringstream ss(key);
    for (std::string p; std::getline(ss, p, '.');) parts.push_back(p);
    G2L_CHECK(!parts.empty() && key.back() != '.' &&
                  std::none_of(parts.begin(), parts.end(), [](const auto& p) { return p.empty(); }),
              where, ": empty component in key path '", key, "'");
    json value;
    try {
        value = json::parse(value_text);
    } catch (const json::exception&) {
        value = value_text;  // not JSON: a plain string
    }
    json* cur = &root;
    std::string path;
    bool in_scene = false;
    for (size_t i = 0; i < parts.size(); ++i) {
        const std::string& p = parts[i];
        if (cur->is_array()) {
            G2L_CHECK(all_digits(p) && p.size() < 10 && std::stoul(p) < cur->size(), where,
                      ": '", path, "' is a list of ", cur->size(), " element(s), '", p,
                      "' is not a valid index");
            cur = &(*cur)[std::stoul(p)];
            path += "." + p;
            continue;
        }
        if (!cur->is_object()) {
            G2L_CHECK(false, where, ": '", path, "' is a ", cur->type_name(),
                      ", it has no key '", p, "'");
        }
        const std::string next = join_key(path, p);
        if (!cur->contains(p)) {
            if (in_scene) {
                (*cur)[p] = i + 1 < parts.size() ? json::object() : json();
            } else {
                Choices known;
                for (auto it = cur->begin(); it != cur->end(); ++it) known.push_back(it.key());
                G2L_CHECK(false, where, ": unknown key '", next, "' (known: ",
                          list_str(known, false), ")");
            }
        }
        in_scene = in_scene || (p == "scene" && path.rfind("data.", 0) == 0);
        cur = &(*cur)[p];
        path = next;
    }
    *cur = std::move(value);
}

std::string stem_of(const std::string& source) {
    const std::string s = fs::path(source).stem().string();
    return s.empty() ? std::string("g2l") : s;
}

/// Fills name/run_dir defaults and resolves the dataset paths.
void finalize(TrainConfig& c, const std::string& source, const std::string& base_dir) {
    if (c.name.empty()) c.name = stem_of(source);
    if (c.run_dir.empty()) c.run_dir = "runs/" + c.name;
    auto resolve = [&](std::vector<SourceConfig>& list, const char* which) {
        for (size_t i = 0; i < list.size(); ++i) {
            SourceConfig& s = list[i];
            const SourceKind& kind = source_kind(s.type);
            std::string& p = kind.frames ? s.root : s.models_root;
            const char* key = kind.frames ? "root" : "models_root";
            G2L_CHECK(!p.empty(), source, ": 'data.", which, "[", i, "].", key,
                      "' must be set for a \"", kind.name, "\" source");
            try {
                p = resolve_config_path(p, base_dir);
            } catch (const Error& e) {
                G2L_CHECK(false, source, ": 'data.", which, "[", i, "].", key, "': ", e.what());
            }
        }
    };
    resolve(c.data.train, "train");
    resolve(c.data.val, "val");
    if (!c.model.init.empty()) {
        try {
            c.model.init = resolve_config_path(c.model.init, base_dir);
        } catch (const Error& e) {
            G2L_CHECK(false, source, ": 'model.init': ", e.what());
        }
    }
}

void check_sources(const TrainConfig& c, const std::vector<SourceConfig>& list,
                   const char* which, const std::string& where) {
    for (size_t i = 0; i < list.size(); ++i) {
        const SourceConfig& s = list[i];
        const std::string p = cat("data.", which, "[", i, "]");
        for (size_t k = 0; k < s.objects.size(); ++k) {
            const int id = s.objects[k];
            G2L_CHECK(std::count(c.data.object_ids.begin(), c.data.object_ids.end(), id) == 1,
                      where, ": '", p, ".objects[", k, "]' = ", id,
                      " is not in data.object_ids (every object needs a class)");
        }
        const SourceKind& kind = source_kind(s.type);
        if (kind.frames) {
            G2L_CHECK(!s.root.empty(), where, ": '", p, ".root' must be set");
            G2L_CHECK(s.type != SourceType::linemod_preprocessed || (s.scenes.empty() && !s.models_eval),
                      where, ": '", p, "': a linemod_preprocessed source reads ", kind.keys,
                      " (its folders are its objects: set '", p, ".objects'), not scenes or models_eval");
            G2L_CHECK(!s.split.empty(), where, ": '", p, ".split' must not be empty");
            G2L_CHECK(s.min_visib_fract >= 0 && s.min_visib_fract <= 1, where, ": '", p,
                      ".min_visib_fract' must be in [0, 1], got ", s.min_visib_fract);
            G2L_CHECK(s.max_frames >= 0, where, ": '", p, ".max_frames' must be >= 0, got ",
                      s.max_frames);
        } else {
            G2L_CHECK(!s.models_root.empty(), where, ": '", p, ".models_root' must be set");
            G2L_CHECK(s.frames > 0, where, ": '", p, ".frames' must be > 0, got ", s.frames);
            const data::SceneConfig sc = source_scene(s, where, p + ".scene");
            const std::vector<int>& allowed = source_objects(c, s);
            for (size_t k = 0; k < sc.target_obj_ids.size(); ++k) {
                const int id = sc.target_obj_ids[k];
                G2L_CHECK(std::count(allowed.begin(), allowed.end(), id) > 0, where, ": '", p,
                          ".scene.target_obj_ids[", k, "]' = ", id, " is not among the ",
                          s.objects.empty() ? "data.object_ids" : "source's objects");
            }
        }
    }
}

bool finite_in(double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; }

}  // namespace

std::string shared_data_root(const std::string& base_dir) {
    if (const char* env = std::getenv("G2L_SHARED_DATA"); env && *env)
        return fs::absolute(env).lexically_normal().string();
    std::error_code ec;
    const fs::path base = fs::absolute(base_dir.empty() ? fs::current_path() : fs::path(base_dir));
    for (const fs::path& start : {base, fs::current_path()}) {
        for (fs::path a = start.lexically_normal();; a = a.parent_path()) {
            if (fs::is_directory(a / "shared" / "data", ec))
                return (a / "shared" / "data").lexically_normal().string();
            if (a == a.parent_path() || a.empty()) break;
        }
    }
    return (base / ".." / ".." / "shared" / "data").lexically_normal().string();
}

std::string resolve_config_path(const std::string& value, const std::string& base_dir) {
    G2L_CHECK(!value.empty(), "empty path");
    static const std::string kShared = "${G2L_SHARED}";
    fs::path p;
    if (value.rfind(kShared, 0) == 0) {
        std::string rest = value.substr(kShared.size());
        G2L_CHECK(rest.empty() || rest[0] == '/', "'", value, "': ${G2L_SHARED} must be followed",
                  " by '/' or nothing");
        while (!rest.empty() && rest[0] == '/') rest.erase(0, 1);
        p = fs::path(shared_data_root(base_dir)) / rest;
    } else {
        G2L_CHECK(value.find("${") == std::string::npos, "'", value,
                  "': the only variable allowed in a path is ${G2L_SHARED} (as its prefix)");
        p = value;
        if (p.is_relative()) {
            std::error_code ec;
            if (!fs::exists(p, ec) && !base_dir.empty()) p = fs::path(base_dir) / p;
        }
    }
    std::string out = fs::absolute(p).lexically_normal().string();
    while (out.size() > 1 && out.back() == '/') out.pop_back();
    return out;
}

data::SceneConfig source_scene(const SourceConfig& src, const std::string& where,
                               const std::string& key_path) {
    G2L_CHECK(src.type == SourceType::synthetic, where, ": not a synthetic source (type \"",
              source_kind(src.type).name, "\")");
    return data::parse_scene_config(src.scene, where, key_path);
}

namespace {

// The sampling and augmentation keys (the crop and what it feeds the networks).
void check_sampling(const TrainConfig& c, const std::string& where) {
    const SamplingConfig& s = c.sampling;
    G2L_CHECK(s.seg_points > 0, where, ": 'sampling.seg_points' must be > 0, got ",
              s.seg_points);
    G2L_CHECK(s.points >= s.seg_points, where, ": 'sampling.points' = ", s.points,
              " must be >= 'sampling.seg_points' = ", s.seg_points);
    G2L_CHECK(s.radius_scale > 0 && std::isfinite(s.radius_scale), where,
              ": 'sampling.radius_scale' must be > 0, got ", s.radius_scale);
    G2L_CHECK(finite_in(s.center_jitter_mm, 0, 1e6), where,
              ": 'sampling.center_jitter_mm' must be >= 0, got ", s.center_jitter_mm);
    G2L_CHECK(finite_in(s.box_jitter_frac, 0, 0.5), where,
              ": 'sampling.box_jitter_frac' must be in [0, 0.5], got ", s.box_jitter_frac);
    G2L_CHECK(s.label_threshold_mm > 0 && std::isfinite(s.label_threshold_mm), where,
              ": 'sampling.label_threshold_mm' must be > 0, got ", s.label_threshold_mm);
    G2L_CHECK(s.surface_spacing_mm > 0 && std::isfinite(s.surface_spacing_mm), where,
              ": 'sampling.surface_spacing_mm' must be > 0, got ", s.surface_spacing_mm);
    G2L_CHECK(s.min_points > 0, where, ": 'sampling.min_points' must be > 0, got ",
              s.min_points);
    G2L_CHECK(finite_in(s.min_visib_fract, 0, 1), where,
              ": 'sampling.min_visib_fract' must be in [0, 1], got ", s.min_visib_fract);

    const AugmentConfig& a = c.augment;
    for (int k = 0; k < 3; ++k)
        G2L_CHECK(finite_in(a.shift_mm[k], 0, 1e6), where, ": 'augment.shift_mm[", k,
                  "]' must be >= 0, got ", a.shift_mm[k]);
    G2L_CHECK(finite_in(a.rot_deg, 0, 180), where, ": 'augment.rot_deg' must be in [0, 180], got ",
              a.rot_deg);
    G2L_CHECK(finite_in(a.point_noise_mm, 0, 1e6), where,
              ": 'augment.point_noise_mm' must be >= 0, got ", a.point_noise_mm);
}

// The model and loss keys.
void check_model_and_losses(const TrainConfig& c, const std::string& where) {
    const ModelConfig& m = c.model;
    G2L_CHECK(std::find(kKeypoints.begin(), kKeypoints.end(), m.keypoints) != kKeypoints.end(),
              where, ": 'model.keypoints' must be one of ", list_str(kKeypoints, true),
              ", got \"", m.keypoints, "\"");
    G2L_CHECK(m.width > 0 && std::isfinite(m.width), where, ": 'model.width' must be > 0, got ",
              m.width);
    G2L_CHECK(std::isfinite(m.dropout) && m.dropout >= 0 && m.dropout < 1, where,
              ": 'model.dropout' must be in [0, 1), got ", m.dropout);
    G2L_CHECK(std::isfinite(m.out_scale_mm) && m.out_scale_mm > 0, where,
              ": 'model.out_scale_mm' must be finite and > 0, got ", m.out_scale_mm);

    const LossConfig& l = c.loss;
    const std::pair<const char*, double> weights[] = {
        {"seg", l.seg}, {"t", l.t}, {"vec", l.vec}, {"kp", l.kp}, {"res", l.res}};
    double total = 0;
    for (const auto& [k, w] : weights) {
        G2L_CHECK(finite_in(w, 0, 1e12), where, ": 'loss.", k, "' must be >= 0, got ", w);
        total += w;
    }
    G2L_CHECK(total > 0, where, ": every loss weight is 0 (nothing to train)");
    G2L_CHECK(l.t_loss == "mse" || l.t_loss == "smooth_l1", where,
              ": 'loss.t_loss' must be one of ", list_str(kTLosses, true), ", got \"", l.t_loss,
              "\"");
}

// The optimizer, schedule and loop keys.
void check_optimization(const TrainConfig& c, const std::string& where) {
    const OptimConfig& o = c.optim;
    G2L_CHECK(o.lr > 0 && std::isfinite(o.lr), where, ": 'optim.lr' must be > 0, got ", o.lr);
    G2L_CHECK(finite_in(o.beta1, 0, 1) && o.beta1 < 1, where,
              ": 'optim.beta1' must be in [0, 1), got ", o.beta1);
    G2L_CHECK(finite_in(o.beta2, 0, 1) && o.beta2 < 1, where,
              ": 'optim.beta2' must be in [0, 1), got ", o.beta2);
    G2L_CHECK(o.eps > 0 && std::isfinite(o.eps), where, ": 'optim.eps' must be > 0, got ", o.eps);
    G2L_CHECK(finite_in(o.weight_decay, 0, 1e12), where,
              ": 'optim.weight_decay' must be >= 0, got ", o.weight_decay);
    const std::pair<const char*, double> mults[] = {{"seg", o.lr_mult.seg},
                                                    {"tnet", o.lr_mult.tnet},
                                                    {"evf", o.lr_mult.evf},
                                                    {"rot", o.lr_mult.rot},
                                                    {"rre", o.lr_mult.rre}};
    for (const auto& [k, v] : mults)
        G2L_CHECK(finite_in(v, 0, 1e12), where, ": 'optim.lr_mult.", k, "' must be >= 0, got ",
                  v);

    const ScheduleConfig& sc = c.schedule;
    G2L_CHECK(std::find(kSchedules.begin(), kSchedules.end(), sc.kind) != kSchedules.end(),
              where, ": 'schedule.kind' must be one of ", list_str(kSchedules, true), ", got \"",
              sc.kind, "\"");
    G2L_CHECK(sc.step_epochs > 0, where, ": 'schedule.step_epochs' must be > 0, got ",
              sc.step_epochs);
    G2L_CHECK(sc.gamma > 0 && sc.gamma <= 1, where, ": 'schedule.gamma' must be in (0, 1], got ",
              sc.gamma);

    const LoopConfig& t = c.train;
    G2L_CHECK(t.epochs > 0, where, ": 'train.epochs' must be > 0, got ", t.epochs);
    G2L_CHECK(t.batch > 0, where, ": 'train.batch' must be > 0, got ", t.batch);
    G2L_CHECK(t.samples_per_epoch >= 0, where,
              ": 'train.samples_per_epoch' must be >= 0 (0 = all), got ", t.samples_per_epoch);
    G2L_CHECK(t.checkpoint_every >= 0, where, ": 'train.checkpoint_every' must be >= 0, got ",
              t.checkpoint_every);
    G2L_CHECK(t.val_every >= 0, where, ": 'train.val_every' must be >= 0, got ", t.val_every);
    G2L_CHECK(t.max_val_samples >= 0, where, ": 'train.max_val_samples' must be >= 0, got ",
              t.max_val_samples);
    G2L_CHECK(finite_in(t.time_limit_min, 0, 1e9), where,
              ": 'train.time_limit_min' must be >= 0 (0 = none), got ", t.time_limit_min);
    G2L_CHECK(std::isfinite(c.loss.rot_centre_noise_mm) && c.loss.rot_centre_noise_mm >= 0, where,
              ": 'loss.rot_centre_noise_mm' must be >= 0, got ", c.loss.rot_centre_noise_mm);
    G2L_CHECK(c.loss.rot_gt_points_epochs >= 0, where,
              ": 'loss.rot_gt_points_epochs' must be >= 0, got ", c.loss.rot_gt_points_epochs);
    G2L_CHECK(c.loss.rot_only_epochs >= 0 && c.loss.rot_only_epochs < c.train.epochs, where,
              ": 'loss.rot_only_epochs' must be in [0, train.epochs), got ", c.loss.rot_only_epochs);
    G2L_CHECK(t.log_every > 0, where, ": 'train.log_every' must be > 0, got ", t.log_every);
}

}  // namespace

void validate(const TrainConfig& c, const std::string& where) {
    try {
        parse_device(c.device);
    } catch (const Error& e) {
        G2L_CHECK(false, where, ": 'device' must be \"cpu\", \"cuda\" or \"cuda:N\", got \"",
                  c.device, "\" (", e.what(), ")");
    }
    G2L_CHECK(c.threads >= 0, where, ": 'threads' must be >= 0 (0 = all), got ", c.threads);
    G2L_CHECK(!c.name.empty(), where, ": 'name' must not be empty");
    G2L_CHECK(!c.run_dir.empty(), where, ": 'run_dir' must not be empty");

    const std::vector<int>& ids = c.data.object_ids;
    G2L_CHECK(!ids.empty(), where, ": 'data.object_ids' must list at least one object");
    for (size_t i = 0; i < ids.size(); ++i) {
        G2L_CHECK(ids[i] > 0, where, ": 'data.object_ids[", i, "]' must be > 0, got ", ids[i]);
        G2L_CHECK(std::count(ids.begin(), ids.end(), ids[i]) == 1, where,
                  ": 'data.object_ids' lists object ", ids[i], " twice");
    }
    G2L_CHECK(c.model.num_classes >= int64_t(ids.size()), where, ": 'model.num_classes' = ",
              c.model.num_classes, " is smaller than the ", ids.size(),
              " objects of data.object_ids");
    G2L_CHECK(!c.data.train.empty(), where, ": 'data.train' must list at least one source");
    check_sources(c, c.data.train, "train", where);
    check_sources(c, c.data.val, "val", where);
    check_sampling(c, where);
    check_model_and_losses(c, where);
    check_optimization(c, where);
}

std::string apply_sets_to_json(const std::string& json_text, const std::vector<std::string>& sets,
                               const std::string& source_name) {
    json full = parse_json(json_text, source_name);
    for (const std::string& s : sets) apply_set(full, s, source_name);
    return full.dump();
}

TrainConfig parse_config_text(const std::string& json_text, const std::string& source_name,
                              const std::vector<std::string>& sets,
                              const std::string& base_dir) {
    const json root = parse_json(json_text, source_name);
    G2L_CHECK(!(root.is_object() && root.contains("task") && root["task"] == "detector"),
              source_name, ": this is a detector config (\"task\": \"detector\"): g2l_train "
              "trains it; the pose tools take its export (detector.g2l) with --detector");
    TrainConfig c = read_config(root, source_name);
    for (const std::string& s : sets) {
        json full = write_config(c);
        apply_set(full, s, source_name);
        c = read_config(full, cat(source_name, " (--set '", s, "')"));
    }
    finalize(c, source_name, base_dir);
    validate(c, source_name);
    return c;
}

TrainConfig load_config(const std::string& path, const std::vector<std::string>& sets) {
    std::error_code ec;
    G2L_CHECK(fs::is_regular_file(path, ec), "load_config: config file '", path,
              "' does not exist or is not a file");
    std::ifstream f(path, std::ios::binary);
    G2L_CHECK(f.good(), "load_config: cannot open config file '", path, "'");
    std::ostringstream text;
    text << f.rdbuf();
    G2L_CHECK(!f.bad(), "load_config: error reading config file '", path, "'");
    std::string dir = fs::absolute(path).parent_path().lexically_normal().string();
    return parse_config_text(text.str(), path, sets, dir);
}

std::string config_to_json(const TrainConfig& cfg) { return write_config(cfg).dump(2) + "\n"; }

}  // namespace g2l::train
