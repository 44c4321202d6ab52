// SPDX-License-Identifier: MIT
#include "data/bop_writer.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/json.h"
#include "geometry/mesh_io.h"
#include "geometry/model_info.h"

namespace g2l::data {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

std::string im_name(int image_id) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%06d.png", image_id);
    return buf;
}

std::string mask_name(int image_id, int k) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%06d_%06d.png", image_id, k);
    return buf;
}

void write_png(const std::string& path, const cv::Mat& img) {
    std::vector<uint8_t> buf;
    G2L_CHECK(cv::imencode(".png", img, buf), "BopSceneWriter: PNG encoding failed for '", path,
              "'");
    // Not durable (no fsync): an image lost in a crash is simply rendered again.
    write_file_atomic(path, std::string(buf.begin(), buf.end()), /*durable=*/false);
}

json box_json(const geom::Box2i& b) {
    // An object with no pixels gets [-1, -1, -1, -1], the BOP toolkit's own convention.
    return b.empty() ? json::array({-1, -1, -1, -1}) : json::array({b.x, b.y, b.w, b.h});
}

// One JSON document {"<id>": value, ...} from already serialised values, in image-id order.
// flush() rewrites the whole files after every batch of frames: keeping each frame's value as
// text makes that a string concatenation, and the map keeps image-id order.
std::string assemble(const std::map<int, std::string>& entries) {
    std::string s = "{\n";
    size_t i = 0;
    for (const auto& [id, val] : entries) {
        s += "  \"" + std::to_string(id) + "\": " + val + (++i < entries.size() ? ",\n" : "\n");
    }
    return s + "}\n";
}

}  // namespace

BopSceneWriter::BopSceneWriter(std::string scene_dir, int64_t planned)
    : dir_(std::move(scene_dir)), planned_(planned) {
    for (const char* sub : {"rgb", "depth", "mask", "mask_visib"}) {
        std::error_code ec;
        fs::create_directories(fs::path(dir_) / sub, ec);
        G2L_CHECK(!ec, "BopSceneWriter: cannot create '", (fs::path(dir_) / sub).string(),
                  "': ", ec.message());
    }
    flush();  // the marker first: a scene killed before its first flush is marked too
}

void BopSceneWriter::write(int image_id, const RenderedFrame& f) {
    G2L_CHECK(image_id >= 0, "BopSceneWriter: image id must be >= 0, got ", image_id);
    G2L_CHECK(gt_.count(image_id) == 0, "BopSceneWriter: image id ", image_id,
              " written twice to '", dir_, "'");
    const int W = f.K.width, H = f.K.height;
    const size_t n = size_t(W) * size_t(H);
    G2L_CHECK(W > 0 && H > 0 && f.depth.size() == n && f.rgb.size() == 3 * n &&
                  f.mask.size() == n && f.full_masks.size() == f.instances.size(),
              "BopSceneWriter: frame buffers do not match the ", W, " x ", H, " camera (depth ",
              f.depth.size(), ", rgb ", f.rgb.size(), ", mask ", f.mask.size(), ")");
    G2L_CHECK(f.depth_scale > 0, "BopSceneWriter: depth_scale must be > 0, got ", f.depth_scale);
    const fs::path dir(dir_);

    cv::Mat rgb(H, W, CV_8UC3);
    for (size_t i = 0; i < n; ++i) {  // OpenCV wants BGR
        uint8_t* p = rgb.data + 3 * i;
        p[0] = f.rgb[3 * i + 2];
        p[1] = f.rgb[3 * i + 1];
        p[2] = f.rgb[3 * i];
    }
    write_png((dir / "rgb" / im_name(image_id)).string(), rgb);

    cv::Mat depth(H, W, CV_16UC1);
    uint16_t* d = depth.ptr<uint16_t>();
    for (size_t i = 0; i < n; ++i) {
        // BOP depth PNGs hold z / depth_scale; 0 means "no measurement", so misses (z <= 0) and
        // values past the uint16 range are both written as 0.
        const double q = std::round(double(f.depth[i]) / f.depth_scale);
        d[i] = (q > 0 && q <= 65535.0) ? uint16_t(q) : uint16_t(0);
    }
    write_png((dir / "depth" / im_name(image_id)).string(), depth);

    json gt = json::array(), info = json::array();
    cv::Mat m(H, W, CV_8UC1);
    for (size_t k = 0; k < f.instances.size(); ++k) {
        const RenderedInstance& in = f.instances[k];
        G2L_CHECK(f.full_masks[k].size() == n, "BopSceneWriter: full mask ", k, " has ",
                  f.full_masks[k].size(), " pixels, expected ", n);
        std::copy(f.full_masks[k].begin(), f.full_masks[k].end(), m.data);
        write_png((dir / "mask" / mask_name(image_id, int(k))).string(), m);
        // f.mask holds k + 1 where instance k is visible (0 elsewhere): its mask_visib.
        for (size_t i = 0; i < n; ++i) m.data[i] = f.mask[i] == k + 1 ? 255 : 0;
        write_png((dir / "mask_visib" / mask_name(image_id, int(k))).string(), m);

        json R = json::array(), t = json::array();
        for (int r = 0; r < 3; ++r) {
            // BOP stores cam_R_m2c row-major and cam_t_m2c in mm, model to camera.
            for (int c = 0; c < 3; ++c) R.push_back(in.pose.R(r, c));
            t.push_back(in.pose.t[r]);
        }
        gt.push_back({{"cam_R_m2c", R}, {"cam_t_m2c", t}, {"obj_id", in.obj_id}});
        info.push_back({{"bbox_obj", box_json(in.bbox_obj)},
                        {"bbox_visib", box_json(in.bbox_visib)},
                        {"px_count_all", in.px_count_all},
                        {"px_count_valid", in.px_count_valid},
                        {"px_count_visib", in.px_count_visib},
                        {"visib_fract", in.visib_fract}});
    }
    const json cam = {{"cam_K", {f.K.fx, 0.0, f.K.cx, 0.0, f.K.fy, f.K.cy, 0.0, 0.0, 1.0}},
                      {"depth_scale", f.depth_scale}};
    gt_[image_id] = gt.dump();
    info_[image_id] = info.dump();
    camera_[image_id] = cam.dump();
}

