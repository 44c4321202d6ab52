// SPDX-License-Identifier: MIT
// libFuzzer target: every text (JSON) reader of g2l. The first byte picks the reader, the rest
// is its input: training config, scene config, BOP detection file, models_info.json, the
// three per-scene BOP files (scene_gt.json, scene_camera.json, scene_gt_info.json) of a small
// BOP dataset, detector config, camera file (g2l_infer --camera) and models_info.yml. Any g2l::Error / std::exception is an accepted outcome; a crash, a sanitizer
// report, a hang or a huge allocation is a bug.
#include <cstdint>
#include <exception>
#include <filesystem>
#include <string>

#include "data/bop.h"
#include "data/detections.h"
#include "data/scene.h"
#include "fuzz_util.h"
#include "geometry/model_info.h"
#include "train/config.h"
#include "train/detector_train.h"

namespace fs = std::filesystem;

namespace {

// A copy of tests/data/ycbv_mini (G2L_FIXTURE_DIR) whose files the inputs replace.
const std::string& bop_root() {
    static const std::string root = [] {
        const std::string r = g2l::fuzz::temp_dir() + "/bop";
        fs::copy(G2L_FIXTURE_DIR "/ycbv_mini", r, fs::copy_options::recursive);
        return r;
    }();
    return root;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 1) return 0;
    const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
    try {
        switch (data[0] % 10) {
            case 0: (void)g2l::train::parse_config_text(text, "fuzz.json"); break;
            case 1: (void)g2l::data::parse_scene_config(text, "fuzz scene"); break;
            case 2: (void)g2l::data::parse_bop_detections(text, "fuzz detections"); break;
            case 3: {
                const std::string p = g2l::fuzz::temp_dir() + "/models_info.json";
                g2l::fuzz::write_file(p, data + 1, size - 1);
                (void)g2l::geom::load_models_info_json(p);
                break;
            }
            case 7: (void)g2l::train::parse_detector_config(text, "fuzz detector", "/tmp"); break;
            case 8: (void)g2l::data::parse_camera_file(text, "fuzz camera", 1); break;
            case 9: {
                const std::string p = g2l::fuzz::temp_dir() + "/models_info.yml";
                g2l::fuzz::write_file(p, data + 1, size - 1);
                (void)g2l::geom::load_models_info_yml(p);
                break;
            }
            default: {  // 4, 5, 6
                static const char* files[] = {"scene_gt.json", "scene_camera.json", "scene_gt_info.json"};
                const std::string scene = bop_root() + "/train_real/000000/";
                const std::string name = files[data[0] % 10 - 4];
                // Restore the other two from the fixture, replace this one.
                for (const char* f : files)
                    fs::copy_file(std::string(G2L_FIXTURE_DIR "/ycbv_mini/train_real/000000/") + f,
                                  scene + f, fs::copy_options::overwrite_existing);
                g2l::fuzz::write_file(scene + name, data + 1, size - 1);
                const g2l::data::BopDataset ds = g2l::data::open_bop(bop_root(), "train_real", {});
                (void)ds.frames().size();
                break;
            }
        }
    } catch (const std::exception&) {
    }
    return 0;
}
