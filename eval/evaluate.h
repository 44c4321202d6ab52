// SPDX-License-Identifier: MIT
// Pose-stage evaluation with ground-truth 2D boxes (the paper's Fig. 5a protocol): for every
// annotated instance, crop the depth inside its box and sphere, run G2L-Net, score the pose.
#pragma once

#include <array>
#include <map>
#include <string>
#include <vector>

#include "data/dataset.h"
#include "data/detections.h"
#include "geometry/types.h"
#include "infer/frame_pipeline.h"
#include "nn/models/g2l_net.h"

namespace g2l::eval {

/// What to evaluate and how. The pipeline's settings are the library's own options (the crop,
/// its radius and point counts the model was trained with come with the model:
/// infer::PipelineModel).
struct EvalOptions {
    /// The pose pipeline's options, as the library and g2l_infer take them (PipelineOptions's
    /// defaults: the model's point counts, `automatic` refinement = `turns` against the
    /// dataset's meshes, the hypotheses road's settings for detections).
    PipelineOptions pipeline;
    double min_visib_fract = 0.0;    ///< instances below are skipped (not counted)
    int64_t max_instances = 0;       ///< instances evaluated at most (0 = all)
    /// Sphere centre: false (default) = from the box and the depth only, as a detector gives
    /// it; true = the GT visible mask's centre (the earlier protocol, for comparison).
    bool centre_from_mask = false;
    int max_model_points = 2000;     ///< model vertices used by ADD / ADD-S (stride subsample)
    /// Boxes from a detector (BOP detection file; every entry needs scene_id and image_id)
    /// instead of the GT boxes. Each frame's detections take the library's road (the
    /// hypotheses: each posed, refined, verified against the depth, duplicates and overlaps
    /// suppressed; infer::FramePipeline::hypotheses), and the accepted poses are matched to the
    /// ground-truth instances as BOP does: by score, each instance at most one estimate, the
    /// one with the smallest ADD-S below 10% of the diameter; an instance left over takes the
    /// nearest remaining estimate of its object within a diameter (a wrong pose), else it is a
    /// miss; an estimate left over is a false positive. Null = GT boxes.
    const std::vector<data::Detection>* detections = nullptr;
    /// Poses estimated elsewhere (a BOP results CSV: g2l_infer --bop-csv, a tracker's, another
    /// method's) instead of the pipeline's: each frame's rows are its reported poses, by score,
    /// matched to the ground-truth instances as `detections`' poses are (each pose's box: its
    /// posed model box's projection). Rows of objects the model does not know are ignored.
    const std::vector<data::PoseRow>* poses = nullptr;
    /// Oracle inputs, to tell which stage an error comes from (the rest runs as usual):
    /// oracle_seg = the ground-truth object points (the crop points within label_threshold_mm
    /// of the posed model, training's label rule) replace the segmentation; oracle_t = the GT
    /// translation replaces the T-net's (it centres the rotation input and is the estimate's
    /// translation, so the errors are then the rotation's alone).
    bool oracle_seg = false;
    bool oracle_t = false;
    /// false: conflicts between hypotheses go to the higher score (infer::HypothesisTuning::
    /// arbitrate off) — the conflicts the arbiter is fitted on (fit_arbiter), reproducible
    /// whatever arbiter is shipped.
    bool arbitrate = true;
    double label_threshold_mm = 8.0;  ///< the object-point rule of the seg IoU and oracle_seg
};

/// Per-object and overall figures. Misses (no pose) count as failures, with distance inf in
/// the AUCs (spec §11.3).
struct ObjectScores {
    int obj_id = 0;
    std::string name;
    bool symmetric = false;
    int count = 0, misses = 0;
    double acc_add_s_10 = 0;   ///< % correct at 10% of the diameter: ADD-S if symmetric else ADD
    double auc_adds = 0;       ///< ADD-S AUC up to 10 cm (YCB-Video toolbox)
    double auc_add = 0;        ///< ADD AUC up to 10 cm
    double mean_rot_err_deg = 0, mean_trans_err_mm = 0;  ///< over found poses
    /// ADD-S accuracy at 10% of the diameter for every object, symmetric or not (%).
    double acc_adds_all_10 = 0;
    /// ADD taken as the minimum over the mesh's geometric symmetries (geometry/symmetry.h;
    /// BOP's MSSD idea: what depth alone can tell) at 10% of the diameter (%).
    double acc_addsym_10 = 0;
    /// Median rotation error modulo those symmetries (degrees; misses count as 180).
    double rot_err_sym_deg_median = 0;
    double median_trans_err_mm = 0;  ///< median translation error over found poses
    int num_symmetries = 1;          ///< geometric symmetries of the mesh (identity included)
    /// Mean IoU of the points taken as object with the ground-truth object points (training's
    /// label rule), among the crop points the seg net sees; -1 when no instance had either.
    double seg_iou = -1;
    /// With detections: % of the instances whose class's best detection in the frame overlaps
    /// the ground-truth visible box with IoU >= 0.5 (the average pools every instance);
    /// -1 with ground-truth boxes. An instance without such a detection counts as a miss.
    double det_recall_50 = -1;
    /// The same with the detections' own boxes (not the boxes the verified poses explain).
    double detector_recall_50 = -1;
    /// With detections: % of the reported (accepted) poses that are right (ADD-S < 0.1 d of the
    /// instance they are matched to); false positives count as wrong. -1 with GT boxes.
    double pose_precision = -1;
    /// With detections: % of the reported poses whose box overlaps a ground-truth visible box
    /// of their object with IoU >= 0.5 (one box each). -1 with GT boxes.
    double det_precision_50 = -1;
    int reported = 0;         ///< with detections: poses reported (accepted), FPs included
    int false_positives = 0;  ///< with detections: reported poses matching no instance
};

struct EvalReport {
    std::vector<ObjectScores> objects;  ///< sorted by obj_id
    ObjectScores average;               ///< objects' mean (acc, AUCs); "all" counts for others
    double ms_crop = 0, ms_seg = 0, ms_t = 0, ms_rot = 0;  ///< mean per instance
    double ms_refine = 0;                  ///< depth refinement, mean per instance
    Refinement refine = Refinement::none;  ///< the pipeline's refinement (resolved)
    int instances = 0;
    std::string oracle = "none";  ///< oracle inputs used: none, seg, t or seg+t (EvalOptions)
};

/// One evaluated instance: its errors (mm, degrees) or a miss (no pose).
struct InstanceResult {
    int obj_id = 0;
    bool found = false;       ///< false: no pose (counts as wrong, distance inf in the AUCs)
    double add_mm = 0, adds_mm = 0, addsym_mm = 0;  ///< ADD, ADD-S, ADD modulo symmetries
    double rot_deg = 0, rot_sym_deg = 0, trans_mm = 0;
    /// IoU of the object points taken (seg net or oracle) with the GT object points among the
    /// crop points the seg net sees; -1 when there was no crop or neither set has a point.
    double seg_iou = -1;
    /// With detections: IoU of the box the matched pose is reported with (infer::Hypothesis::
    /// reported_box: the box of its surface the depth explains, else the detection's) with the
    /// ground-truth visible box (0 without one); -1 with ground-truth boxes. Below 0.5 the
    /// instance is a detection miss (det_recall_50); its reported pose is still judged by its
    /// error.
    double det_iou = -1;
    /// The same for the detection's own box (detector_recall_50).
    double det_iou_detector = -1;
    bool det_miss() const { return det_iou >= 0 && det_iou < 0.5; }
    // Where it came from and what was estimated (evaluate_gt_boxes fills these; aggregate
    // does not read them).
    std::string scene;             ///< BOP scene folder name ("000048")
    int image_id = 0;
    int inst_index = 0;            ///< index of the instance in the frame's scene_gt list
    std::string status;            ///< "ok", "no detection", "no depth", "too few ... points"
    double score = 1;              ///< box score (1 for GT boxes)
    geom::Box2i box;               ///< the box used (clipped to the image) or reported
    geom::Box2i detector_box;      ///< with detections: the detection's own box (clipped)
    geom::Pose est, gt;            ///< estimate (when found) and ground truth
    double ms = 0;                 ///< crop + networks (+ refinement), this instance
    int refine_cluster = -1;       ///< refinement: -1 all object points, else the cluster that won
    double alt_fit_mm = -1;        ///< refinement: the best distinct pose's fit (PoseOutcome)
    int refine_hyp = -1;           ///< refinement: -1 none, 0 the network's pose, else the turn
    double fit_mm = -1;            ///< refinement: the final fit (geometry/refine.h)
    double gt_fit_mm = -1;         ///< refinement: its cost of the ground-truth pose (geom::pose_cost)
    // The hypotheses road (detections):
    bool reported = false;         ///< an accepted pose was matched to this instance
    /// A reported pose that matches no ground-truth instance (its errors are not set; obj_id,
    /// scene, image_id, score, est and box are). Counts against the precisions only.
    bool false_positive = false;
    bool box_hit = false;          ///< the reported pose's box has IoU >= 0.5 with a GT box
    double det_score = -1;         ///< the detector's score of the reported pose's candidate
    double verify_score = -1;      ///< its verification score (-1: not verified)
    double explained = -1, violation = -1, seg_agree = -1;  ///< its verification's parts
    /// Right at ADD-S < 0.1 d (only for a reported pose matched to an instance).
    bool right = false;
};

/// One hypothesis of the hypotheses road, for precision-recall curves and pictures.
struct HypothesisRecord {
    std::string scene;
    int image_id = 0;
    int obj_id = 0;
    double score = 0;         ///< the verified score (what a threshold compares)
    double det_score = 0;
    std::string verdict;      ///< infer::to_string(Verdict)
    int rival = -1;           ///< the index (within the frame) of the pose that beat it
    bool right = false;       ///< accepted and matched right (ADD-S < 0.1 d) to an instance
    geom::Box2i box;
    geom::Pose est;           ///< when posed
    bool posed = false;
    bool verified = false;
    /// The score model's inputs (infer::ScoreModel::features), when verified.
    std::array<double, infer::ScoreModel::kFeatures> features{};
    /// The pose is right for some ground-truth instance of its object (ADD-S < 0.1 d),
    /// whatever the matching: what the score model is fitted to predict.
    bool pose_right = false;
    /// The verification's counts, when verified: visible model points with a depth reading,
    /// those the depth explains, and the image cells they cover (the depth the pose claims).
    int visible = 0, inliers = 0, footprint_cells = 0;
};

/// Fits the score model (logistic regression, Newton's method with an L2 penalty `l2` on the
/// weights but the bias) to the verified hypotheses' features and pose_right labels. Throws
/// g2l::Error with fewer than 20 verified hypotheses or only one label among them.
infer::ScoreModel fit_score_model(const std::vector<HypothesisRecord>& hyps, double l2 = 1e-2);

/// Fits the arbiter (infer::ArbiterModel: logistic regression without a bias on feature
/// differences, Newton's method, L2 penalty `l2`) to the conflicts among the hypotheses: each
/// duplicate or overlap and the pose that beat it (its `rival`, an index within its frame's
/// records, which lie together as g2l_eval records them), both verified, exactly one of the two
/// right (pose_right); the difference of their ln footprint_cells (ArbiterModel::footprint)
/// is fitted with the features' differences. Throws g2l::Error with fewer than 10
/// such pairs or with a rival index outside its frame.
infer::ArbiterModel fit_arbiter(const std::vector<HypothesisRecord>& hyps, double l2 = 1e-2);

/// What aggregation needs to know of an object.
struct ObjectMeta {
    std::string name;
    double diameter = 0;      ///< mm; accuracies use 10% of it
    bool symmetric = false;   ///< the dataset's ADD-S list (acc_add_s_10)
    int num_symmetries = 1;
};

/// The report of per-instance results: per object (sorted by id) accuracies at 10% of the
/// diameter, AUCs, mean / median errors over found poses (misses count as 180 degrees in the
/// symmetric rotation median); the average row is the mean over objects of the accuracies, AUCs
/// and medians and the mean over found instances of the mean errors. Throws g2l::Error for an
/// object without meta or with a diameter <= 0.
EvalReport aggregate(const std::vector<InstanceResult>& results,
                     const std::map<int, ObjectMeta>& meta);

/// `model`: the network and what it was trained with (its class_of maps obj_id -> class index;
/// objects not in it are skipped). The objects' diameters are the dataset's.
EvalReport evaluate_gt_boxes(const infer::PipelineModel& model, const data::Dataset& ds,
                             const EvalOptions& opt);

/// evaluate_gt_boxes with every per-instance result (in frame order) in *instances and, with
/// detections, every hypothesis in *hypotheses (either may be null).
EvalReport evaluate_instances(const infer::PipelineModel& model, const data::Dataset& ds,
                              const EvalOptions& opt, std::vector<InstanceResult>* instances,
                              std::vector<HypothesisRecord>* hypotheses = nullptr);

/// One point of a precision-recall curve: reporting the poses scoring >= threshold.
struct PrPoint {
    double threshold = 0, precision = 0, recall = 0;  ///< precision and recall in %
};
/// The precision-recall curve of the reported poses over their verification scores (the
/// detection's score where none was verified): a pose is right when matched right (ADD-S < 0.1
/// d), recall counts every ground-truth instance. One point per distinct score, highest first.
/// Greedy matching by score makes a higher-scored pose's match independent of the lower ones,
/// so the curve is exact for every threshold.
std::vector<PrPoint> pr_curve(const std::vector<InstanceResult>& results);

/// The report as a Markdown table (one row per object + the average + timings).
std::string report_markdown(const EvalReport& r);
/// The report as a JSON text.
std::string report_json(const EvalReport& r);

}  // namespace g2l::eval
