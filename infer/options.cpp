// SPDX-License-Identifier: MIT
// The pipeline's options (include/g2l/pose_estimator.h): their names and their checks, in one
// place for every road that takes them. Compiled into the shared library (what a user links)
// and into the internal pipeline archive the tools link: the library exports these symbols
// itself, since it hides whatever comes from its static archives.
#include <cmath>
#include <string>

#include "core/error.h"
#include "g2l/pose_estimator.h"

namespace g2l {

const char* to_string(Refinement r) {
    switch (r) {
        case Refinement::none: return "none";
        case Refinement::icp: return "icp";
        case Refinement::turns: return "turns";
        case Refinement::automatic: return "automatic";
    }
    return "unknown refinement";
}

Refinement parse_refinement(const std::string& text, const std::string& what) {
    for (Refinement r : {Refinement::none, Refinement::icp, Refinement::turns, Refinement::automatic})
        if (text == to_string(r)) return r;
    G2L_CHECK(false, what, " must be none, icp, turns or automatic, got '", text, "'");
    return Refinement::none;
}

void PipelineOptions::check() const {
    G2L_CHECK(crop_points >= -1, "crop_points must be >= -1 (-1: the model's), got ", crop_points);
    G2L_CHECK(object_points == -1 || object_points >= 1,
              "object_points must be -1 (the model's) or >= 1, got ", object_points);
    G2L_CHECK(refine == Refinement::none || refine == Refinement::icp ||
                  refine == Refinement::turns || refine == Refinement::automatic,
              "refine must be none, icp, turns or automatic, got ", int(refine));
    G2L_CHECK(std::isfinite(min_detection_score) && min_detection_score >= 0 &&
                  min_detection_score <= 1,
              "min_detection_score must be in [0, 1], got ", min_detection_score);
    G2L_CHECK(max_instances >= 1, "max_instances must be >= 1, got ", max_instances);
    G2L_CHECK(max_hypotheses >= 1, "max_hypotheses must be >= 1, got ", max_hypotheses);
    G2L_CHECK(std::isfinite(alike_frac) && alike_frac >= 0 && alike_frac < 1,
              "alike_frac must be in [0, 1) (0: off), got ", alike_frac);
    G2L_CHECK(std::isfinite(min_pose_score) && min_pose_score >= 0 && min_pose_score <= 1,
              "min_pose_score must be in [0, 1], got ", min_pose_score);
    G2L_CHECK(std::isfinite(cover_score) && cover_score >= 0,
              "cover_score must be >= 0 (above 1: off), got ", cover_score);
}

void EstimatorOptions::check() const {
    PipelineOptions::check();
    G2L_CHECK(threads >= 0, "threads must be >= 0, got ", threads);
}

}  // namespace g2l
