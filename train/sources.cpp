// SPDX-License-Identifier: MIT
// BopSource and SyntheticSource: index -> (frame, instance) -> SampleMaker::make.
#include "train/sources.h"

#include <cmath>
#include <utility>

#include "core/error.h"

namespace g2l::train {

namespace {

// The frames a BopSource uses: all, or max_frames evenly spaced ones (k * F / max_frames).
std::vector<int> pick_frames(int64_t n_frames, int64_t max_frames) {
    std::vector<int> out;
    if (max_frames <= 0 || max_frames >= n_frames) {
        for (int64_t f = 0; f < n_frames; ++f) out.push_back(static_cast<int>(f));
        return out;
    }
    for (int64_t k = 0; k < max_frames; ++k) {
        out.push_back(static_cast<int>(k * n_frames / max_frames));
    }
    return out;
}

}  // namespace

BopSource::BopSource(const data::Dataset& dataset, const SampleMaker& maker,
                     double min_visib_fract, int64_t max_frames)
    : ds_(dataset), maker_(maker) {
    G2L_CHECK(std::isfinite(min_visib_fract) && min_visib_fract <= 1,
              "BopSource: min_visib_fract must be finite and <= 1, got ", min_visib_fract);
    const std::vector<data::Frame>& frames = ds_.frames();
    for (const int f : pick_frames(static_cast<int64_t>(frames.size()), max_frames)) {
        const data::Frame& fr = frames[static_cast<size_t>(f)];
        if (fr.depth_path.empty()) continue;
        for (size_t k = 0; k < fr.instances.size(); ++k) {
            const data::Instance& in = fr.instances[k];
            if (!maker_.has_class(in.obj_id)) continue;
            // visib_fract -1 = not annotated: nothing to judge it by, so keep it.
            if (in.visib_fract >= 0 && in.visib_fract < min_visib_fract) continue;
            entries_.push_back({f, static_cast<int>(k)});
        }
    }
    G2L_CHECK(!entries_.empty(), "BopSource: no instance of dataset '", ds_.root(), "' (",
              frames.size(), " frames, max_frames ", max_frames, ") has depth, an object of the "
              "class map and visib_fract >= ", min_visib_fract);
}

bool BopSource::get(int64_t index, Rng& rng, PoseSample* out) {
    G2L_CHECK(index >= 0 && index < size(), "BopSource::get: index ", index,
              " is outside [0, ", size(), ")");
    const Entry& e = entries_[static_cast<size_t>(index)];
    const data::Frame& fr = ds_.frames()[static_cast<size_t>(e.frame)];
    if (cached_frame_ != e.frame) {
        cached_frame_ = -1;  // stays invalid if the load throws
        depth_mm_ = ds_.load_depth_mm(fr, &width_, &height_);
        cached_frame_ = e.frame;
    }
    const DepthView view{depth_mm_.data(), width_, height_, fr.K};
    return maker_.make(view, fr.instances[static_cast<size_t>(e.instance)], rng, out);
}

SyntheticSource::SyntheticSource(const data::SceneConfig& scene,
                                 std::vector<data::SceneModel> models, const SampleMaker& maker,
                                 int64_t frames, int render_threads, double min_visib_fract)
    : maker_(maker), gen_(scene, models), frames_(frames),
      per_frame_(std::max(1, scene.targets_max)), render_threads_(render_threads),
      min_visib_fract_(min_visib_fract) {
    G2L_CHECK(frames > 0, "SyntheticSource: frames must be > 0, got ", frames);
    G2L_CHECK(std::isfinite(min_visib_fract) && min_visib_fract >= 0 && min_visib_fract <= 1,
              "SyntheticSource: min_visib_fract must be in [0, 1], got ", min_visib_fract);
    std::vector<int> targets = scene.target_obj_ids;
    if (targets.empty()) {
        for (const data::SceneModel& m : models) targets.push_back(m.obj_id);
    }
    for (const int id : targets) {
        G2L_CHECK(maker_.has_class(id), "SyntheticSource: target obj_id ", id,
                  " has no class in the SampleMaker (set SceneConfig.target_obj_ids or add it to "
                  "the class map)");
    }
}

int64_t SyntheticSource::frame_of(int64_t index) const {
    G2L_CHECK(index >= 0 && index < size(), "SyntheticSource: index ", index,
              " is outside [0, ", size(), ")");
    return index / per_frame_;
}

const data::RenderedFrame& SyntheticSource::frame(int64_t frame_index) {
    G2L_CHECK(frame_index >= 0 && frame_index < frames_, "SyntheticSource::frame: frame index ",
              frame_index, " is outside [0, ", frames_, ")");
    if (cached_frame_ != frame_index) {
        cached_frame_ = -1;  // stays invalid if rendering throws
        gen_.render_frame(frame_index, frame_, render_threads_);
        cached_frame_ = frame_index;
    }
    return frame_;
}

int SyntheticSource::instance_of(int64_t index) {
    const data::RenderedFrame& f = frame(frame_of(index));
    if (f.instances.empty()) return -1;
    return static_cast<int>((index % per_frame_) % static_cast<int64_t>(f.instances.size()));
}

bool SyntheticSource::get(int64_t index, Rng& rng, PoseSample* out) {
    const int k = instance_of(index);
    if (k < 0) return false;
    const data::RenderedInstance& ri = frame_.instances[static_cast<size_t>(k)];
    // An instance that is off-image or fully occluded has no box at all: nothing to crop.
    if (ri.bbox_visib.empty() && ri.bbox_obj.empty()) return false;
    if (ri.visib_fract < min_visib_fract_) return false;
    data::Instance inst;
    inst.obj_id = ri.obj_id;
    inst.pose = ri.pose;
    inst.bbox_obj = ri.bbox_obj;
    inst.bbox_visib = ri.bbox_visib;
    inst.visib_fract = ri.visib_fract;
    inst.index_in_frame = k;
    const DepthView view{frame_.depth.data(), frame_.K.width, frame_.K.height, frame_.K};
    return maker_.make(view, inst, rng, out);
}

}  // namespace g2l::train
