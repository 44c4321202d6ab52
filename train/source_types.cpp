// SPDX-License-Identifier: MIT
#include "train/source_types.h"

#include "core/error.h"
#include "data/bop.h"
#include "data/linemod_preprocessed.h"
#include "train/config.h"

namespace g2l::train {

namespace {

data::BopOptions bop_options(const SourceConfig& s, const SourceOpen& w) {
    data::BopOptions o;
    o.scenes = s.scenes;
    o.obj_ids = w.obj_ids;
    o.models_eval = s.models_eval;
    o.symmetric_ids = w.symmetric_ids;
    return o;
}

std::unique_ptr<data::Dataset> open_bop_source(const SourceConfig& s, const SourceOpen& w) {
    const data::BopOptions o = bop_options(s, w);
    if (w.models_only)
        return std::make_unique<data::BopDataset>(data::open_bop_models(s.root, o), "",
                                                  std::vector<std::string>{});
    return std::make_unique<data::BopDataset>(data::open_bop(s.root, s.split, o));
}

std::unique_ptr<data::Dataset> open_synthetic_source(const SourceConfig& s, const SourceOpen& w) {
    // Renders need only the models; the frames come from the scene generator.
    return std::make_unique<data::BopDataset>(data::open_bop_models(s.models_root, bop_options(s, w)),
                                              "", std::vector<std::string>{});
}

std::unique_ptr<data::Dataset> open_linemod_source(const SourceConfig& s, const SourceOpen& w) {
    data::LinemodOptions o;
    o.objects = w.obj_ids;  // one folder per object: data/NN
    o.split = w.models_only ? "all" : s.split;
    o.symmetric_ids = w.symmetric_ids;
    return std::make_unique<data::LinemodDataset>(data::open_linemod_preprocessed(s.root, o));
}

const std::vector<SourceKind> kKinds = {
    {SourceType::bop, "bop", true,
     "root, split, scenes, models_eval, min_visib_fract, max_frames", open_bop_source},
    {SourceType::synthetic, "synthetic", false, "models_root, frames, scene",
     open_synthetic_source},
    {SourceType::linemod_preprocessed, "linemod_preprocessed", true,
     "root, split (train | test | all), min_visib_fract, max_frames", open_linemod_source},
};

}  // namespace

const std::vector<SourceKind>& source_kinds() { return kKinds; }

const SourceKind& source_kind(SourceType type) {
    for (const SourceKind& k : kKinds)
        if (k.type == type) return k;
    G2L_CHECK(false, "source type ", int(type), " has no row in train/source_types.cpp");
    return kKinds.front();
}

std::optional<SourceType> source_type_named(const std::string& name) {
    for (const SourceKind& k : kKinds)
        if (name == k.name) return k.type;
    return std::nullopt;
}

std::vector<std::string> source_type_names() {
    std::vector<std::string> out;
    for (const SourceKind& k : kKinds) out.push_back(k.name);
    return out;
}

}  // namespace g2l::train
