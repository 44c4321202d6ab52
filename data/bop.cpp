// SPDX-License-Identifier: MIT
#include "data/bop.h"
#include "core/json.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <nlohmann/json.hpp>
#include <set>
#include <unordered_set>

#include "core/error.h"
#include "geometry/camera.h"
#include "geometry/model_info.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace g2l::data {

namespace {

// ---- strict JSON access: every failure names the file and the key path ---------------------

json read_json(const fs::path& path) {
    G2L_CHECK(fs::is_regular_file(path), "BOP file not found: '", path.string(), "'");
    std::ifstream f(path, std::ios::binary);
    G2L_CHECK(f.good(), "cannot open '", path.string(), "'");
    std::ostringstream ss;
    ss << f.rdbuf();
    return parse_json_strict(ss.str(), "malformed JSON in '" + path.string() + "'");
}

/// A JSON value together with where it came from, so that errors can say so.
struct Node {
    const json& v;
    const std::string& file;
    std::string key;  // key path, e.g. "3"[1].cam_t_m2c

    Node operator[](const std::string& name) const {
        G2L_CHECK(v.is_object(), file, ": key ", key, " must be an object, got ", v.type_name());
        const auto it = v.find(name);
        const std::string sub = key.empty() ? "\"" + name + "\"" : key + "." + name;
        G2L_CHECK(it != v.end(), file, ": missing key ", sub);
        return {*it, file, sub};
    }
    Node operator[](size_t i) const {
        G2L_CHECK(v.is_array() && i < v.size(), file, ": key ", key, " has no element [", i, "]");
        return {v[i], file, key + "[" + std::to_string(i) + "]"};
    }
    bool has(const std::string& name) const { return v.is_object() && v.contains(name); }

