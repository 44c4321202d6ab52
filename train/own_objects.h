// SPDX-License-Identifier: MIT
// Your own objects, from a folder of meshes to a detector and a pose model in one call
// (`g2l_train --objects DIR --out RUN --minutes M`, docs/own_objects.md):
//   1. the meshes (PLY / OBJ, any names, millimetres or metres) become a BOP models folder,
//      RUN/models: obj_NNNNNN.ply in millimetres, models_info.json (diameters, boxes and the
//      geometric symmetries geometry/symmetry.h finds), obj_names.json (id -> file name);
//   2. the recipe writes RUN/detector.json and RUN/pose.json (renders of those meshes only);
//   3. the detector, then the pose model, train on renders within the time budget, each with
//      its share of the minutes and a schedule fitted to its time (train.time_schedule), then
//      export RUN/detector.g2l and RUN/pose.g2l.
// Then `g2l_infer --model RUN/pose.g2l --detector RUN/detector.g2l --meshes RUN/models ...`.
#pragma once

#include <atomic>
#include <string>
#include <vector>

namespace g2l::train {

/// One mesh of the user's folder, as it entered RUN/models.
struct OwnObject {
    int obj_id = 0;
    std::string source;          ///< the file it came from
    std::string name;            ///< its file name without extension (obj_names.json)
    double diameter_mm = 0;
    bool converted_from_m = false;  ///< the mesh was in metres: its vertices were scaled by 1000
    int symmetries = 1;          ///< geometric symmetries found (identity included)
};

/// Step 1: every .ply / .obj of `dir` (sorted by name) as a BOP models folder under `root`
/// (root/models/obj_NNNNNN.ply, root/models/models_info.json, root/obj_names.json). A file
/// named obj_NNNNNN keeps id NNNNNN; the others get the smallest free ids, in name order. A
/// mesh less than 10 units across is taken as metres and scaled by 1000 (a note in
/// `notes`). Throws g2l::Error naming the file for a folder without meshes, an unreadable
/// mesh, two files of one id, or a mesh under 10 mm across even in metres... (below 1 cm).
std::vector<OwnObject> prepare_own_models(const std::string& dir, const std::string& root,
                                          std::vector<std::string>* notes);

struct OwnObjectsOptions {
    std::string objects_dir;   ///< the folder of meshes
    std::string out_dir;       ///< RUN: refused when it holds files, unless `force`
    double minutes = 30;       ///< the whole budget, both trainings (> 0)
    /// The camera the detector's renders see (a BOP camera.json or a scene_camera.json entry):
    /// yours. "" = YCB-Video's Xtion (640 x 480, f 1067 px), the default scene's.
    std::string camera;
    double detector_share = 0.5;  ///< of the training minutes, the detector's (the rest: pose)
    int64_t max_steps = 0;     ///< per training, for tests (0 = the time decides)
    bool force = false;
    bool progress = true;
    const std::atomic<bool>* stop_flag = nullptr;
};

struct OwnObjectsSummary {
    std::vector<OwnObject> objects;
    std::string detector, pose, models;  ///< RUN/detector.g2l, RUN/pose.g2l, RUN/models
    bool interrupted = false;            ///< stop_flag: the phase's run folder can --resume
    std::string interrupted_run;         ///< that folder
    int64_t interrupted_steps = 0;
    double minutes = 0;                  ///< wall time of the whole call
};

/// Steps 1-3. Progress lines (with ETA) on stderr when `progress`. Throws g2l::Error for bad
/// options, an out_dir holding files (without force), and every error of the steps.
OwnObjectsSummary run_own_objects(const OwnObjectsOptions& opt);

}  // namespace g2l::train
