// SPDX-License-Identifier: MIT
// Writes the seed corpora of the fuzz targets: fuzz_seeds OUT_DIR SOURCE_DIR -> OUT_DIR/{text,
// mesh,checkpoint}/. Seeds are generated from the current code (a tiny model checkpoint, small
// meshes) and copied from the repository (configs, fixture BOP files), so they follow format
// changes.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "core/checkpoint.h"
#include "geometry/mesh_io.h"
#include "nn/models/detector.h"
#include "nn/models/g2l_io.h"

namespace fs = std::filesystem;

namespace {

std::string read(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    std::ostringstream s;
    s << f.rdbuf();
    return s.str();
}

void put(const fs::path& path, const std::string& bytes) {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f << bytes;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 3) {
        std::fprintf(stderr, "usage: fuzz_seeds OUT_DIR SOURCE_DIR\n");
        return 2;
    }
    try {
        const fs::path out = argv[1], src = argv[2];
        for (const char* d : {"text_formats", "mesh", "checkpoint"}) fs::create_directories(out / d);
        // Text formats: selector byte + content.
        const fs::path mini = src / "tests/data/ycbv_mini";
        put(out / "text_formats/config", std::string(1, '\0') + read((src / "configs/demo_cpu.json").string()));
        put(out / "text_formats/config_sim", std::string(1, '\0') + read((src / "configs/ycbv_sim2real.json").string()));
        put(out / "text_formats/scene", std::string(1, '\1') +
            R"({"pose_mode": "resting", "targets_min": 2, "targets_max": 3, "noise": {"enabled": true, "holes_max": 2}, "camera": {"fx": 500, "fy": 500, "cx": 320, "cy": 240, "width": 640, "height": 480}})");
        put(out / "text_formats/detections", std::string(1, '\2') +
            R"([{"scene_id": 0, "image_id": 1, "category_id": 8, "bbox": [186, 132, 139, 191], "score": 0.9, "time": 0.1}])");
        put(out / "text_formats/models_info", std::string(1, '\3') + read((mini / "models/models_info.json").string()));
        const char* scene_files[] = {"scene_gt.json", "scene_camera.json", "scene_gt_info.json"};
        for (int i = 0; i < 3; ++i)
            put(out / ("text_formats/bop_" + std::to_string(i)),
                std::string(1, char(4 + i)) + read((mini / "train_real/000000" / scene_files[i]).string()));
        put(out / "text_formats/detector_config",
            std::string(1, '\7') + read((src / "configs/ycbv_detector.json").string()));
        put(out / "text_formats/camera", std::string(1, '\10') + read((mini / "camera.json").string()));
        put(out / "text_formats/scene_camera",
            std::string(1, '\10') + read((mini / "train_real/000000/scene_camera.json").string()));
        put(out / "text_formats/models_info_yml", std::string(1, '\11') +
            "1: {diameter: 102.1, min_x: -37.9, min_y: -38.7, min_z: -45.9, size_x: 75.9, "
            "size_y: 77.4, size_z: 91.8}\n5: {diameter: 247.5, min_x: -50.4, min_y: -90.9, "
            "min_z: -96.9, size_x: 100.8, size_y: 181.8, size_z: 193.7}\n");
        // Meshes: a tetrahedron as binary PLY, ASCII PLY and OBJ.
        g2l::geom::Mesh m;
        m.vertices.resize(4, 3);
        m.vertices << 0, 0, 0, 10, 0, 0, 0, 10, 0, 0, 0, 10;
        m.faces.resize(4, 3);
        m.faces << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
        g2l::geom::save_ply((out / "mesh_bin.ply").string(), m);
        put(out / "mesh/binary_ply", std::string(1, '\0') + read((out / "mesh_bin.ply").string()));
        fs::remove(out / "mesh_bin.ply");
        put(out / "mesh/ascii_ply", std::string(1, '\0') +
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
        put(out / "mesh/obj", std::string(1, '\1') + "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n");
        // A tiny model export (every width at its minimum of 8).
        g2l::nn::G2LConfig c;
        c.num_classes = 1;
        c.width = 0.01;
        c.rot_unit = "kp_rms";
        g2l::nn::G2LNet net(c);
        std::vector<std::pair<std::string, g2l::Tensor>> tensors;
        for (const auto& [name, t] : net.state_dict()) tensors.emplace_back("model." + name, t);
        nlohmann::json meta;
        meta["format"] = "g2l-model";
        meta["model"] = g2l::nn::g2l_config_json(c);
        meta["classes"] = {{1, 0}};
        nlohmann::json kp = nlohmann::json::array();
        for (int i = 0; i < 8; ++i) kp.push_back({(i & 1) ? 10 : -10, (i & 2) ? 20 : -20, (i & 4) ? 5 : -5});
        meta["keypoints"] = {kp};
        meta["objects"] = {{{"obj_id", 1}, {"diameter", 50.0}, {"symmetric", false}}};
        meta["sampling"] = {{"crop", "sphere"}, {"radius_scale", 1.0}, {"points", 64}, {"seg_points", 32}};
        g2l::save_checkpoint((out / "checkpoint/tiny_model.g2l").string(), tensors, meta.dump());
        // A tiny detector export (depth input, width 4, two classes).
        g2l::nn::DetectorConfig dc;
        dc.num_classes = 2;
        dc.width = 4;
        dc.input = g2l::nn::DetectorInput::depth;
        g2l::nn::save_detector((out / "checkpoint/tiny_detector.g2l").string(),
                               g2l::nn::Detector(dc), {1, 5}, 2);
        g2l::save_checkpoint((out / "checkpoint/two_tensors.g2l").string(),
                             {{"a", g2l::Tensor::ones({2, 3})}, {"b", g2l::Tensor::zeros({1}, g2l::DType::I32)}},
                             R"({"format": "other"})");
        std::printf("fuzz seeds written to %s\n", out.string().c_str());
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fuzz_seeds: %s\n", e.what());
        return 1;
    }
}
