// SPDX-License-Identifier: MIT
// Sample sources: an index space of (frame, instance) pairs turned into PoseSamples by a
// SampleMaker, from a real BOP dataset or from synthetic renders (data/scene.h).
// Thread-safety: a source caches its last frame, so use one source object per thread (several
// sources may share one SampleMaker, whose make() is const and thread-safe).
#pragma once

#include <cstdint>
#include <vector>

#include "core/rng.h"
#include "data/dataset.h"
#include "data/scene.h"
#include "train/sample.h"

namespace g2l::train {

/// Something that produces training samples by index.
class SampleSource {
public:
    virtual ~SampleSource() = default;
    /// Number of addressable (frame, instance) pairs; indices run over [0, size()).
    virtual int64_t size() const = 0;
    /// Makes the sample of `index` with random draws from `rng`. Returns false when the crop is
    /// unusable (see SampleMaker::make). The result depends only on (index, rng state), never on
    /// which indices were requested before. Throws g2l::Error for index outside [0, size()) and
    /// whatever SampleMaker::make or the frame loader throws.
    virtual bool get(int64_t index, Rng& rng, PoseSample* out) = 0;
};

/// Samples from the annotated instances of a (BOP) dataset's real depth frames.
class BopSource : public SampleSource {
public:
    /// Where index i comes from.
    struct Entry {
        int frame = 0;     ///< index into dataset.frames()
        int instance = 0;  ///< index into that frame's instances
    };

    /// Indexes every instance whose obj_id has a class in `maker` and whose visib_fract is >=
    /// min_visib_fract (instances without a visib_fract annotation, -1, are kept), over frames
    /// that have depth. max_frames > 0 keeps that many frames evenly spaced over the dataset
    /// (frame k * F / max_frames), <= 0 keeps all. The dataset and maker are borrowed (must
    /// outlive the source). Throws g2l::Error if min_visib_fract is not finite or > 1, or if no
    /// instance qualifies (naming the dataset root and the filters).
    BopSource(const data::Dataset& dataset, const SampleMaker& maker, double min_visib_fract,
              int64_t max_frames = 0);

    int64_t size() const override { return static_cast<int64_t>(entries_.size()); }
    /// Loads the frame's depth (cached: consecutive indices of one frame decode it once).
    bool get(int64_t index, Rng& rng, PoseSample* out) override;

    const std::vector<Entry>& entries() const { return entries_; }
    const data::Dataset& dataset() const { return ds_; }

private:
    const data::Dataset& ds_;
    const SampleMaker& maker_;
    std::vector<Entry> entries_;
    int cached_frame_ = -1;
    int width_ = 0, height_ = 0;
    std::vector<float> depth_mm_;
};

/// Samples from synthetic frames rendered on demand by data::SceneGenerator. Index i addresses
/// frame i / targets_max and instance (i % targets_max) % (instances in that frame), so every
/// index maps to an instance and the mapping depends only on (scene config, i).
class SyntheticSource : public SampleSource {
public:
    /// scene: the scene distribution (validated); models: borrowed meshes (must outlive the
    /// source); frames > 0: number of frames indexed (size() = frames * targets_max);
    /// render_threads: OpenMP threads of the rasterizer; 1 (default) suits one source per loader
    /// thread, 0 = the OpenMP default. Never changes the result. min_visib_fract: instances whose
    /// rendered visible fraction is below it give no sample (get returns false).
    /// Throws g2l::Error for frames <= 0, min_visib_fract outside [0, 1], a target object without
    /// a class in `maker` (every model when target_obj_ids is empty), or whatever
    /// SceneGenerator's constructor throws.
    SyntheticSource(const data::SceneConfig& scene, std::vector<data::SceneModel> models,
                    const SampleMaker& maker, int64_t frames, int render_threads = 1,
                    double min_visib_fract = 0);

    int64_t size() const override { return frames_ * per_frame_; }
    /// Renders the frame (cached: the indices of one frame render it once). Returns false also
    /// when the frame has no annotated instance or the instance is less visible than
    /// min_visib_fract.
    bool get(int64_t index, Rng& rng, PoseSample* out) override;

    /// Frame index of a sample index (index / targets_max).
    int64_t frame_of(int64_t index) const;
    /// Instance of `index` within frame(frame_of(index)), or -1 when the frame has none.
    int instance_of(int64_t index);
    /// The rendered frame `frame_index` (renders it unless it is the cached one). The reference
    /// is valid until the next call of get/frame/instance_of. Throws for a negative index or
    /// one >= the number of frames.
    const data::RenderedFrame& frame(int64_t frame_index);

private:
    const SampleMaker& maker_;
    data::SceneGenerator gen_;
    int64_t frames_ = 0;
    int64_t per_frame_ = 1;
    int render_threads_ = 1;
    double min_visib_fract_ = 0;
    int64_t cached_frame_ = -1;
    data::RenderedFrame frame_;
};

}  // namespace g2l::train
