// SPDX-License-Identifier: MIT
// The pipeline's options on a command line: g2l_eval and g2l_infer read the same flags
// straight into one g2l::PipelineOptions (what the library, evaluation and validation take),
// and its own check() is the usage check. A new pipeline option is one field, one check and
// one flag here.
#pragma once

#include <CLI/CLI.hpp>
#include <map>
#include <string>

#include "g2l/pose_estimator.h"

namespace g2l::cli {

/// Adds --crop-points, --object-points, --refine, --min-pose-score, `peaks_flag` (the peaks of
/// one object tried per frame: g2l_eval's --max-instances already counts evaluated instances),
/// --max-hypotheses, --alike and --cover-score, each writing its field of `o`.
inline void add_pipeline_options(CLI::App& app, PipelineOptions& o, const std::string& peaks_flag) {
    app.add_option("--crop-points", o.crop_points,
                   "seg-net input points per crop (default: the model's sampling.points, as in "
                   "training; 0 = the whole crop)")
        ->check(CLI::Range(0, 1 << 24));
    app.add_option("--object-points", o.object_points,
                   "object points fed to the T-net and rotation blocks (default: the model's "
                   "sampling.seg_points)")
        ->check(CLI::Range(1, 1 << 24));
    const std::map<std::string, Refinement> refinements{{"none", Refinement::none},
                                                        {"icp", Refinement::icp},
                                                        {"turns", Refinement::turns},
                                                        {"automatic", Refinement::automatic}};
    app.add_option("--refine", o.refine,
                   "depth refinement against the objects' meshes: turns (ICP from the networks' "
                   "pose and from it turned by the model box's near-symmetric turns, the best "
                   "depth fit wins; ~20-30 ms per object), icp (from the networks' pose only), "
                   "none (the networks alone, as G2L-Net publishes them); automatic (default): "
                   "turns for every object with a mesh")
        ->transform(CLI::CheckedTransformer(refinements));
    app.add_option("--min-pose-score", o.min_pose_score,
                   "poses whose depth-verified score (the probability that the pose is right) is "
                   "below this are rejected: not reported from detections, marked \"low score\" "
                   "for given boxes (default 0)")
        ->check(CLI::Range(0.0, 1.0));
    app.add_option(peaks_flag, o.max_instances,
                   "detections: peaks (instances) of one object tried per frame (default 3)")
        ->check(CLI::Range(1, 1000));
    app.add_option("--max-hypotheses", o.max_hypotheses,
                   "detections: hypotheses posed and verified per frame (default 12)")
        ->check(CLI::Range(1, 100000));
    app.add_option("--alike", o.alike_frac,
                   "detections: a peak is also tried as each object whose sorted box sides lie "
                   "within this fraction of its own (default 0.15; 0 = off)")
        ->check(CLI::Range(0.0, 0.99));
    app.add_option("--cover-score", o.cover_score,
                   "detections: one whose peak lies on depth that an earlier verified pose "
                   "scoring at least this explains is not posed (default 0.7; above 1 = off)")
        ->check(CLI::Range(0.0, 2.0));
}

/// PipelineOptions::check() as a usage error: "" when the options hold together.
inline std::string pipeline_usage_error(const PipelineOptions& o) {
    try {
        o.check();
    } catch (const std::exception& e) {
        return e.what();
    }
    return "";
}

}  // namespace g2l::cli
