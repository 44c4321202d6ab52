// SPDX-License-Identifier: MIT
#include "data/bop.h"
#include "core/json.h"
#include "core/json_reader.h"

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

json read_json(const fs::path& path) { return parse_json_file(path.string()); }

// BOP files are read with the one schema reader (core/json_reader.h), by path: errors read
// "<file>: '3[1].cam_t_m2c' must be an array of 3 numbers, got [1,2]". Keys we do not use
// (BOP adds fields over versions: px_count_*, cam_R_w2c, elev, ...) are accepted: these files
// are written by other tools, unlike our configs.

/// An array of JSON objects (one per instance).
const json& need_list(const JsonReader& r, const json& v, const std::string& path) {
    G2L_CHECK(v.is_array(), r.source(), ": '", path, "' must be an array, got ", v.type_name());
    return v;
}

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

geom::Box2i box_from(JsonReader& r, const char* key) {
    std::vector<double> b;
    r.nums(key, b, 4);
    for (double x : b) {
        G2L_CHECK(x == std::floor(x) && std::abs(x) < 1e9, r.source(), ": '", r.at(key),
                  "' must hold integers, got ", x);
    }
    // BOP writes [-1, -1, -1, -1] for invisible objects: keep it as an empty box.
    return {static_cast<int>(b[0]), static_cast<int>(b[1]), static_cast<int>(b[2]),
            static_cast<int>(b[3])};
}

// Real annotations are stored with few digits: LM-O's cam_R_m2c deviate from orthonormal by up to
// 1.3e-3. The check only rejects what cannot be a rotation (a typo, a transposed 4x4, ...).
constexpr double kRotationTol = 1e-2;