void BopSceneWriter::flush() const {
    const fs::path dir(dir_);
    write_file_atomic((dir / kIncompleteMarker).string(),
                      json{{"frames_planned", planned_}, {"frames_listed", gt_.size()}}.dump() + "\n");
    write_file_atomic((dir / "scene_gt.json").string(), assemble(gt_));
    write_file_atomic((dir / "scene_camera.json").string(), assemble(camera_));
    write_file_atomic((dir / "scene_gt_info.json").string(), assemble(info_));
}

void BopSceneWriter::finish() const {
    flush();
    std::error_code ec;
    // Removed only after the final flush, so a scene without the marker is always complete.
    fs::remove(fs::path(dir_) / kIncompleteMarker, ec);
    G2L_CHECK(!ec, "BopSceneWriter: cannot remove '", (fs::path(dir_) / kIncompleteMarker).string(),
              "': ", ec.message());
}

BopSceneWriter BopSceneWriter::resume(const std::string& scene_dir) {
    const fs::path dir(scene_dir);
    std::error_code ec;
    G2L_CHECK(fs::is_regular_file(dir / kIncompleteMarker, ec), "'", scene_dir, "' holds no ",
              kIncompleteMarker, ": it is complete (or not a rendered scene), nothing to resume");
    BopSceneWriter w;
    w.dir_ = scene_dir;
    const json marker = parse_json_file((dir / kIncompleteMarker).string());
    G2L_CHECK(marker.is_object() && marker.contains("frames_planned") &&
                  marker["frames_planned"].is_number_integer(),
              "'", (dir / kIncompleteMarker).string(), "' has no integer frames_planned");
    w.planned_ = marker["frames_planned"].get<int64_t>();
    // The records as the last flush wrote them, each kept as its serialised text (a parse and
    // dump of nlohmann's shortest round-trip numbers gives the same text back).
    for (auto [file, records] : {std::pair<const char*, std::map<int, std::string>*>{
                                     "scene_gt.json", &w.gt_},
                                 {"scene_camera.json", &w.camera_},
                                 {"scene_gt_info.json", &w.info_}}) {
        const std::string path = (dir / file).string();
        const json j = parse_json_file(path);
        G2L_CHECK(j.is_object(), "'", path, "' must be a JSON object of image ids");
        for (auto it = j.begin(); it != j.end(); ++it) {
            char* end = nullptr;
            const long id = std::strtol(it.key().c_str(), &end, 10);
            G2L_CHECK(*end == '\0' && id >= 0 && id < (1L << 30), "'", path, "': key '", it.key(),
                      "' is not an image id");
            (*records)[int(id)] = it.value().dump();
        }
    }
    G2L_CHECK(w.gt_.size() == w.camera_.size() && w.gt_.size() == w.info_.size(), "'", scene_dir,
              "': scene_gt.json, scene_camera.json and scene_gt_info.json list different frames");
    // Images of frames written after the last flush: no record names them; rendered again.
    for (const char* sub : {"rgb", "depth", "mask", "mask_visib"}) {
        G2L_CHECK(fs::is_directory(dir / sub, ec), "'", scene_dir, "' has no ", sub, "/ folder");
        std::vector<fs::path> orphans;
        for (const auto& e : fs::directory_iterator(dir / sub)) {
            // Also a crash's leftover temporary files (<name>.tmp.<pid>).
            const int id = std::atoi(e.path().filename().string().c_str());
            if (!w.gt_.count(id) || e.path().extension() != ".png") orphans.push_back(e.path());
        }
        for (const fs::path& o : orphans) fs::remove(o, ec);
    }
    w.flush();
    return w;
}

