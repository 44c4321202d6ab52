// SPDX-License-Identifier: MIT
// Tracking across the frames of a video (spec §17): each verified pose of frame t is followed
// into frame t+1 (FramePipeline::follow: the depth near its posed surface, a short ICP from it,
// verified again), and the detector's hypotheses road runs only when it is needed: on the first
// frame, when a confident pose fails its check (no pose, or its score falls below
// lost_score), and every `redetect_every` frames (to find objects that entered the view,
// and better poses for the weak ones). On such a frame the
// followed poses enter the hypotheses road ahead of the detections, so a detection of an object
// already followed confidently is not posed again (PipelineOptions::cover_score) and the
// better of a followed and a fresh pose of one instance wins.
//
// Internal (not installed): the public face is g2l::PoseTracker (include/g2l/pose_estimator.h).
#pragma once

#include <functional>
#include <vector>

#include "infer/frame_pipeline.h"

namespace g2l::infer {

struct TrackerOptions {
    /// The detector runs on every redetect_every-th frame even when every pose was followed
    /// (new objects entering the view are found then); 1 = every frame; 0 = only when needed.
    int redetect_every = 10;
    /// While a followed pose scores below min_track_score (a weak one: the wrong one of two
    /// like objects, a half-hidden one), the detector runs every redetect_weak_every frames and
    /// the weak poses are decided again from its fresh hypotheses; 0 = redetect_every.
    int redetect_weak_every = 3;
    /// A pose scoring at least this is confident (0.5: on the real YCB-Video frames 99.5% of the
    /// poses scoring at least 0.5 are right, docs/results.md); below it, weak.
    double min_track_score = 0.5;
    /// A confident pose whose followed pose scores below this has lost its object: the detector
    /// runs on that frame. Lower than min_track_score, so that a pose whose score wavers about
    /// 0.5 from frame to frame does not call the detector on every frame (it turns weak).
    double lost_score = 0.3;
    TrackOptions follow;
};

class Tracker {
public:
    /// Throws g2l::Error for options out of range or a pipeline that does not refine.
    Tracker(FramePipeline& pipeline, const TrackerOptions& opt);
    /// The next frame's hypotheses (as FramePipeline::hypotheses lists them: accepted first, by
    /// score; each with `tracked` and `track_id`). `detect` gives the frame's candidates (the
    /// detector, then FramePipeline::candidates); it is called only when the frame needs it.
    /// The pipeline's options (FramePipeline::options) decide the selection.
    void step(const float* depth_mm, const geom::Intrinsics& K,
              const std::function<std::vector<Candidate>()>& detect, std::vector<Hypothesis>* out);
    /// Forgets every track: the next step runs the detector (a new sequence, a cut).
    void reset();
    bool detected() const { return detected_; }  ///< the last step ran the detector
    int tracks() const { return int(tracks_.size()); }  ///< poses followed into the next step

private:
    FramePipeline* pipe_;
    TrackerOptions opt_;
    std::vector<Hypothesis> tracks_;  // the accepted poses of the last frame worth following
    int since_detect_ = 0;  // frames since the detector last ran
    int next_id_ = 0;
    bool detected_ = false;
};

}  // namespace g2l::infer