geom::Pose pose_from(JsonReader& inst) {
    std::vector<double> r, t;
    inst.require("cam_R_m2c");
    inst.nums("cam_R_m2c", r, 9);
    inst.require("cam_t_m2c");
    inst.nums("cam_t_m2c", t, 3);
    geom::Pose p;
    for (int i = 0; i < 9; ++i) p.R(i / 3, i % 3) = r[i];  // row-major in BOP
    p.t = Eigen::Vector3d(t[0], t[1], t[2]);
    const double orth = (p.R.transpose() * p.R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    G2L_CHECK(orth < kRotationTol && p.R.determinant() > 0, inst.source(), ": '",
              inst.at("cam_R_m2c"), "' is not a rotation matrix (max |R^T R - I| = ", orth, ", det = ", p.R.determinant(),
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
    // A models root is what g2l_render writes from any folder of meshes: say so, as a user
    // with only meshes meets this first.
    const char* how = " (a BOP models root holds models/obj_NNNNNN.ply and models/models_info.json; "
                      "from a folder of meshes, 'g2l_render --models DIR --out ROOT --frames 1' "
                      "writes one with the diameters and symmetries)";
    G2L_CHECK(fs::is_directory(dir), "BOP models folder not found: '", dir.string(), "'", how);
    const fs::path info_path = dir / "models_info.json";
    G2L_CHECK(fs::is_regular_file(info_path), "BOP file not found: '", info_path.string(), "'", how);
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
    // Symmetric objects: the models_info.json's symmetries_* entries, unless the caller names
    // them (BopOptions::symmetric_ids); never guessed from the folder's name.
    const bool use_list = opt.symmetric_ids.has_value();
    const std::vector<int> sym = use_list ? *opt.symmetric_ids : std::vector<int>{};

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
            JsonReader nr(names, names_file);
            nr.text(key.c_str(), m.name);
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

void read_instance_info(JsonReader& info, Instance* inst) {
    if (info.has("bbox_obj")) inst->bbox_obj = box_from(info, "bbox_obj");
    if (info.has("bbox_visib")) inst->bbox_visib = box_from(info, "bbox_visib");
    if (info.has("visib_fract")) {
        info.num("visib_fract", inst->visib_fract);
        G2L_CHECK(inst->visib_fract >= 0 && inst->visib_fract <= 1 + 1e-6, info.source(), ": '",
                  info.at("visib_fract"), "' must be in [0, 1], got ", inst->visib_fract);
    }
}

std::vector<Frame> read_scene(const SceneContext& sc) {
    const fs::path gt_path = sc.dir / "scene_gt.json", cam_path = sc.dir / "scene_camera.json";
    const fs::path info_path = sc.dir / "scene_gt_info.json";
    const std::string gt_file = gt_path.string(), cam_file = cam_path.string();
    const std::string info_file = info_path.string();
    // A scene a writer did not finish (g2l_render killed): its JSON lists fewer frames than its
    // folders hold, and the render was meant to be larger. Refused, never read as complete.
    const fs::path marker = sc.dir / "render_incomplete.json";  // data/bop_writer.h
    if (fs::is_regular_file(marker)) {
        const json m = read_json(marker);
        G2L_CHECK(false, "scene '", sc.dir.string(), "' was not finished: its render stopped with ",
                  m.value("frames_listed", 0), " of ", m.value("frames_planned", 0), " frames "
                  "listed in scene_gt.json (", marker.string(), "); continue it (g2l_render "
                  "--resume), render it again (g2l_render --force), or delete the marker to use "
                  "the frames listed");
    }
    const json gt = read_json(gt_path), cam = read_json(cam_path);
    const bool has_info = fs::is_regular_file(info_path);
    const json info = has_info ? read_json(info_path) : json::object();
    JsonReader gt_root(gt, gt_file), cam_root(cam, cam_file), info_root(info, info_file);

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
        const CameraFile c = parse_camera_entry(cam.at(key), cam_file, key);
        try {
            fr.K = geom::intrinsics_from_cam_K(c.cam_K().data(), width, height);
        } catch (const Error& e) {
            G2L_CHECK(false, cam_file, ": '", key, ".cam_K': ", e.what());
        }
        fr.depth_scale = c.depth_scale;

        const json& insts = need_list(gt_root, gt.at(key), key);
        const size_t n = insts.size();
        if (has_info) {
            G2L_CHECK(info.contains(key), info_file, ": image id ", key, " of ", gt_file,
                      " is missing (no key \"", key, "\")");
            const size_t ni = need_list(info_root, info.at(key), key).size();
            G2L_CHECK(ni == n, info_file, ": key \"", key, "\" lists ", ni, " instances but ",
                      gt_file, " lists ", n);
        }
        for (size_t i = 0; i < n; ++i) {
            const std::string at = key + "[" + std::to_string(i) + "]";
            JsonReader in(insts[i], gt_file, at);
            Instance inst;
            in.require("obj_id");
            in.integer("obj_id", inst.obj_id);
            if (!sc.wanted.empty() && !sc.wanted.count(inst.obj_id)) continue;
            G2L_CHECK(sc.models.count(inst.obj_id), gt_file, ": '", in.at("obj_id"), "': object ",
                      inst.obj_id, " has no model in models_info.json");
            inst.pose = pose_from(in);
            inst.index_in_frame = static_cast<int>(i);
            if (has_info) {
                JsonReader ir(info.at(key)[i], info_file, at);
                read_instance_info(ir, &inst);
            }
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
        const CameraFile c = load_camera_file(cam_path.string());
        width = c.width;
        height = c.height;
        G2L_CHECK(width > 0 && height > 0, cam_path.string(),
                  ": 'width' and 'height' are required (> 0), got ", width, "x", height);
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

// ---- camera files ----------------------------------------------------------------------------

CameraFile parse_camera_entry(const json& j, const std::string& source, const std::string& path) {
    JsonReader r(j, source, path);
    CameraFile c;
    if (r.has("cam_K")) {
        std::vector<double> k;
        r.nums("cam_K", k, 9);
        // zero skew and a last row (0, 0, 1): checked as the dataset reader does
        try {
            (void)geom::intrinsics_from_cam_K(k.data(), 1, 1);
        } catch (const Error& e) {
            G2L_CHECK(false, source, ": '", r.at("cam_K"), "': ", e.what());
        }
        c.fx = k[0];
        c.cx = k[2];
        c.fy = k[4];
        c.cy = k[5];
    } else {
        if (!r.has("fx")) r.require("cam_K");  // neither form: name the BOP one
        for (const char* key : {"fx", "fy", "cx", "cy"}) r.require(key);
        r.num("fx", c.fx);
        r.num("fy", c.fy);
        r.num("cx", c.cx);
        r.num("cy", c.cy);
    }
    // Without depth_scale the depth's units are unknown (BOP: 1 for LM, 0.1 for YCB-Video):
    // guessing 1 would give a pose 10 times too far.
    G2L_CHECK(r.has("depth_scale"), source, ": '", r.at("depth_scale"),
              "' is required (mm per unit of the depth PNG, e.g. 1 or 0.1)");
    r.num("depth_scale", c.depth_scale);
    r.integer("width", c.width);
    r.integer("height", c.height);
    G2L_CHECK(c.fx > 0 && c.fy > 0, source, ": focal lengths must be > 0, got fx=", c.fx,
              " fy=", c.fy);
    G2L_CHECK(c.depth_scale > 0, source, ": '", r.at("depth_scale"), "' must be > 0, got ",
              c.depth_scale);
    G2L_CHECK(c.width >= 0 && c.width <= 100000 && c.height >= 0 && c.height <= 100000, source,
              ": 'width' / 'height' must be in [1, 100000], got ", c.width, " x ", c.height);
    return c;
}

CameraFile parse_camera_file(const std::string& text, const std::string& source, int image_id) {
    const json j = parse_json_strict(text, source);
    G2L_CHECK(j.is_object(), source, ": the top level must be a JSON object, got ", j.type_name());
    if (j.contains("cam_K") || j.contains("fx")) return parse_camera_entry(j, source, "");
    G2L_CHECK(image_id >= 0, source, ": neither 'cam_K' nor 'fx' at the top level; for a "
              "scene_camera.json give the image id (--image-id)");
    const std::string key = std::to_string(image_id);
    G2L_CHECK(j.contains(key), source, ": no entry for image ", image_id, " (no key \"", key,
              "\")");
    return parse_camera_entry(j.at(key), source, key);
}

CameraFile load_camera_file(const std::string& path, int image_id) {
    G2L_CHECK(fs::is_regular_file(path), "camera file not found: '", path, "'");
    std::ifstream f(path, std::ios::binary);
    G2L_CHECK(f.good(), "cannot open camera file '", path, "'");
    std::ostringstream ss;
    ss << f.rdbuf();
    return parse_camera_file(ss.str(), "camera '" + path + "'", image_id);
}

}  // namespace g2l::data
