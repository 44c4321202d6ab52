// SPDX-License-Identifier: MIT
#include "data/sequence.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/error.h"
#include "core/json.h"

namespace g2l::data {

namespace fs = std::filesystem;

std::vector<SequenceFrame> list_bop_scene(const std::string& dir) {
    std::error_code ec;
    G2L_CHECK(fs::is_directory(dir, ec), "scene '", dir, "' is not a folder");
    const fs::path depth_dir = fs::path(dir) / "depth";
    G2L_CHECK(fs::is_directory(depth_dir, ec), "scene '", dir,
              "' has no depth/ folder (a BOP scene: depth/, rgb/, scene_camera.json)");
    const fs::path cam_path = fs::path(dir) / "scene_camera.json";
    G2L_CHECK(fs::is_regular_file(cam_path, ec), "scene '", dir, "' has no scene_camera.json");
    std::ifstream in(cam_path, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    G2L_CHECK(in.good() || in.eof(), "cannot read '", cam_path.string(), "'");
    const std::string source = "camera '" + cam_path.string() + "'";
    const nlohmann::json cams = parse_json_strict(text.str(), source);
    G2L_CHECK(cams.is_object(), source, ": the top level must be an object of image ids, got ",
              cams.type_name());
    std::vector<SequenceFrame> frames;
    std::error_code list_ec;
    for (const fs::directory_entry& e : fs::directory_iterator(depth_dir, list_ec)) {
        const fs::path p = e.path();
        if (p.extension() != ".png") continue;
        const std::string stem = p.stem().string();
        // At most 9 digits, so the stoi below cannot overflow an int.
        G2L_CHECK(!stem.empty() && stem.size() <= 9 &&
                      std::all_of(stem.begin(), stem.end(), [](char c) { return c >= '0' && c <= '9'; }),
                  "scene '", dir, "': depth file '", p.filename().string(),
                  "' is not named by its image id (BOP: 000001.png)");
        SequenceFrame f;
        f.image_id = std::stoi(stem);
        f.depth = p.string();
        // BOP scenes store colour as PNG (real captures) or JPEG (the PBR training renders).
        for (const char* ext : {".png", ".jpg", ".jpeg"}) {
            const fs::path rgb = fs::path(dir) / "rgb" / (stem + ext);
            if (fs::is_regular_file(rgb, ec)) {
                f.rgb = rgb.string();
                break;
            }
        }
        const std::string key = std::to_string(f.image_id);
        // A missing or bad camera entry fails only this frame (camera_error); the others still run.
        try {
            G2L_CHECK(cams.contains(key), source, ": no entry for image ", f.image_id, " (key \"",
                      key, "\")");
            f.camera = parse_camera_entry(cams.at(key), source, key);
        } catch (const std::exception& err) {
            f.camera_error = err.what();
        }
        frames.push_back(std::move(f));
    }
    G2L_CHECK(!list_ec, "scene '", dir, "': cannot list depth/: ", list_ec.message());
    G2L_CHECK(!frames.empty(), "scene '", dir, "': no depth image (depth/NNNNNN.png)");
    // directory_iterator's order is unspecified: sort by image id to get the video's order.
    std::sort(frames.begin(), frames.end(),
              [](const SequenceFrame& a, const SequenceFrame& b) { return a.image_id < b.image_id; });
    return frames;
}

std::vector<SequenceFrame> list_frames_file(const std::string& path, const CameraFile& camera) {
    std::ifstream in(path);
    G2L_CHECK(in.good(), "frame list '", path, "' cannot be opened");
    const fs::path base = fs::path(path).parent_path();
    auto resolve = [&](const std::string& p) {
        // Relative paths are relative to the list file, so a list works from any working directory.
        return fs::path(p).is_absolute() || base.empty() ? p : (base / p).string();
    };
    std::vector<SequenceFrame> frames;
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
        const size_t hash = line.find('#');
        if (hash != std::string::npos) line.resize(hash);
        std::istringstream ss(line);
        std::string depth, rgb, extra;
        if (!(ss >> depth)) continue;
        ss >> rgb;
        G2L_CHECK(!(ss >> extra), "frame list '", path, "' line ", n,
                  ": expected DEPTH_PNG [RGB_IMAGE], got a third path '", extra, "'");
        SequenceFrame f;
        f.image_id = int(frames.size()) + 1;
        f.depth = resolve(depth);
        if (!rgb.empty()) f.rgb = resolve(rgb);
        f.camera = camera;
        frames.push_back(std::move(f));
    }
    G2L_CHECK(!frames.empty(), "frame list '", path, "' lists no frame");
    return frames;
}

}  // namespace g2l::data
