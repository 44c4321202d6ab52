// SPDX-License-Identifier: MIT
// The kinds of data source a config's data.train / data.val may name, in ONE table: the name a
// config writes, whether it reads annotated frames or renders meshes, the keys it reads, and the
// reader that opens it. Adding a reader is a file in data/ and a row in source_types.cpp; nothing
// else compares source names (configs, the trainer and g2l_eval go through this table).
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "data/dataset.h"

namespace g2l::train {

enum class SourceType {
    bop,                   ///< a BOP dataset split: <root>/<split>/<scene>/... (data/bop.h)
    synthetic,             ///< renders of a BOP root's models (data/scene.h)
    linemod_preprocessed,  ///< the DenseFusion / G2L-Net "Linemod_preprocessed" release (data/linemod_preprocessed.h)
};

struct SourceConfig;

/// What a reader is asked for.
struct SourceOpen {
    std::vector<int> obj_ids;  ///< the objects to keep (models and instances)
    bool models_only = false;  ///< only the models (a synthetic source's meshes): no frame is read
    /// Objects scored with ADD-S; nullopt = what the dataset declares (data/bop.h BopOptions).
    std::optional<std::vector<int>> symmetric_ids;
};

/// One row of the table.
struct SourceKind {
    SourceType type;
    const char* name;  ///< the config's "type"
    /// True: annotated frames under `root` (and `split`); false: renders of `models_root`'s meshes.
    bool frames;
    const char* keys;  ///< the keys it reads besides "type" and "objects" (for messages and docs)
    /// Opens the source's dataset (the frames of its split, or only its models). Throws
    /// g2l::Error naming the file.
    std::unique_ptr<data::Dataset> (*open)(const SourceConfig& s, const SourceOpen& what);
};

/// Every row, in the order the docs list them.
const std::vector<SourceKind>& source_kinds();
/// The row of `type`.
const SourceKind& source_kind(SourceType type);
/// The type a config names; nullopt for an unknown name.
std::optional<SourceType> source_type_named(const std::string& name);
/// The names, for "must be one of" messages.
std::vector<std::string> source_type_names();

}  // namespace g2l::train
