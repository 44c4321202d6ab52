// SPDX-License-Identifier: MIT
#include "infer/tracker.h"

#include "core/error.h"

namespace g2l::infer {

Tracker::Tracker(FramePipeline& pipeline, const TrackerOptions& opt) : pipe_(&pipeline), opt_(opt) {
    G2L_CHECK(opt.redetect_every >= 0 && opt.redetect_weak_every >= 0,
              "Tracker: redetect_every and redetect_weak_every must be >= 0, got ",
              opt.redetect_every, " and ", opt.redetect_weak_every);
    G2L_CHECK(opt.min_track_score >= 0 && opt.min_track_score <= 1,
              "Tracker: min_track_score must be in [0, 1], got ", opt.min_track_score);
    G2L_CHECK(opt.lost_score >= 0 && opt.lost_score <= opt.min_track_score,
              "Tracker: lost_score must be in [0, min_track_score], got ", opt.lost_score);
    G2L_CHECK(pipeline.refine() != Refinement::none,
              "Tracker: the pipeline does not refine: tracking follows poses with the depth "
              "refinement against the objects' meshes");
}

void Tracker::reset() {
    tracks_.clear();
    since_detect_ = 0;
    detected_ = false;
}

void Tracker::step(const float* depth, const geom::Intrinsics& K,
                   const std::function<std::vector<Candidate>()>& detect,
                   std::vector<Hypothesis>* out) {
    // 1. Follow every track. A confident pose that loses its object (no pose, or a score that
    //    falls below lost_score) calls the detector in; a weak one (below min_track_score) rides
    //    along, reported with its score, until the next detection can replace it.
    std::vector<Hypothesis> seeds;
    bool lost = false, weak = false;
    for (const Hypothesis& t : tracks_) {
        Hypothesis h = pipe_->follow(depth, K, t, opt_.follow);
        const bool confident = t.score >= opt_.min_track_score;
        if (confident && (!h.outcome.ok() || h.score < opt_.lost_score)) lost = true;
        weak = weak || (h.outcome.ok() && h.score < opt_.min_track_score);
        if (h.outcome.ok()) seeds.push_back(std::move(h));
    }
    ++since_detect_;
    const int every = weak && opt_.redetect_weak_every > 0 ? opt_.redetect_weak_every
                                                           : opt_.redetect_every;
    detected_ = tracks_.empty() || lost || (every > 0 && since_detect_ >= every);
    // 2. The selection (duplicates, overlaps, the score threshold) over the followed poses and,
    //    when detecting, this frame's fresh hypotheses. On a frame the detector sees, the fresh
    //    poses are decided first and the followed ones only fill in the instances they left out:
    //    a followed pose carries its first frame's errors (the wrong one of two like objects, a
    //    box flipped end over end) that depth alone cannot reveal, where the networks decide
    //    afresh on each detection.
    //    A weak followed pose does not even fill in: the fresh hypotheses decide it again (or
    //    leave it out, as they would without a tracker).
    std::vector<Hypothesis> dropped;
    if (detected_) {
        since_detect_ = 0;
        std::vector<Hypothesis> kept;
        for (Hypothesis& h : seeds) {
            h.fill_in = true;
            (h.score >= opt_.min_track_score ? kept : dropped).push_back(std::move(h));
        }
        seeds = std::move(kept);
    }
    const std::vector<Candidate> cands = detected_ ? detect() : std::vector<Candidate>{};
    pipe_->hypotheses(depth, K, cands, out, &seeds);
    // 3. Track ids: a followed pose keeps its id; a fresh pose that beat a followed one of the
    //    same instance (a duplicate), or is the same instance as a dropped weak one
    //    (same_instance: near it and claiming the same depth), takes that id; any other fresh
    //    pose is a new instance.
    std::vector<Hypothesis>& hs = *out;
    for (const Hypothesis& h : hs)
        if (h.tracked && h.verdict == Verdict::duplicate && h.rival >= 0 &&
            hs[size_t(h.rival)].track_id < 0)
            hs[size_t(h.rival)].track_id = h.track_id;
    for (const Hypothesis& w : dropped) {  // a fresh pose of the same instance takes its id
        const double d = pipe_->model().diameter.at(w.cand.obj_id);
        for (Hypothesis& h : hs)
            if (h.accepted() && h.track_id < 0 && same_instance(h, w, pipe_->tuning(), d)) {
                h.track_id = w.track_id;
                break;
            }
    }
    tracks_.clear();
    for (Hypothesis& h : hs) {
        if (!h.accepted()) continue;
        if (h.track_id < 0) h.track_id = next_id_++;
        h.fill_in = false;
        if (h.verified) tracks_.push_back(h);  // an object without a mesh cannot be followed
    }
}

}  // namespace g2l::infer