    double number() const {
        G2L_CHECK(v.is_number(), file, ": key ", key, " must be a number, got ", v.type_name(), " ",
                  v.dump());
        const double d = v.get<double>();
        G2L_CHECK(std::isfinite(d), file, ": key ", key, " is not finite: ", v.dump());
        return d;
    }
    int integer() const {
        G2L_CHECK(v.is_number_integer(), file, ": key ", key, " must be an integer, got ",
                  v.type_name(), " ", v.dump());
        return v.get<int>();
    }
    std::vector<double> numbers(size_t n) const {
        G2L_CHECK(v.is_array(), file, ": key ", key, " must be an array of ", n, " numbers, got ",
                  v.type_name());
        G2L_CHECK(v.size() == n, file, ": key ", key, " must have ", n, " numbers, got ", v.size());
        std::vector<double> out(n);
        for (size_t i = 0; i < n; ++i) out[i] = (*this)[i].number();
        return out;
    }
    size_t list_size() const {
        G2L_CHECK(v.is_array(), file, ": key ", key, " must be a list, got ", v.type_name());
        return v.size();
    }
};

int parse_image_id(const std::string& key, const std::string& file) {
    size_t used = 0;
    int id = -1;
    try {
        id = std::stoi(key, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    G2L_CHECK(used == key.size() && id >= 0, file, ": key \"", key,
              "\" is not a non-negative image id");
    return id;
}

std::string fmt06(int v) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%06d", v);
    return buf;
}

geom::Box2i box_from(const Node& n) {
    const std::vector<double> b = n.numbers(4);
    for (double x : b) {
        G2L_CHECK(x == std::floor(x), n.file, ": key ", n.key, " must hold integers, got ", x);
    }
    // BOP writes [-1, -1, -1, -1] for invisible objects: keep it as an empty box.
    return {static_cast<int>(b[0]), static_cast<int>(b[1]), static_cast<int>(b[2]),
            static_cast<int>(b[3])};
}

// Real annotations are stored with few digits: LM-O's cam_R_m2c deviate from orthonormal by up to
// 1.3e-3. The check only rejects what cannot be a rotation (a typo, a transposed 4x4, ...).
constexpr double kRotationTol = 1e-2;

geom::Pose pose_from(const Node& inst) {
    const Node rn = inst["cam_R_m2c"];
    const std::vector<double> r = rn.numbers(9);
    const std::vector<double> t = inst["cam_t_m2c"].numbers(3);
    geom::Pose p;
    for (int i = 0; i < 9; ++i) p.R(i / 3, i % 3) = r[i];  // row-major in BOP
    p.t = Eigen::Vector3d(t[0], t[1], t[2]);
    const double orth = (p.R.transpose() * p.R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    G2L_CHECK(orth < kRotationTol && p.R.determinant() > 0, rn.file, ": key ", rn.key,
              " is not a rotation matrix (max |R^T R - I| = ", orth, ", det = ", p.R.determinant(),
              ")");
    return p;
}

// File names of a folder (empty set with exists=false when the folder is absent). Listing once
// per scene is much cheaper than one stat per frame on a full BOP download.
struct Folder {
    fs::path dir;
    bool exists = false;
    std::unordered_set<std::string> names;
};

Folder list_folder(const fs::path& dir) {
    Folder f;
    f.dir = dir;
    f.exists = fs::is_directory(dir);
    if (f.exists) {
        for (const auto& e : fs::directory_iterator(dir)) f.names.insert(e.path().filename());
    }
    return f;
}

// Path of <stem><ext> in the folder for the first extension present; "" if the folder is absent;
// error when the folder exists but holds none of them.
std::string find_image(const Folder& f, const std::string& stem,
                       std::initializer_list<const char*> exts, const std::string& context) {
    if (!f.exists) return "";
    for (const char* ext : exts) {
        if (f.names.count(stem + ext)) return (f.dir / (stem + ext)).string();
    }
    std::string tried;
    for (const char* ext : exts) tried += (tried.empty() ? "" : ", ") + stem + ext;
    G2L_CHECK(false, "BOP folder '", f.dir.string(), "' has no file for ", context, " (tried ",
              tried, ")");
    return "";
}

// ---- models ----------------------------------------------------------------------------------

std::map<int, ObjectModel> read_models(const fs::path& root, const std::string& name,
                                       const BopOptions& opt) {
    const fs::path dir = root / (opt.models_eval ? "models_eval" : "models");
    G2L_CHECK(fs::is_directory(dir), "BOP models folder not found: '", dir.string(), "'");
    const fs::path info_path = dir / "models_info.json";
    G2L_CHECK(fs::is_regular_file(info_path), "BOP file not found: '", info_path.string(), "'");
    const std::map<int, geom::ModelInfo> infos = geom::load_models_info_json(info_path.string());

    json names;
    const fs::path names_path = root / "obj_names.json";
    const std::string names_file = names_path.string();
    if (fs::is_regular_file(names_path)) names = read_json(names_path);

    std::set<int> wanted(opt.obj_ids.begin(), opt.obj_ids.end());
    for (int id : wanted) {
        G2L_CHECK(infos.count(id), "object id ", id,
                  " requested in BopOptions::obj_ids is not in '", info_path.string(), "'");
    }
    bool known = false;
    const std::vector<int> def_sym = default_symmetric_ids(name, &known);
    const std::vector<int>& sym = opt.symmetric_ids ? *opt.symmetric_ids : def_sym;
    const bool use_list = opt.symmetric_ids.has_value() || known;

    std::map<int, ObjectModel> models;
    for (const auto& [id, info] : infos) {
        if (!wanted.empty() && !wanted.count(id)) continue;
        ObjectModel m;
        m.obj_id = id;
        m.info = info;
        if (use_list) m.info.symmetric = std::find(sym.begin(), sym.end(), id) != sym.end();
        m.mesh_path = (dir / ("obj_" + fmt06(id) + ".ply")).string();
        G2L_CHECK(fs::is_regular_file(m.mesh_path), "model file of object ", id, " listed in '",
                  info_path.string(), "' not found: '", m.mesh_path, "'");
        const std::string key = std::to_string(id);
        if (!names.is_null() && names.contains(key)) {
            const Node n{names.at(key), names_file, "\"" + key + "\""};
            G2L_CHECK(n.v.is_string(), names_file, ": key ", n.key, " must be a string");
            m.name = n.v.get<std::string>();
        } else {
            m.name = default_object_name(name, id);
            if (m.name.empty()) m.name = "obj_" + fmt06(id);
        }
        models.emplace(id, std::move(m));
    }
    return models;
}

// ---- one scene -------------------------------------------------------------------------------

struct SceneContext {
    const fs::path& dir;
    const std::string& scene;
    const std::map<int, ObjectModel>& models;
    const std::set<int>& wanted;  // empty = all
    int width, height;            // 0 = take from the first image of the scene
};

void read_instance_info(const Node& info, Instance* inst) {
    if (info.has("bbox_obj")) inst->bbox_obj = box_from(info["bbox_obj"]);
    if (info.has("bbox_visib")) inst->bbox_visib = box_from(info["bbox_visib"]);
    if (info.has("visib_fract")) {
        const Node vf = info["visib_fract"];
        inst->visib_fract = vf.number();
        G2L_CHECK(inst->visib_fract >= 0 && inst->visib_fract <= 1 + 1e-6, vf.file, ": key ",
                  vf.key, " must be in [0, 1], got ", inst->visib_fract);
    }
}

std::vector<Frame> read_scene(const SceneContext& sc) {
    const fs::path gt_path = sc.dir / "scene_gt.json", cam_path = sc.dir / "scene_camera.json";
    const fs::path info_path = sc.dir / "scene_gt_info.json";
    const std::string gt_file = gt_path.string(), cam_file = cam_path.string();
    const std::string info_file = info_path.string();
    const json gt = read_json(gt_path), cam = read_json(cam_path);
    const bool has_info = fs::is_regular_file(info_path);
    const json info = has_info ? read_json(info_path) : json::object();
    G2L_CHECK(gt.is_object(), gt_file, ": top level must be an object keyed by image id");
    G2L_CHECK(cam.is_object(), cam_file, ": top level must be an object keyed by image id");
    G2L_CHECK(info.is_object(), info_file, ": top level must be an object keyed by image id");
    const Node gt_root{gt, gt_file, ""}, cam_root{cam, cam_file, ""},
        info_root{info, info_file, ""};

    const Folder rgb = list_folder(sc.dir / "rgb"), depth = list_folder(sc.dir / "depth");
    const Folder masks = list_folder(sc.dir / "mask_visib");
    int width = sc.width, height = sc.height;

    std::vector<Frame> frames;
    for (const auto& item : gt.items()) {
        const std::string& key = item.key();
        Frame fr;
        fr.scene = sc.scene;
        fr.image_id = parse_image_id(key, gt_file);
        const std::string stem = fmt06(fr.image_id);
        const std::string what = "scene " + sc.scene + " image " + key;
        fr.rgb_path = find_image(rgb, stem, {".png", ".jpg", ".jpeg", ".tif", ".tiff"}, what);
        fr.depth_path = find_image(depth, stem, {".png"}, what);
        if (width <= 0 || height <= 0) {
            const std::string& probe = !fr.rgb_path.empty() ? fr.rgb_path : fr.depth_path;
            G2L_CHECK(!probe.empty(), "no image size for scene '", sc.dir.string(),
                      "': no camera.json at the dataset root and no rgb/ or depth/ images");
            image_size(probe, &width, &height);
        }
        G2L_CHECK(cam.contains(key), cam_file, ": image id ", key, " of ", gt_file,
                  " is missing (no key \"", key, "\")");
        const Node c = cam_root[key];
        const std::vector<double> k = c["cam_K"].numbers(9);
        try {
            fr.K = geom::intrinsics_from_cam_K(k.data(), width, height);
        } catch (const Error& e) {
            G2L_CHECK(false, cam_file, ": key ", c.key, ".cam_K: ", e.what());
        }
        const Node ds = c["depth_scale"];
        fr.depth_scale = ds.number();
        G2L_CHECK(fr.depth_scale > 0, cam_file, ": key ", ds.key, " must be > 0, got ",
                  fr.depth_scale);

        const Node insts = gt_root[key];
        const size_t n = insts.list_size();
        if (has_info) {
            G2L_CHECK(info.contains(key), info_file, ": image id ", key, " of ", gt_file,
                      " is missing (no key \"", key, "\")");
            const size_t ni = info_root[key].list_size();
            G2L_CHECK(ni == n, info_file, ": key \"", key, "\" lists ", ni, " instances but ",
                      gt_file, " lists ", n);
        }
        for (size_t i = 0; i < n; ++i) {
            const Node in = insts[i];
            Instance inst;
            const Node oid = in["obj_id"];
            inst.obj_id = oid.integer();
            if (!sc.wanted.empty() && !sc.wanted.count(inst.obj_id)) continue;
            G2L_CHECK(sc.models.count(inst.obj_id), gt_file, ": key ", oid.key, ": object ",
                      inst.obj_id, " has no model in models_info.json");
            inst.pose = pose_from(in);
            inst.index_in_frame = static_cast<int>(i);
            if (has_info) read_instance_info(info_root[key][i], &inst);
            inst.mask_visib_path = find_image(masks, stem + "_" + fmt06(static_cast<int>(i)),
                                              {".png"}, what + " instance " + std::to_string(i));
            fr.instances.push_back(std::move(inst));
        }
        if (!sc.wanted.empty() && fr.instances.empty()) continue;
        frames.push_back(std::move(fr));
    }
    std::sort(frames.begin(), frames.end(),
              [](const Frame& a, const Frame& b) { return a.image_id < b.image_id; });
    return frames;
}

bool all_digits(const std::string& s) {
    return !s.empty() &&
           std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

std::string dataset_name_of(const fs::path& root, const BopOptions& opt) {
    if (!opt.dataset_name.empty()) return opt.dataset_name;
    return (root.has_filename() ? root : root.parent_path()).filename().string();
}

}  // namespace

Dataset open_bop_models(const std::string& root_str, const BopOptions& opt) {
    const fs::path root = fs::path(root_str).lexically_normal();
    G2L_CHECK(fs::is_directory(root), "BOP dataset root not found: '", root_str, "'");
    const std::string name = dataset_name_of(root, opt);
    return Dataset(name, root.string(), {}, read_models(root, name, opt));
}

BopDataset open_bop(const std::string& root_str, const std::string& split, const BopOptions& opt) {
    const fs::path root = fs::path(root_str).lexically_normal();
    G2L_CHECK(fs::is_directory(root), "BOP dataset root not found: '", root_str, "'");
    const fs::path split_dir = root / split;
    G2L_CHECK(!split.empty() && fs::is_directory(split_dir), "BOP split '", split,
              "' not found: no folder '", split_dir.string(), "'");
    const std::string name = dataset_name_of(root, opt);

    const std::map<int, ObjectModel> models = read_models(root, name, opt);

    // Image size: <root>/camera.json when present (BOP ships one per dataset).
    int width = 0, height = 0;
    const fs::path cam_path = root / "camera.json";
    if (fs::is_regular_file(cam_path)) {
        const json cam = read_json(cam_path);
        const std::string file = cam_path.string();
        const Node c{cam, file, ""};
        width = c["width"].integer();
        height = c["height"].integer();
        G2L_CHECK(width > 0 && height > 0, file, ": width/height must be > 0, got ", width, "x",
                  height);
    }

    std::vector<std::string> scenes = opt.scenes;
    if (scenes.empty()) {
        for (const auto& e : fs::directory_iterator(split_dir)) {
            if (e.is_directory() && all_digits(e.path().filename().string())) {
                scenes.push_back(e.path().filename().string());
            }
        }
        std::sort(scenes.begin(), scenes.end());
        G2L_CHECK(!scenes.empty(), "BOP split folder '", split_dir.string(),
                  "' has no scene folders (all-digit names such as 000001)");
    }
    const std::set<int> wanted(opt.obj_ids.begin(), opt.obj_ids.end());
    std::vector<Frame> frames;
    for (const std::string& s : scenes) {
        const fs::path dir = split_dir / s;
        G2L_CHECK(fs::is_directory(dir), "BOP scene '", s, "' not found: no folder '", dir.string(),
                  "'");
        std::vector<Frame> f = read_scene({dir, s, models, wanted, width, height});
        frames.insert(frames.end(), std::make_move_iterator(f.begin()),
                      std::make_move_iterator(f.end()));
    }
    return BopDataset(Dataset(name, root.string(), std::move(frames), models), split,
                      std::move(scenes));
}

}  // namespace g2l::data