uint64_t BopSceneWriter::image_bytes(int image_id) const {
    const fs::path dir(dir_);
    std::error_code ec;
    uint64_t bytes = 0;
    auto add = [&](const fs::path& p) {
        const auto n = fs::file_size(p, ec);
        if (!ec) bytes += n;
    };
    add(dir / "rgb" / im_name(image_id));
    add(dir / "depth" / im_name(image_id));
    const auto it = gt_.find(image_id);
    const size_t k = it == gt_.end() ? 0 : json::parse(it->second).size();
    for (size_t i = 0; i < k; ++i) {
        add(dir / "mask" / mask_name(image_id, int(i)));
        add(dir / "mask_visib" / mask_name(image_id, int(i)));
    }
    return bytes;
}

std::string read_symmetries(const std::string& models_info_path, int obj_id) {
    std::error_code ec;
    // No models_info.json: no declared symmetries (BOP readers treat absent ones as none).
    if (!fs::is_regular_file(models_info_path, ec)) return "";
    const json all = parse_json_file(models_info_path);
    const std::string key = std::to_string(obj_id);
    if (!all.is_object() || !all.contains(key) || !all.at(key).is_object()) return "";
    json out = json::object();
    for (const char* k : {"symmetries_discrete", "symmetries_continuous"}) {
        if (!all.at(key).contains(k)) continue;
        const json& v = all.at(key).at(k);
        G2L_CHECK(v.is_array(), "'", models_info_path, "': '", key, ".", k,
                  "' must be an array, got ", v.type_name());
        if (!v.empty()) out[k] = v;
    }
    return out.empty() ? "" : out.dump();
}

void write_bop_models(const std::string& models_dir, const std::vector<SceneModel>& models) {
    std::error_code ec;
    fs::create_directories(models_dir, ec);
    G2L_CHECK(!ec, "write_bop_models: cannot create '", models_dir, "': ", ec.message());
    std::map<int, std::string> info;
    for (const SceneModel& m : models) {
        G2L_CHECK(m.mesh != nullptr, "write_bop_models: obj_id ", m.obj_id, " has a null mesh");
        char name[32];
        std::snprintf(name, sizeof name, "obj_%06d.ply", m.obj_id);
        const std::string path = (fs::path(models_dir) / name).string();
        // save_ply writes in place, so it writes a temporary that is renamed over the final name: a
        // crash never leaves a truncated model.
        const std::string tmp = path + ".tmp.ply";
        geom::save_ply(tmp, *m.mesh);
        fs::rename(tmp, path, ec);
        G2L_CHECK(!ec, "write_bop_models: cannot rename '", tmp, "': ", ec.message());
        const geom::ModelInfo mi = geom::compute_model_info(m.mesh->vertices);
        json j = {{"diameter", mi.diameter}, {"min_x", mi.min.x()}, {"min_y", mi.min.y()},
                  {"min_z", mi.min.z()},     {"size_x", mi.size.x()}, {"size_y", mi.size.y()},
                  {"size_z", mi.size.z()}};
        if (!m.symmetries.empty()) {  // carried, never guessed: the evaluation reads them back
            const json sym = json::parse(m.symmetries);
            for (auto it = sym.begin(); it != sym.end(); ++it) j[it.key()] = it.value();
        }
        info[m.obj_id] = j.dump();
    }
    write_file_atomic((fs::path(models_dir) / "models_info.json").string(), assemble(info));
}

int bop_mesh_id(const std::string& file) {
    const std::string stem = fs::path(file).stem().string();
    if (stem.size() < 5 || stem.size() > 13 || stem.compare(0, 4, "obj_") != 0) return -1;
    for (size_t i = 4; i < stem.size(); ++i)
        if (stem[i] < '0' || stem[i] > '9') return -1;
    const int id = std::stoi(stem.substr(4));
    return id > 0 ? id : -1;
}

std::vector<int> mesh_file_ids(const std::vector<std::string>& files) {
    std::vector<int> ids(files.size(), -1);
    std::map<int, size_t> owner;
    for (size_t i = 0; i < files.size(); ++i) {
        const int id = bop_mesh_id(files[i]);
        if (id < 0) continue;
        G2L_CHECK(!owner.count(id), "'", files[owner[id]], "' and '", files[i],
                  "' both give object ", id);
        owner[id] = i;
        ids[i] = id;
    }
    int next = 1;
    for (size_t i = 0; i < files.size(); ++i) {
        if (ids[i] > 0) continue;
        while (owner.count(next)) ++next;
        owner[next] = i;
        ids[i] = next;
    }
    return ids;
}

void write_obj_names(const std::string& root, const std::map<int, std::string>& names) {
    json j = json::object();
    for (const auto& [id, name] : names) j[std::to_string(id)] = name;
    write_file_atomic((fs::path(root) / "obj_names.json").string(), j.dump(2) + "\n");
}

}  // namespace g2l::data
