// SPDX-License-Identifier: MIT
// Model diameter / extent: computed from vertices or read from BOP models_info.json and the
// classic Linemod_preprocessed models_info.yml. All lengths in millimetres.
#pragma once

#include <map>
#include <string>

#include "geometry/types.h"

namespace g2l::geom {

/// Computes the exact diameter (largest distance between two vertices) and the axis-aligned
/// extent (min corner, size = max - min) of `vertices` (N x 3, mm). The diameter is exact: pairs
/// that provably cannot be longer than a pair already found are skipped (centre-distance
/// bounds), all others are compared (OpenMP; the result does not depend on the thread count).
/// symmetric is false. Throws g2l::Error if N == 0 or a vertex is not finite (naming it).
ModelInfo compute_model_info(const Points& vertices);

/// Below this many units across, a mesh is taken to be in metres (a part under 1 cm is rare; a
/// part of 1 m given in metres is 1 unit across): check_mesh_units refuses it, g2l_train
/// --objects scales it by 1000.
constexpr double kMetreMeshBelow = 10;

/// The unit and scale check of a mesh a user hands in (meshes are in millimetres): measures it
/// (compute_model_info) and
///  - with `declared` (its models_info entry, read from `declared_in`): the measured diameter
///    must be within 5 % of the declared one;
///  - without: a mesh less than kMetreMeshBelow units across is refused as being in metres.
/// Returns the measured info. Throws g2l::Error naming the mesh, both diameters and the fix
/// (a mesh in metres: scale by 1000; a factor of 10: a cm / mm slip).
ModelInfo check_mesh_units(const Mesh& mesh, const ModelInfo* declared,
                           const std::string& declared_in = "");

/// Reads a BOP models_info.json: {"<obj_id>": {"diameter", "min_x", "min_y", "min_z", "size_x",
/// "size_y", "size_z", optional "symmetries_discrete" / "symmetries_continuous"}}. An entry with
/// a non-empty symmetry list gets symmetric = true. Throws g2l::Error naming the file and key for
/// a missing file, invalid JSON, a non-integer object id, a missing or non-numeric field, or a
/// diameter <= 0.
std::map<int, ModelInfo> load_models_info_json(const std::string& path);

/// Reads the Linemod_preprocessed models_info.yml, one object per line:
/// `<id>: {diameter: <d>, min_x: .., min_y: .., min_z: .., size_x: .., size_y: .., size_z: ..}`.
/// Blank lines and `#` comments are skipped. symmetric is false (the file has no symmetry data).
/// Throws g2l::Error naming the file and line for a missing file, a malformed line, a missing
/// key, a bad number, a duplicated id or a diameter <= 0.
std::map<int, ModelInfo> load_models_info_yml(const std::string& path);

}  // namespace g2l::geom
