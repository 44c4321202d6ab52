// SPDX-License-Identifier: MIT
#include "data/linemod_preprocessed.h"

#include <Eigen/LU>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>

#include "core/error.h"
#include "data/simple_yaml.h"
#include "geometry/camera.h"
#include "geometry/model_info.h"

namespace fs = std::filesystem;

namespace g2l::data {

namespace {

std::string fmt(const char* f, int v) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), f, v);
    return buf;
}

// Image indices of data/NN/<split>.txt: one integer per line ("0004"), blank lines skipped.
std::vector<int> read_split_list(const fs::path& path) {
    G2L_CHECK(fs::is_regular_file(path), "Linemod split list not found: '", path.string(), "'");
    std::ifstream in(path);
    std::vector<int> ids;
    std::string line;
    int line_no = 0;
    while (std::getline(in, line)) {
        ++line_no;
        const size_t b = line.find_first_not_of(" \t\r");
        if (b == std::string::npos) continue;
        const size_t e = line.find_last_not_of(" \t\r");
        const std::string tok = line.substr(b, e - b + 1);
        G2L_CHECK(std::all_of(tok.begin(), tok.end(), [](char c) { return c >= '0' && c <= '9'; }),
                  path.string(), ":", line_no, ": '", tok, "' is not an image index");
        ids.push_back(std::stoi(tok));
    }
    return ids;
}

// Same tolerance as the BOP reader: annotations are stored with few digits.
geom::Pose pose_from(const YamlRecord& rec, const std::string& file) {
    const std::vector<double>& r = yaml_numbers(rec, "cam_R_m2c", 9, file);
    const std::vector<double>& t = yaml_numbers(rec, "cam_t_m2c", 3, file);
    geom::Pose p;
    for (int i = 0; i < 9; ++i) p.R(i / 3, i % 3) = r[i];
    p.t = Eigen::Vector3d(t[0], t[1], t[2]);
    // det > 0 also rejects reflections, which orthogonality alone would let through.
    const double orth = (p.R.transpose() * p.R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    G2L_CHECK(orth < 1e-2 && p.R.determinant() > 0, file, ":", rec.fields.at("cam_R_m2c").line,
              ": cam_R_m2c is not a rotation matrix (max |R^T R - I| = ", orth, ")");
    return p;
}

int as_int(const std::vector<double>& v, const std::string& what, const std::string& file,
           int line) {
    G2L_CHECK(v[0] == static_cast<int>(v[0]), file, ":", line, ": ", what,
              " must be an integer, got ", v[0]);
    return static_cast<int>(v[0]);
}

struct FolderResult {
    std::vector<Frame> frames;
    std::set<int> objects;
};

FolderResult read_folder(const fs::path& dir, int obj, const LinemodOptions& opt) {
    const std::string gt_file = (dir / "gt.yml").string(), info_file = (dir / "info.yml").string();
    const std::map<int, YamlBlock> gt = parse_int_keyed_yaml(gt_file);
    const std::map<int, YamlBlock> info = parse_int_keyed_yaml(info_file);
    std::vector<int> ids;
    // "all": every image annotated in gt.yml, whatever the train/test lists say.
    if (opt.split == "all") {
        for (const auto& kv : gt) ids.push_back(kv.first);
    } else {
        ids = read_split_list(dir / (opt.split + ".txt"));
    }
    const bool has_depth = fs::is_directory(dir / "depth");
    const std::string scene = fmt("%02d", obj);
    FolderResult out;
    int width = 0, height = 0;
    for (int id : ids) {
        const std::string stem = fmt("%04d", id);
        Frame fr;
        fr.scene = scene;
        fr.image_id = id;
        fr.rgb_path = (dir / "rgb" / (stem + ".png")).string();
        G2L_CHECK(fs::is_regular_file(fr.rgb_path), "Linemod image ", id, " of folder ", scene,
                  " is listed but '", fr.rgb_path, "' does not exist");
        if (has_depth) {
            fr.depth_path = (dir / "depth" / (stem + ".png")).string();
            G2L_CHECK(fs::is_regular_file(fr.depth_path), "Linemod image ", id, " of folder ",
                      scene, " is listed but '", fr.depth_path, "' does not exist");
        }
        // Read once per folder: one camera took every image of a LINEMOD object folder.
        if (width == 0) image_size(fr.rgb_path, &width, &height);

        const auto ic = info.find(id);
        G2L_CHECK(ic != info.end() && !ic->second.records.empty(), info_file,
                  ": no entry for image ", id);
        const YamlRecord& cam = ic->second.records.front();
        const std::vector<double>& k = yaml_numbers(cam, "cam_K", 9, info_file);
        // Re-thrown with the info.yml file and line, which the intrinsics check cannot know.
        try {
            fr.K = geom::intrinsics_from_cam_K(k.data(), width, height);
        } catch (const Error& e) {
            G2L_CHECK(false, info_file, ":", cam.line, ": cam_K of image ", id, ": ", e.what());
        }
        fr.depth_scale = yaml_numbers(cam, "depth_scale", 1, info_file)[0];
        G2L_CHECK(fr.depth_scale > 0, info_file, ":", cam.line, ": depth_scale must be > 0, got ",
                  fr.depth_scale);

        const auto g = gt.find(id);
        G2L_CHECK(g != gt.end(), gt_file, ": no entry for image ", id);
        const std::vector<YamlRecord>& recs = g->second.records;
        bool own = false;
        for (size_t i = 0; i < recs.size(); ++i) {
            const YamlRecord& r = recs[i];
            Instance inst;
            inst.obj_id = as_int(yaml_numbers(r, "obj_id", 1, gt_file), "obj_id", gt_file, r.line);
            // The masks in data/NN/mask show only the folder's own object, so the other objects
            // (folder 02 annotates all of LM-O) have no mask and are dropped unless asked for.
            if (inst.obj_id != obj && opt.only_folder_object) continue;
            inst.pose = pose_from(r, gt_file);
            const std::vector<double>& bb = yaml_numbers(r, "obj_bb", 4, gt_file);
            inst.bbox_obj = {static_cast<int>(bb[0]), static_cast<int>(bb[1]),
                             static_cast<int>(bb[2]), static_cast<int>(bb[3])};
            inst.index_in_frame = static_cast<int>(i);
            if (inst.obj_id == obj) {
                // mask/NNNN.png is the mask of the folder's object: a second instance of it
                // would be ambiguous.
                G2L_CHECK(!own, gt_file, ":", r.line, ": image ", id, " lists object ", obj,
                          " twice");
                own = true;
                inst.mask_visib_path = (dir / "mask" / (stem + ".png")).string();
                G2L_CHECK(fs::is_regular_file(inst.mask_visib_path), "Linemod image ", id,
                          " of folder ", scene, " is listed but '", inst.mask_visib_path,
                          "' does not exist");
            }
            out.objects.insert(inst.obj_id);
            fr.instances.push_back(std::move(inst));
        }
        // Folder NN is object NN's sequence (its masks, its train/test lists), so each of its
        // frames must show that object.
        G2L_CHECK(own, gt_file, ":", g->second.line, ": image ", id, " has no instance of the ",
                  "folder's object ", obj);
        out.frames.push_back(std::move(fr));
    }
    // Split lists need not be sorted; frames come out in image order either way.
    std::sort(out.frames.begin(), out.frames.end(),
              [](const Frame& a, const Frame& b) { return a.image_id < b.image_id; });
    return out;
}

}  // namespace

