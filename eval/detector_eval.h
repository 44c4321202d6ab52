// SPDX-License-Identifier: MIT
// The 2D detector against ground truth: recall / precision at IoU 0.5 and where the heat-map
// peak falls, per object (g2l_eval --detector, the detector trainer's validation), and the
// detector run over a dataset as the pose evaluation's boxes (g2l_eval --boxes det).
#pragma once

#include <string>
#include <vector>

#include "data/dataset.h"
#include "data/detections.h"
#include "nn/models/detector.h"

namespace g2l::eval {

/// Detector evaluation on real frames with GT boxes.
struct DetectorEvalRow {
    int obj_id = 0;
    int instances = 0;      ///< GT instances (visib_fract >= min_visib)
    int found = 0;          ///< the class's best detection overlaps the GT box with IoU >= 0.5
    int found_top3 = 0;     ///< one of the class's three best detections does (ranking aside)
    int peak_on_mask = 0;   ///< the class's best detection peaks on the instance's visible mask
    int detections = 0;     ///< detections of this class with score >= score_threshold
    int true_detections = 0;  ///< ... matched one-to-one to a GT box of the class (IoU >= 0.5)
    double recall() const { return instances ? double(found) / instances : 0; }
    double recall_top3() const { return instances ? double(found_top3) / instances : 0; }
    double precision() const { return detections ? double(true_detections) / detections : 0; }
    double peak_rate() const { return instances ? double(peak_on_mask) / instances : 0; }
};
struct DetectorEvalResult {
    std::vector<DetectorEvalRow> rows;  ///< per object, in class order
    DetectorEvalRow total;              ///< sums over objects (obj_id 0)
    double mean_recall = 0, mean_precision = 0, mean_peak_rate = 0;  ///< mean over objects
    double mean_recall_top3 = 0;
    int frames = 0;
    double ms_per_frame = 0;            ///< detector time (input + network + decoding)
};

/// Evaluates on every frame of `ds` that has an RGB image (instances of the detector's objects
/// with visib_fract >= min_visib). The visible masks come from the dataset when it has them,
/// else from rendering the GT-posed models of the frame (the annotated objects occlude each
/// other; unannotated clutter is not modelled, so such masks can be larger than the truth).
DetectorEvalResult evaluate_detector(const nn::LoadedDetector& det, const data::Dataset& ds,
                                     double min_visib = 0.1, float score_threshold = 0.3f,
                                     int max_frames = 0, bool progress = false,
                                     bool mirror = false);
/// The detector on every frame of `ds` that has an RGB image: one data::Detection per class
/// peak (scene_id from the scene folder name, image_id, obj_id, box, score, heat-map peak, the
/// frame's detector time), as g2l_eval --boxes det feeds them to the pose evaluation. Throws
/// for a scene name that is not a number (BOP scene ids are). `mirror`: nn::detect's
/// mirrored second pass (both functions). At most `max_per_class` peaks of one class.
std::vector<data::Detection> run_detector_on(const nn::LoadedDetector& det, const data::Dataset& ds,
                                             float min_score = 0.05f, bool mirror = false,
                                             int max_per_class = 3);

/// The table of a result (per object and mean), plain text.
std::string detector_eval_table(const DetectorEvalResult& r);

}  // namespace g2l::eval
