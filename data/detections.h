// SPDX-License-Identifier: MIT
// 2D detections in the BOP Challenge's detection-file format (the "default detections" of
// BOP 2022+): a JSON array of {"scene_id", "image_id", "category_id", "bbox": [x, y, w, h],
// "score", "time"}, one entry per detected object instance. `obj_id` is accepted for
// `category_id`; scene_id / image_id / score / time are optional (-1 / -1 / 1 / -1).
#pragma once

#include <array>
#include <string>
#include <vector>

namespace g2l::data {

struct Detection {
    int scene_id = -1, image_id = -1;  ///< -1 when the file does not say
    int obj_id = 0;                    ///< category_id (BOP object id, >= 1)
    double x = 0, y = 0, w = 0, h = 0; ///< pixels
    double score = 1;
    double time = -1;                  ///< seconds the detector took for the image (-1: unknown)
    /// Pixel of the detector's heat-map peak (g2l's detector; key "peak": [x, y] in a file);
    /// -1 when unknown: the sphere centre then comes from the box (geom::box_centre).
    double peak_x = -1, peak_y = -1;
};

/// Parses a BOP detection file. Throws g2l::Error naming the file, the entry index and the key
/// for: a missing/unreadable file, text that is not JSON, a top level that is not an array, an
/// entry that is not an object, an unknown key (a typo must not be ignored), a missing
/// category_id/obj_id or bbox, ids that are not integers (obj_id >= 1, scene/image >= 0), a bbox
/// that is not 4 finite numbers with w, h >= 0, or a score/time that is not a finite number.
std::vector<Detection> load_bop_detections(const std::string& path);

/// The same for JSON text already in memory; `what` names it in errors.
std::vector<Detection> parse_bop_detections(const std::string& json_text, const std::string& what);

/// One row of a BOP Challenge results CSV (scene_id,im_id,obj_id,score,R,t,time): a pose
/// estimate, model -> camera, R row-major, t in mm.
struct PoseRow {
    int scene_id = 0, image_id = 0, obj_id = 0;
    double score = 1;
    std::array<double, 9> R{};
    std::array<double, 3> t{};
    double time = -1;  ///< seconds for the image (-1 in the file: unknown)
};

/// Parses a BOP results CSV (the header line "scene_id,im_id,obj_id,score,R,t,time", then one
/// estimate per line; R: 9 numbers, t: 3, separated by spaces). Throws g2l::Error naming the
/// file and line for a missing file, another header, a line without 7 fields, ids that are not
/// integers >= 0 (obj_id >= 1), a number that is not finite, or R / t with the wrong count.
std::vector<PoseRow> load_bop_results_csv(const std::string& path);
/// The same for text in memory; `what` names it in errors.
std::vector<PoseRow> parse_bop_results_csv(const std::string& text, const std::string& what);

}  // namespace g2l::data