LinemodDataset open_linemod_preprocessed(const std::string& root_str, const LinemodOptions& opt) {
    const fs::path root = fs::path(root_str).lexically_normal();
    const fs::path data_dir = root / "data", models_dir = root / "models";
    G2L_CHECK(fs::is_directory(data_dir), "Linemod_preprocessed folder not found: '",
              data_dir.string(), "'");
    G2L_CHECK(opt.split == "train" || opt.split == "test" || opt.split == "all",
              "LinemodOptions::split must be \"train\", \"test\" or \"all\", got \"", opt.split,
              "\"");
    std::vector<int> objects = opt.objects;
    if (objects.empty()) {
        for (const auto& e : fs::directory_iterator(data_dir)) {
            const std::string n = e.path().filename().string();
            if (e.is_directory() && !n.empty() &&
                std::all_of(n.begin(), n.end(), [](char c) { return c >= '0' && c <= '9'; })) {
                objects.push_back(std::stoi(n));
            }
        }
        std::sort(objects.begin(), objects.end());
        G2L_CHECK(!objects.empty(), "'", data_dir.string(), "' has no object folders (01, 02, ..)");
    }

    std::vector<Frame> frames;
    std::set<int> used;
    for (int obj : objects) {
        const fs::path dir = data_dir / fmt("%02d", obj);
        G2L_CHECK(fs::is_directory(dir), "Linemod object folder not found: '", dir.string(), "'");
        FolderResult r = read_folder(dir, obj, opt);
        used.insert(r.objects.begin(), r.objects.end());
        used.insert(obj);
        frames.insert(frames.end(), std::make_move_iterator(r.frames.begin()),
                      std::make_move_iterator(r.frames.end()));
    }

    const std::string info_path = (models_dir / "models_info.yml").string();
    const std::map<int, geom::ModelInfo> infos = geom::load_models_info_yml(info_path);
    const std::vector<int> sym =
        // LINEMOD's ADD-S objects are eggbox (10) and glue (11) (spec §11.1).
        opt.symmetric_ids ? *opt.symmetric_ids : symmetric_convention("linemod");
    std::map<int, ObjectModel> models;
    for (int id : used) {
        const auto it = infos.find(id);
        G2L_CHECK(it != infos.end(), "object ", id, " is annotated but has no entry in '",
                  info_path, "'");
        ObjectModel m;
        m.obj_id = id;
        m.info = it->second;
        m.info.symmetric = std::find(sym.begin(), sym.end(), id) != sym.end();
        m.name = default_object_name("linemod", id);
        if (m.name.empty()) m.name = fmt("obj_%02d", id);
        m.mesh_path = (models_dir / fmt("obj_%02d.ply", id)).string();
        G2L_CHECK(fs::is_regular_file(m.mesh_path), "model file of object ", id, " not found: '",
                  m.mesh_path, "'");
        models.emplace(id, std::move(m));
    }
    return LinemodDataset(Dataset("linemod", root.string(), std::move(frames), std::move(models)),
                          opt.split);
}

}  // namespace g2l::data
